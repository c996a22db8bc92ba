"""The compiled form of :class:`~jointctl.model.dynamics.RobotDynamics`'s pose queries: the same MuJoCo
functions on the same private ``MjData``, called from a compiled cycle.

:class:`DynamicsArrays` holds what the kernels need of one ``RobotDynamics``: its model's and data's addresses,
the joints' ``qpos`` and dof addresses (in the dynamics' joint order), and full-width buffers. The answers are
those of the Python methods, bit for bit (the same C functions, the same gathers):

- :func:`dynamics_set_pose` is ``set_pose(q, inertia=...)``;
- :func:`dynamics_jacobians` is ``frame(link).jacobians()`` (3 x n each, base frame);
- :func:`dynamics_gravity` is ``gravity_at_pose()`` [N or N·m];
- :func:`dynamics_inertia` is ``inertia_at_pose(qdd)`` [N or N·m];
- :func:`dynamics_mass_matrix` is ``mass_matrix()`` (n x n) [kg, kg·m or kg·m²], after ``set_pose`` with inertia.

A frame's position and rotation are the data's ``xpos[body]`` and ``xmat[body]``, read by the caller.
"""

from __future__ import annotations

import numpy as np

from jointctl.jit import kernel
from jointctl.model.dynamics import RobotDynamics
from jointctl.model.mujoco_functions_kernel import (mj_comPos, mj_crb, mj_fullM, mj_jacBody, mj_kinematics, mj_mulM,
                                                    mj_rne)

#: ``DynamicsArrays.addresses``: the model's and the data's address.
MODEL, DATA = range(2)


def _addresses(selection, count: int) -> np.ndarray:
    if isinstance(selection, slice):
        return np.arange(selection.start, selection.stop, dtype=np.int64)
    return np.asarray(selection, dtype=np.int64).reshape(count)


class DynamicsArrays:
    """What the kernels need of ``dynamics`` (kept alive here: the addresses are its model's and data's)."""

    def __init__(self, dynamics: RobotDynamics) -> None:
        self.dynamics = dynamics
        m, d = dynamics._model, dynamics._data
        n = len(dynamics.joint_names)
        self.addresses = np.array([m._address, d._address], dtype=np.uintp)
        self.qpos_adr = _addresses(dynamics._qpos, n)
        self.dof_adr = _addresses(dynamics._dofs, n)
        self.qpos = d.qpos
        self.xpos, self.xmat = d.xpos, d.xmat
        self.jacp, self.jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        self.tau, self.qdd = np.zeros(m.nv), np.zeros(m.nv)

    def body(self, link: str) -> int:
        """The MuJoCo body id of ``link`` (as ``RobotDynamics.frame`` finds it)."""
        return self.dynamics.frame(link)._body


@kernel
def dynamics_set_pose(addresses, qpos, qpos_adr, q, inertia):
    """``RobotDynamics.set_pose(q, inertia=inertia)``: kinematics, centre-of-mass frames, and M(q) if asked."""
    for j in range(qpos_adr.shape[0]):
        qpos[qpos_adr[j]] = q[j]
    mj_kinematics(addresses[MODEL], addresses[DATA])
    mj_comPos(addresses[MODEL], addresses[DATA])
    if inertia:
        mj_crb(addresses[MODEL], addresses[DATA])


@kernel
def dynamics_jacobians(addresses, jacp, jacr, body, dof_adr, jv, jr):
    """``Frame.jacobians()`` of body ``body`` into ``jv`` and ``jr`` (3 x n): ``v = Jv·q̇``, ``ω = Jr·q̇``."""
    mj_jacBody(addresses[MODEL], addresses[DATA], jacp.ctypes.data, jacr.ctypes.data, body)
    for j in range(dof_adr.shape[0]):
        a = dof_adr[j]
        for axis in range(3):
            jv[axis, j] = jacp[axis, a]
            jr[axis, j] = jacr[axis, a]


@kernel
def dynamics_gravity(addresses, tau, dof_adr, out):
    """``RobotDynamics.gravity_at_pose()`` into ``out``: the efforts holding the pose against gravity."""
    mj_rne(addresses[MODEL], addresses[DATA], 0, tau.ctypes.data)
    for j in range(dof_adr.shape[0]):
        out[j] = tau[dof_adr[j]]


@kernel
def dynamics_inertia(addresses, tau, qdd_full, dof_adr, qdd, out):
    """``RobotDynamics.inertia_at_pose(qdd)`` into ``out``: ``M(q)·q̈`` at the pose."""
    for j in range(dof_adr.shape[0]):
        qdd_full[dof_adr[j]] = qdd[j]
    mj_mulM(addresses[MODEL], addresses[DATA], tau.ctypes.data, qdd_full.ctypes.data)
    for j in range(dof_adr.shape[0]):
        out[j] = tau[dof_adr[j]]


@kernel
def dynamics_mass_matrix(addresses, nv, dof_adr, table, full_row, out, out_row):
    """``RobotDynamics.mass_matrix()`` into ``out[out_row + i, j]`` (i, j < n): MuJoCo's dense ``nv`` x ``nv``
    M(q) (``nv``: the model's) is written row by row from ``table[full_row, 0]`` on (a C-ordered float table whose
    rows from ``full_row`` hold nv² numbers), then gathered to the dynamics' joints."""
    width = table.shape[1]
    mj_fullM(addresses[MODEL], addresses[DATA], table.ctypes.data + full_row * width * 8)
    n = dof_adr.shape[0]
    for i in range(n):
        for j in range(n):
            flat = dof_adr[i] * nv + dof_adr[j]
            out[out_row + i, j] = table[full_row + flat // width, flat % width]

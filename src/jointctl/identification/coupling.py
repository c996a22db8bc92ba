"""The load a chain's other joints put on the joint being identified, from the robot's model.

Row ``i`` of the manipulator equation of a chain (SI units: N·m or N, kg·m² or kg)::

    effort_i = Σ_j M_ij(q)·qdd_j + c_i(q, qd) + g_i(q) + b_i·qd_i + friction_i

With the other joints held by their own position loops they still move a little under the
joint's reaction (a planar arm's shoulder, held by a P gain of 1000 N·m/rad, 0.015 rad while the
elbow swings 0.26 rad at up to 3 Hz), and their motion loads joint ``i`` in step with its own: their
accelerations through the off-diagonal inertia ``M_ij``, the products of speeds through ``c_i``,
their displacement through gravity. A per-joint fit that ignores it reads that load as extra inertia
and damping (10 % and 5 % on that elbow; -21 % and 24 times on the 7-DOF arm's joint 1, whose loop
barely follows 3 Hz). :func:`chain_coupling` computes it from the robot's model along the recorded
motion of every joint, with the differences the fit takes, so that it can be subtracted from the effort::

    coupling_i = rne_i(q, qd, qdd with qdd_i = 0) - rne_i(q̄, qd_i·e_i, 0)

``rne`` is MuJoCo's recursive Newton-Euler (``M(q)·qdd + c(q, qd) + g(q)``, on the robot's own
model: :func:`jointctl.model.mjcf.compile_robot`, the URDF's links and joints, nothing spawned) and
``q̄`` the pose the other joints are held at (the median of their recorded positions) with joint
``i`` where it is. What is left, ``effort_i - coupling_i``, is the effort of joint ``i`` alone with
the others at ``q̄``: ``M_ii(q)·qdd_i + b_i·qd_i + friction + g_i(q̄)`` (``c_i`` of its own speed
alone vanishes on a chain: a body turning about an axis does not change its inertia about it), the
model :func:`jointctl.identification.plant_fit.fit_plant` fits, its gravity a function of ``q_i``.

The joint's own inertia ``M_ii(q)`` changes with the others' pose. Rather than subtract the model's
``(M_ii(q) - M_ii(q̄))·qdd_i`` (the model's absolute inertia, the very thing identified), the fit's
inertia column is scaled by the model's ratio ``inertia_scale = M_ii(q) / M_ii(q̄)``; the identified
inertia is then the joint's at ``q̄``, whatever the model's scale. (On a simulated joint it includes
``dt·b_i``, MuJoCo's implicit damping, see :mod:`jointctl.identification.plant_fit`, which the ratio
scales too: off by ``dt·b_i·(1 - ratio)``, 1e-8 of the 7-DOF arm's joint 1 at its pre-pose.)

What rests on the model: the off-diagonal inertia, the speed products and the gravity shift come
from the robot's description, not from the data. A model off by some per cent moves the fit by
that share of the error the coupling removes (a coupling 10 % off moves the planar arm's elbow
inertia by 0.94 % and its damping by 0.67 %, a tenth of the 10 % and 5 % without it), and the 95 %
intervals, which count the residual's scatter, do not include it; ``coupling_rms`` in the result
says how large the load was. The joint's own inertia, damping, friction and gravity are measured,
not assumed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from jointctl.identification.plant_fit import IdentificationError, difference_rows, stretches
from jointctl.model.mjcf import compile_robot
from jointctl.model.robot_model import RobotModel


@dataclass(frozen=True)
class Coupling:
    """The other joints' load on ``joint`` along a recorded motion, per sample: ``torque`` [N·m or N]
    (NaN where the differences are not defined: the last sample, at a gap) and ``inertia_scale``
    (``M_ii(q) / M_ii(q̄)``); ``pose`` the others' positions ``q̄`` [rad or m] the identified inertia
    is for, ``model_inertia`` the model's ``M_ii(q̄)`` [kg·m² or kg] (armature included, without the
    simulator's ``dt·b``)."""

    joint: str
    torque: np.ndarray
    inertia_scale: np.ndarray
    pose: dict[str, float]
    model_inertia: float


def chain_coupling(robot: RobotModel, joint: str, joints: Sequence[str], time_s: ArrayLike, positions: ArrayLike,
                   velocities: ArrayLike, *, gravity_m_s2=(0.0, 0.0, -9.81),
                   acceleration: str = "forward") -> Coupling:
    """The coupling of the module docstring for ``joint`` of ``robot`` under ``gravity_m_s2`` [m/s²],
    from every joint's ``positions`` and ``velocities`` (N x n, columns in the order of ``joints``,
    which must name every movable joint of the robot) at ``time_s`` [s] (uniform, gaps allowed: see
    :func:`jointctl.identification.plant_fit.stretches`), with the differences ``acceleration``
    ("forward" or "central") that the fit will take."""
    names = list(joints)
    movable = [j.name for j in robot.movable_joints]
    missing = [n for n in movable if n not in names]
    if missing:
        raise IdentificationError("the recording must hold every movable joint of the robot", field="joints",
                                  value=missing)
    if joint not in names:
        raise IdentificationError("not one of the recorded joints", field="joint", value=joint)
    q = np.asarray(positions, dtype=float)
    qd = np.asarray(velocities, dtype=float)
    t = np.asarray(time_s, dtype=float)
    if not (q.ndim == qd.ndim == 2 and q.shape == qd.shape == (t.size, len(names))):
        raise IdentificationError("positions and velocities must be N x n (samples x joints)", field="samples",
                                  value=[list(q.shape), list(qd.shape), t.size])
    m = compile_robot(robot, gravity_m_s2=tuple(float(g) for g in gravity_m_s2))
    d = mujoco.MjData(m)
    columns = [names.index(n) for n in movable]
    jids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in movable]
    qadr = np.array([m.jnt_qposadr[j] for j in jids], dtype=int)
    dadr = np.array([m.jnt_dofadr[j] for j in jids], dtype=int)
    me = movable.index(joint)
    others = np.array([k for k in range(len(movable)) if k != me], dtype=int)
    q, qd = q[:, columns], qd[:, columns]
    rest = np.median(q, axis=0)

    split = stretches(t)
    rows, qdd = difference_rows(split.index, qd, split.dt, 0, acceleration)
    qdd[:, me] = 0.0  # the joint's own acceleration is the fit's
    torque = np.full(t.size, np.nan)
    scale = np.full(t.size, np.nan)
    tau = np.zeros(m.nv)
    full = np.zeros((m.nv, m.nv))
    i = int(dadr[me])
    qpos, qvel, qacc = d.qpos, d.qvel, d.qacc

    def inverse_dynamics(flg_acc: int) -> tuple[float, float]:
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        mujoco.mj_rne(m, d, flg_acc, tau)
        mujoco.mj_crb(m, d)
        mujoco.mj_fullM(m, d, full)
        return float(tau[i]), float(full[i, i])

    reference = rest.copy()
    for r, k in enumerate(rows):
        qpos[qadr] = q[k]
        qvel[dadr] = qd[k]
        qacc[dadr] = qdd[r]
        moving, inertia = inverse_dynamics(1)
        reference[me] = q[k, me]
        qpos[qadr] = reference
        qvel[:] = 0.0
        qvel[i] = qd[k, me]
        alone, inertia_alone = inverse_dynamics(0)
        torque[k] = moving - alone
        scale[k] = inertia / inertia_alone
    qpos[qadr] = rest
    qvel[:] = 0.0
    _, model_inertia = inverse_dynamics(0)
    return Coupling(joint, torque, scale, {movable[k]: float(rest[k]) for k in others}, model_inertia)


__all__ = ["Coupling", "chain_coupling"]

"""Rigid-body dynamics of the robot model, for model-based feed-forward.

:class:`RobotDynamics` compiles the robot's own MuJoCo model (no world, no
objects) into a private ``MjData`` and answers inverse-dynamics questions
about it. It never touches the simulated world, so controllers can use it
on real hardware too: it is the URDF's model, computed with MuJoCo.
Joint order is the robot's movable joints in document order; SI units.
"""

from __future__ import annotations

import mujoco
import numpy as np

from jointctl.model.robot_model import RobotModel
from jointctl.sim.mjcf_builder import WorldSettings, build_spec


class RobotDynamics:
    """Inverse dynamics ``tau = M(q)·qdd + g(q)`` of a robot under ``gravity_m_s2``."""

    def __init__(self, robot: RobotModel, gravity_m_s2=(0.0, 0.0, -9.81)) -> None:
        spec = build_spec(robot, WorldSettings(gravity_m_s2=tuple(gravity_m_s2), floor=False))
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self.joint_names = tuple(j.name for j in robot.movable_joints)
        m = self.model
        jids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in self.joint_names]
        self.qpos_adr = np.array([m.jnt_qposadr[j] for j in jids], dtype=int)
        self.dof_adr = np.array([m.jnt_dofadr[j] for j in jids], dtype=int)
        self.damping = m.dof_damping[self.dof_adr].copy()
        self._tau = np.zeros(m.nv)
        self._qdd = np.zeros(m.nv)
        # A robot fixed to the world: its joints are all of qpos and qvel, in order.
        self._direct = (np.array_equal(self.qpos_adr, np.arange(m.nq))
                        and np.array_equal(self.dof_adr, np.arange(m.nv)))

    def set_gravity(self, gravity_m_s2) -> None:
        """Answer for another gravity vector [m/s², world frame] from now on."""
        self.model.opt.gravity[:] = [float(g) for g in gravity_m_s2]

    def set_pose(self, q, *, inertia: bool = True) -> None:
        """Compute the position-dependent quantities at ``q`` (zero velocity); the
        ``*_at_pose`` methods then answer for that pose without recomputing it. With
        ``inertia=False`` M(q) is skipped: only :meth:`gravity_at_pose` may follow."""
        m, d = self.model, self.data
        if self._direct:
            d.qpos[:] = q
        else:
            d.qpos[self.qpos_adr] = q
        # Only what inverse dynamics needs (no collisions or constraints): kinematics, the
        # centre-of-mass frames and the composite inertia M(q). qvel stays zero: this data never moves.
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        if inertia:
            mujoco.mj_crb(m, d)

    def gravity_at_pose(self) -> np.ndarray:
        """g(q) at the pose of the last :meth:`set_pose` (a view, valid until the next call)."""
        mujoco.mj_rne(self.model, self.data, 0, self._tau)  # without qacc: the bias, g(q) at rest
        return self._tau if self._direct else self._tau[self.dof_adr]

    def inertia_at_pose(self, qdd) -> np.ndarray:
        """M(q)·qdd at the pose of the last :meth:`set_pose` (MuJoCo's sparse product)."""
        if self._direct:
            self._qdd[:] = qdd
        else:
            self._qdd[self.dof_adr] = qdd
        mujoco.mj_mulM(self.model, self.data, self._tau, self._qdd)
        return self._tau if self._direct else self._tau[self.dof_adr]

    def inverse_dynamics(self, q, qdd=None) -> np.ndarray:
        """Joint efforts [N or N·m] holding the robot at ``q`` with acceleration ``qdd``
        (zero velocity): ``M(q)·qdd + g(q)``."""
        self.set_pose(q)
        tau = self.gravity_at_pose().copy()
        if qdd is not None:
            tau += self.inertia_at_pose(qdd)
        return tau

    def gravity(self, q) -> np.ndarray:
        """Efforts that hold the robot still at ``q`` against gravity: g(q)."""
        return self.inverse_dynamics(q)

    def mass_matrix(self, q) -> np.ndarray:
        """The joint-space inertia matrix M(q) [kg or kg·m²]."""
        m, d = self.model, self.data
        self.set_pose(q)
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, full)
        return full[np.ix_(self.dof_adr, self.dof_adr)]

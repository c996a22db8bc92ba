"""The robot's kinematics and dynamics: a library of the model, not of the simulator.

:class:`RobotDynamics` compiles the robot's own MuJoCo model (:func:`~jointctl.model.mjcf.robot_spec`:
no floor, no objects) into a private ``MjData`` and answers questions about the robot at a pose:

- forward kinematics and Jacobians of any link (:meth:`RobotDynamics.frame`, :meth:`RobotDynamics.poses`),
- the joint-space inertia ``M(q)`` (:meth:`RobotDynamics.mass_matrix`) and the efforts of inverse
  dynamics at rest, ``g(q)`` and ``M(q)·q̈`` (:meth:`RobotDynamics.gravity_at_pose`,
  :meth:`RobotDynamics.inertia_at_pose`),
- a joint's axis in the base frame (:meth:`RobotDynamics.joint_axis`).

It never touches the simulated world, so controllers can use it on real hardware too: it is the
URDF's model, computed with MuJoCo. Callers set a pose once (:meth:`RobotDynamics.set_pose`) and then
ask; answers are views into buffers kept here, valid until the next call that recomputes them, so a
control loop allocates nothing. Joint values are those of ``joints`` (default: the robot's movable
joints in document order), in that order; joints not listed stay at zero. The base frame is the
world frame of the URDF's root link; SI units (m, rad, kg, N, N·m).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from jointctl.errors import ModelError
from jointctl.model.mjcf import compile_robot
from jointctl.model.robot_model import RobotModel


def _contiguous(addresses: np.ndarray) -> slice | np.ndarray:
    """A slice when ``addresses`` are consecutive (views instead of copies), else the addresses."""
    if addresses.size and np.array_equal(addresses, np.arange(addresses[0], addresses[0] + addresses.size)):
        return slice(int(addresses[0]), int(addresses[0]) + addresses.size)
    return addresses


class Frame:
    """A link's frame at the pose of the last :meth:`RobotDynamics.set_pose`.

    ``position`` (its origin [m]) and ``rotation`` (columns: its axes) in the base frame are views
    that follow every new pose. :meth:`jacobians` fills the translational and rotational Jacobians
    of the origin with respect to the dynamics' joints (3 x n each; rows: base-frame axes).
    """

    def __init__(self, dynamics: RobotDynamics, link: str, body: int) -> None:
        self.link = link
        self._dynamics = dynamics
        self._body = body
        data = dynamics._data
        self.position: np.ndarray = data.xpos[body]
        self.rotation: np.ndarray = data.xmat[body].reshape(3, 3)
        nv, n = dynamics._model.nv, len(dynamics.joint_names)
        self._jacp, self._jacr = np.zeros((3, nv)), np.zeros((3, nv))
        dofs = dynamics._dofs
        if isinstance(dofs, slice) and dofs == slice(0, nv):
            self.translation_jacobian, self.rotation_jacobian = self._jacp, self._jacr
        else:
            self.translation_jacobian, self.rotation_jacobian = np.zeros((3, n)), np.zeros((3, n))

    def jacobians(self) -> tuple[np.ndarray, np.ndarray]:
        """``(Jv, Jr)`` of the frame's origin at the pose: ``v = Jv·q̇`` [m/s], ``ω = Jr·q̇`` [rad/s].

        The arrays are the frame's own (``translation_jacobian``, ``rotation_jacobian``), refilled
        by every call."""
        dynamics = self._dynamics
        mujoco.mj_jacBody(dynamics._model, dynamics._data, self._jacp, self._jacr, self._body)
        jv, jr = self.translation_jacobian, self.rotation_jacobian
        if jv is not self._jacp:  # the dynamics' joints are not all of the model's, in order
            dofs = dynamics._dofs
            if isinstance(dofs, slice):
                jv[:], jr[:] = self._jacp[:, dofs], self._jacr[:, dofs]
            else:
                np.take(self._jacp, dofs, axis=1, out=jv)
                np.take(self._jacr, dofs, axis=1, out=jr)
        return jv, jr


class RobotDynamics:
    """Kinematics and rigid-body dynamics of ``robot`` under ``gravity_m_s2`` [m/s², base frame].

    ``joints`` names the movable joints whose values are given and answered for, in that order
    (default: all movable joints in document order).
    """

    def __init__(self, robot: RobotModel, gravity_m_s2=(0.0, 0.0, -9.81),
                 joints: Sequence[str] | None = None) -> None:
        movable = {j.name: j for j in robot.movable_joints}
        names = tuple(movable) if joints is None else tuple(joints)
        for name in names:
            if name not in movable:
                raise ModelError("the robot model has no movable joint of that name", source=robot.source,
                                 field="joints", value=name)
        self.robot = robot
        self.joint_names = names
        m = self._model = compile_robot(robot, gravity_m_s2=tuple(gravity_m_s2))
        self._data = mujoco.MjData(m)
        self._qpos_all = self._data.qpos  # a view of the data's buffer, kept: set_pose writes into it
        jids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names]
        self._jids = dict(zip(names, jids))
        self._qpos = _contiguous(np.array([m.jnt_qposadr[j] for j in jids], dtype=int))
        self._dofs = _contiguous(np.array([m.jnt_dofadr[j] for j in jids], dtype=int))
        #: Viscous damping of each joint [N·s/m or N·m·s/rad], from the URDF.
        self.damping = np.array([movable[n].damping for n in names])
        self._tau = np.zeros(m.nv)
        self._qdd = np.zeros(m.nv)
        self._full = np.zeros((m.nv, m.nv))
        self._frames: dict[str, Frame] = {}

    # -- the pose -----------------------------------------------------------------------------
    def set_gravity(self, gravity_m_s2) -> None:
        """Answer for another gravity vector [m/s², base frame] from now on."""
        self._model.opt.gravity[:] = [float(g) for g in gravity_m_s2]

    def set_pose(self, q, *, inertia: bool = True) -> None:
        """Compute the position-dependent quantities at joint values ``q`` (zero velocity); the
        other methods then answer for that pose without recomputing it. With ``inertia=False``
        ``M(q)`` is skipped: :meth:`mass_matrix` and :meth:`inertia_at_pose` must not follow."""
        m, d = self._model, self._data
        self._qpos_all[self._qpos] = q
        # Only what is asked of a pose (no collisions or constraints): kinematics, the
        # centre-of-mass frames (Jacobians and inverse dynamics need them) and the composite
        # inertia M(q). qvel stays zero: this data never moves.
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        if inertia:
            mujoco.mj_crb(m, d)

    # -- kinematics ---------------------------------------------------------------------------
    def frame(self, link: str) -> Frame:
        """The frame of ``link`` (one object per link: its views and buffers are reused)."""
        frame = self._frames.get(link)
        if frame is None:
            body = mujoco.mj_name2id(self._model, mujoco.mjtObj.mjOBJ_BODY, link)
            if body < 0:
                raise ModelError("the robot model has no link of that name", source=self.robot.source,
                                 field="link", value=link)
            frame = self._frames[link] = Frame(self, link, body)
        return frame

    def poses(self, link: str, q_rows) -> tuple[np.ndarray, np.ndarray]:
        """Forward kinematics of ``link`` along a path: positions (N x 3) [m] and rotations
        (N x 3 x 3) in the base frame for joint values ``q_rows`` (N x n)."""
        frame = self.frame(link)
        positions, rotations = np.empty((len(q_rows), 3)), np.empty((len(q_rows), 3, 3))
        for k, q in enumerate(q_rows):
            self.set_pose(q, inertia=False)
            positions[k] = frame.position
            rotations[k] = frame.rotation
        return positions, rotations

    def joint_axis(self, joint: str) -> np.ndarray:
        """The axis of ``joint`` in the base frame at the pose (a unit vector, a copy)."""
        jid = self._jids.get(joint)
        if jid is None:
            raise ModelError("not one of the dynamics' joints", source=self.robot.source, field="joint",
                             value=joint)
        return self._data.xaxis[jid].copy()

    # -- dynamics -----------------------------------------------------------------------------
    def gravity_at_pose(self) -> np.ndarray:
        """``g(q)`` [N or N·m]: the efforts that hold the pose still against gravity (a view,
        valid until the next call)."""
        mujoco.mj_rne(self._model, self._data, 0, self._tau)  # without qacc: the bias, g(q) at rest
        return self._tau[self._dofs]

    def inertia_at_pose(self, qdd) -> np.ndarray:
        """``M(q)·q̈`` [N or N·m] for joint accelerations ``qdd`` (MuJoCo's sparse product; a view,
        valid until the next call)."""
        self._qdd[self._dofs] = qdd
        mujoco.mj_mulM(self._model, self._data, self._tau, self._qdd)
        return self._tau[self._dofs]

    def mass_matrix(self, out: np.ndarray | None = None) -> np.ndarray:
        """The joint-space inertia ``M(q)`` (n x n) [kg, kg·m or kg·m²] at the pose, into ``out``
        when given."""
        mujoco.mj_fullM(self._model, self._data, self._full)
        dofs = self._dofs
        block = self._full[dofs, dofs] if isinstance(dofs, slice) else self._full[np.ix_(dofs, dofs)]
        if out is None:
            return block.copy()
        out[:] = block
        return out


__all__ = ["Frame", "RobotDynamics"]

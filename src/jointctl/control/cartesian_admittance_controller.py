"""Natural admittance control of a flange in Cartesian space (chapter 11.6, figure 11.7).

``admittance_controllers/CartesianAdmittanceController`` makes the arm's flange behave like
a virtual mass-spring-damper in the base frame, pushed by the force measured at the
force-torque sensor. It is chained in front of one velocity controller per joint (it writes
their commands) and runs inside the control loop, before them, every cycle::

    p, Jv, Jr  = flange position, translational and rotational Jacobians at the measured q
                 (the robot's own model, :class:`~jointctl.sim.dynamics.RobotDynamics`)
    v          = Jv·q̇
    F          = R_sensor·force - F_tare          (sensed force in the base frame)
    f          = K·(p_att - p) - B·v + F          (virtual force at the flange, base frame)
    τ          = Jvᵀ·f
    q̈          = H⁻¹·(τ - c·q̇)                    (c = ``joint_damping``)
    q̇_cmd     += q̈·dt                             (once per cycle), clamped to ±max_velocity

and hands ``q̇_cmd`` to the velocity controllers. At rest ``f = 0``, so ``p = p_att + K⁻¹·F``.
The chapter's code adds ``q̈·dt`` twice per cycle, which halves the effective inertia; here it
is added once.

Units: m, m/s, N, N/m (``stiffness``), N·s/m (``damping``); per joint kg·m² (``inertia_estimate``),
N·m·s/rad (``joint_damping``), rad/s (``max_velocity``); 1/s (``wrist_gain``).

Sensed force. The hardware's wrench is the chapter's (Gazebo ft_sensor) convention: the force
the sensor link's subtree exerts on its parent, in the sensor link's frame, so a load on an
upward plate reads negative z. Rotated into the base frame it is the external force acting on
the flange (a resting weight: (0, 0, -m·g)). ``tare: true`` (default) records that base-frame
force when the controller starts, i.e. the plate's own weight, and subtracts it every cycle,
so the unloaded flange rests at the attractor. The tare is the mean reading over the first
``tare_time_s`` (default 0.2 s) after start, while the controller holds the arm still (it
commands zero velocity and integrates nothing); the admittance starts after it.
``tare_time_s: 0`` takes the single reading at start and starts at once. The window is there
because a simulated arm's reading at the very start is that of an unsupported arm (MuJoCo's
state after reset, before any effort is applied: the plate in free fall reads about zero), and
one taken while the arm accelerates carries the plate's inertial force; on real hardware it
also averages sensor noise. With ``tare: false`` the plate's weight counts in
``F`` and the unloaded flange rests ``K⁻¹·m_plate·g`` below the attractor. The tare is a
base-frame vector because the plate's weight is constant in the base frame; the flange
orientation is held anyway.

Wrist (design choice). The chapter servos the wrist to a fixed flange orientation with gain
20. Here the ``wrist_joints`` (default joints 4, 5, 6 of a seven-joint arm; ``[]`` turns the
servo off) are not integrated: every cycle they get the velocity that keeps the flange at the
orientation it had at start, through the rotational Jacobian::

    e      = rotation vector of R_0·Rᵀ             (orientation error, base frame)
    q̇_W    = Jr_W⁺·(wrist_gain·e - Jr_A·q̇_cmd,A)   (damped least squares)

so the flange's angular velocity is ``wrist_gain·e``: the arm joints' rotation of the flange
is cancelled (feed-forward) and any error decays at ``wrist_gain``. The admittance dynamics
run on the other ("arm") joints A only, as the chapter's mechanism with the orientation held:
with ``T = [I; -Jr_W⁺·Jr_A]`` mapping arm-joint velocities to all joint velocities,

    (Tᵀ·H·T)·q̈_A = Tᵀ·(Jvᵀ·f - c·q̇)

which is ``q̈ = H⁻¹(Jvᵀ·f - c·q̇)`` of the virtual seven-joint mechanism (inertia ``H``,
joint damping ``c``) constrained to keep its flange orientation: the wrist joints' inertia and
damping and their share of the flange's motion are included, so the virtual system stays
passive. Without wrist joints ``T = I`` and it is exactly the chapter's formula.

``H`` is ``diag(inertia_estimate)`` (the chapter's estimate was diag(20, 20, 10, 10, 3) for
joints 0-4), or the model's joint-space inertia ``M(q)`` with ``use_model_inertia: true``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from jointctl.control.controller import Controller, register_controller
from jointctl.control.joint_controllers import JointVelocityController
from jointctl.control.params import Params
from jointctl.errors import ConfigError
from jointctl.hardware.interface import HardwareInterface
from jointctl.model.robot_model import RobotModel

#: Damping of the least-squares inverse of the wrist's rotational Jacobian [rad].
WRIST_DLS_DAMPING = 0.01
_CHAPTER_WRIST = (4, 5, 6)


class FlangeKinematics:
    """Flange position, orientation and Jacobians of a robot's own model (no world).

    ``joints`` name the movable joints whose values are given (others stay at zero);
    ``frame`` is the link whose origin is the flange; ``sensor_link`` the force sensor's link.
    """

    def __init__(self, robot: RobotModel, joints: Sequence[str], frame: str,
                 sensor_link: str | None = None, gravity_m_s2=(0.0, 0.0, -9.81)) -> None:
        from jointctl.sim.dynamics import RobotDynamics  # the model's dynamics, not the simulated world

        self.dynamics = RobotDynamics(robot, gravity_m_s2)
        m = self.model = self.dynamics.model
        self.data = self.dynamics.data
        names = self.dynamics.joint_names
        self.qpos_adr = np.array([self.dynamics.qpos_adr[names.index(j)] for j in joints], dtype=int)
        self.dof_adr = np.array([self.dynamics.dof_adr[names.index(j)] for j in joints], dtype=int)
        self.frame_id = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, frame)
        self.sensor_id = (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, sensor_link)
                          if sensor_link is not None else self.frame_id)
        self._jacp = np.zeros((3, m.nv))
        self._jacr = np.zeros((3, m.nv))
        self._full = np.zeros((m.nv, m.nv))

    def set_pose(self, q, *, inertia: bool = False) -> None:
        """Compute the kinematics at ``q`` (and the mass matrix when ``inertia``)."""
        m, d = self.model, self.data
        d.qpos[self.qpos_adr] = q
        if inertia:
            mujoco.mj_fwdPosition(m, d)
        else:
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)

    @property
    def position(self) -> np.ndarray:
        """Flange origin in the base (world) frame [m]."""
        return self.data.xpos[self.frame_id].copy()

    @property
    def rotation(self) -> np.ndarray:
        """Flange orientation: columns are its axes in the base frame."""
        return self.data.xmat[self.frame_id].reshape(3, 3).copy()

    @property
    def sensor_rotation(self) -> np.ndarray:
        """The force sensor frame's axes in the base frame."""
        return self.data.xmat[self.sensor_id].reshape(3, 3).copy()

    def jacobians(self) -> tuple[np.ndarray, np.ndarray]:
        """Translational and rotational Jacobians (3 x n each) of the flange origin."""
        mujoco.mj_jacBody(self.model, self.data, self._jacp, self._jacr, self.frame_id)
        return self._jacp[:, self.dof_adr].copy(), self._jacr[:, self.dof_adr].copy()

    def mass_matrix(self) -> np.ndarray:
        """M(q) of the given joints at the last pose set with ``inertia=True`` [kg·m²]."""
        mujoco.mj_fullM(self.model, self.data, self._full)
        return self._full[np.ix_(self.dof_adr, self.dof_adr)].copy()

    def positions(self, q_rows) -> np.ndarray:
        """Flange positions (N x 3) for joint values ``q_rows`` (N x n)."""
        out = np.empty((len(q_rows), 3))
        for k, q in enumerate(q_rows):
            self.set_pose(q)
            out[k] = self.data.xpos[self.frame_id]
        return out

    def sensor_rotations(self, q_rows) -> np.ndarray:
        """Sensor frame rotations (N x 3 x 3) for joint values ``q_rows``."""
        out = np.empty((len(q_rows), 3, 3))
        for k, q in enumerate(q_rows):
            self.set_pose(q)
            out[k] = self.data.xmat[self.sensor_id].reshape(3, 3)
        return out


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """Axis times angle [rad] (angle in [0, π]) of a rotation matrix."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).ravel())
    if quat[0] < 0:
        quat = -quat
    s = math.sqrt(quat[1] ** 2 + quat[2] ** 2 + quat[3] ** 2)
    if s < 1e-12:
        return 2.0 * quat[1:]  # small-angle limit
    return 2.0 * math.atan2(s, quat[0]) / s * quat[1:]


def _vector(params: Params, key: str, length: int, default: Any = None, *, minimum: float | None = None,
            positive: bool = False, scalar: bool = False) -> np.ndarray | None:
    """A list of ``length`` finite numbers (or one number for all when ``scalar``)."""
    value = params.raw(key, default)
    if value is None:
        if default is None and key in params.values:
            raise params.error(f"must be a list of {length} numbers", key, value)
        return None
    if scalar and isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [value] * length
    if not isinstance(value, (list, tuple)) or len(value) != length:
        what = f"a list of {length} numbers" + (" or one number" if scalar else "")
        raise params.error(f"must be {what}", key, value)
    out = []
    for k, item in enumerate(value):
        where = f"{key}[{k}]"
        if isinstance(item, bool) or not isinstance(item, (int, float)):
            raise params.error("must be a number", where, item)
        item = float(item)
        if not math.isfinite(item):
            raise params.error("must be finite", where, item)
        if positive and item <= 0:
            raise params.error("must be positive", where, item)
        if minimum is not None and item < minimum:
            raise params.error("must not be negative", where, item)
        out.append(item)
    return np.array(out)


def _names(params: Params, key: str, length: int | None = None) -> tuple[str, ...]:
    value = params.raw(key)
    if not isinstance(value, (list, tuple)) or not value or (length is not None and len(value) != length):
        count = f"{length} names" if length is not None else "names"
        raise params.error(f"must be a list of {count}", key, value)
    for k, item in enumerate(value):
        if not isinstance(item, str) or not item:
            raise params.error("must be a non-empty string", f"{key}[{k}]", item)
        if item in value[:k]:
            raise params.error("is listed twice", f"{key}[{k}]", item)
    return tuple(value)


@register_controller("admittance_controllers/CartesianAdmittanceController")
class CartesianAdmittanceController(Controller):
    """Turns sensed force into joint velocity references for ``velocity_controllers``."""

    def __init__(self, name: str, params: Params) -> None:
        super().__init__(name, params)
        self.joint_names = _names(params, "joints")
        n = len(self.joint_names)
        self.joints = ()  # it commands controllers, not joints' hardware interfaces
        self.sensor = params.string("sensor")
        self.velocity_controllers = _names(params, "velocity_controllers", n)
        self.downstream = self.velocity_controllers
        frame = params.raw("frame", None)
        if frame is not None and (not isinstance(frame, str) or not frame):
            raise params.error("must name a link", "frame", frame)
        self.frame: str | None = frame
        self.attractor = _vector(params, "attractor", 3)
        self.stiffness = _vector(params, "stiffness", 3, minimum=0)
        self.damping = _vector(params, "damping", 3, minimum=0)
        for key in ("attractor", "stiffness", "damping"):
            if getattr(self, key) is None:
                raise params.error("is required", key)
        self.use_model_inertia = params.boolean("use_model_inertia", False)
        self.inertia_estimate = _vector(params, "inertia_estimate", n, positive=True)
        if self.inertia_estimate is None and not self.use_model_inertia:
            raise params.error("is required (or use_model_inertia: true)", "inertia_estimate")
        self.joint_damping = _vector(params, "joint_damping", n, 1.0, minimum=0, scalar=True)
        default_wrist = list(_CHAPTER_WRIST) if n == 7 else []
        wrist = params.raw("wrist_joints", default_wrist)
        if not isinstance(wrist, (list, tuple)):
            raise params.error("must be a list of joint indices (0-based, in joints order)", "wrist_joints",
                               wrist)
        for k, index in enumerate(wrist):
            if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < n:
                raise params.error(f"must be a joint index from 0 to {n - 1}", f"wrist_joints[{k}]", index)
            if index in wrist[:k]:
                raise params.error("is listed twice", f"wrist_joints[{k}]", index)
        if len(wrist) >= n:
            raise params.error("must leave at least one joint for the admittance dynamics", "wrist_joints",
                               wrist)
        self.wrist_joints = tuple(wrist)
        self.arm_joints = tuple(k for k in range(n) if k not in self.wrist_joints)
        self.wrist_gain = params.number("wrist_gain", 20.0, minimum=0)
        self._max_velocity = _vector(params, "max_velocity", n, positive=True, scalar=True)
        self.tare = params.boolean("tare", True)
        self.tare_time_s = params.number("tare_time_s", 0.2, minimum=0)
        params.reject_unknown({"type"})
        n_arm = len(self.arm_joints)
        self.velocity_reference = np.zeros(n_arm)  # the integrated arm-joint velocities [rad/s]
        self.velocity_command = [0.0] * n           # what was handed to the velocity controllers
        self.tare_force = np.zeros(3)

    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        return tuple((name, "command") for name in self.velocity_controllers)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        self.indices = [hardware.joint_index(j, source=self.source, field=f"{self.field}.joints[{k}]")
                        for k, j in enumerate(self.joint_names)]
        movable = {j.name for j in robot.movable_joints}
        for k, joint in enumerate(self.joint_names):
            if joint not in movable:
                raise ConfigError("the robot model has no movable joint of that name", source=self.source,
                                  field=f"{self.field}.joints[{k}]", value=joint)
        if self.sensor not in hardware.sensor_names:
            known = ", ".join(hardware.sensor_names) or "none"
            raise ConfigError(f"no force-torque sensor of that name (sensors: {known})",
                              source=self.source, field=f"{self.field}.sensor", value=self.sensor)
        spec = next((s for s in robot.sensors if s.name == self.sensor), None)
        if spec is None:
            raise ConfigError("the robot model describes no force-torque sensor of that name",
                              source=self.source, field=f"{self.field}.sensor", value=self.sensor)
        if self.frame is None:
            self.frame = spec.link
        elif not robot.has_link(self.frame):
            raise ConfigError("the robot model has no link of that name", source=self.source,
                              field=f"{self.field}.frame", value=self.frame)
        if self._max_velocity is None:
            limits = [robot.joint(j).limits for j in self.joint_names]
            self._max_velocity = np.array([lim.velocity if lim is not None and lim.velocity > 0 else math.inf
                                           for lim in limits])
        self.max_velocity = self._max_velocity
        gravity = self.context.gravity_m_s2 if self.context is not None else (0.0, 0.0, -9.81)
        self.kinematics = FlangeKinematics(robot, self.joint_names, self.frame, spec.link, gravity)
        self.hardware = hardware
        self.wrench = hardware.wrenches[self.sensor]
        self._A = np.array(self.arm_joints, dtype=int)
        self._W = np.array(self.wrist_joints, dtype=int)

    def bind_downstream(self, controllers: dict[str, Controller]) -> None:
        """Receive the velocity controllers this controller commands, one per joint, in order."""
        self.targets = []
        for k, (name, joint) in enumerate(zip(self.velocity_controllers, self.joint_names)):
            target = controllers[name]
            if not isinstance(target, JointVelocityController) or target.joints != (joint,):
                raise ConfigError(f"must name a velocity controller of joint {joint!r}", source=self.source,
                                  field=f"{self.field}.velocity_controllers[{k}]", value=name)
            self.targets.append(target)
        self._setters = [t.set_command for t in self.targets]

    def set_gains(self, *, stiffness=None, damping=None, inertia_estimate=None, attractor=None) -> None:
        """Change K, B, H or the attractor while running (validated; all or nothing; next cycle)."""
        n = len(self.joint_names)
        changes = {}
        for name, value, length, lower, strict in (
                ("stiffness", stiffness, 3, 0.0, False), ("damping", damping, 3, 0.0, False),
                ("inertia_estimate", inertia_estimate, n, 0.0, True),
                ("attractor", attractor, 3, None, False)):
            if value is None:
                continue
            ok = isinstance(value, (list, tuple, np.ndarray)) and len(value) == length and all(
                not isinstance(v, bool) and isinstance(v, (int, float, np.floating)) and math.isfinite(v)
                and (lower is None or (v > lower if strict else v >= lower)) for v in value)
            if not ok:
                bound = "" if lower is None else " above zero" if strict else " >= 0"
                raise ConfigError(f"must be {length} finite numbers{bound}", source=self.name, field=name,
                                  value=value)
            changes[name] = np.array(value, dtype=float)
        for name, value in changes.items():
            setattr(self, name, value)

    # -- the cycle ---------------------------------------------------------------------
    def _measure(self) -> None:
        hw, idx = self.hardware, self.indices
        position, velocity = hw.position, hw.velocity
        self.q = np.array([position[i] for i in idx])
        self.qd = np.array([velocity[i] for i in idx])
        kin = self.kinematics
        kin.set_pose(self.q, inertia=self.use_model_inertia)
        self.position = kin.position
        self.rotation = kin.rotation
        self.jv, self.jr = kin.jacobians()
        self.sensed_force = kin.sensor_rotation @ np.array(self.wrench[:3])  # base frame, before tare

    def start(self, time_s: float) -> None:
        self.hardware.read()
        self._measure()
        self.tare_force = self.sensed_force.copy() if self.tare else np.zeros(3)
        self._tare_sum, self._tare_count = np.zeros(3), 0
        self._tare_until_s = time_s + self.tare_time_s if self.tare else -math.inf
        self.target_rotation = self.rotation
        self.orientation_error = np.zeros(3)
        self.velocity_reference = np.zeros(len(self.arm_joints))
        self.velocity_command = [0.0] * len(self.joint_names)

    def inertia(self) -> np.ndarray:
        """H: the model's M(q) at the measured pose, or diag(inertia_estimate)."""
        if self.use_model_inertia:
            return self.kinematics.mass_matrix()
        return np.diag(self.inertia_estimate)

    def update(self, time_s: float, period_s: float) -> None:
        self._measure()
        if time_s < self._tare_until_s - 1e-9:  # taring: hold still, average the reading
            self._tare_sum += self.sensed_force
            self._tare_count += 1
            self.tare_force = self._tare_sum / self._tare_count
            for setter in self._setters:
                setter(0.0)
            return
        A, W = self._A, self._W
        self.velocity = self.jv @ self.qd
        self.force = self.sensed_force - self.tare_force
        f = self.stiffness * (self.attractor - self.position) - self.damping * self.velocity + self.force
        self.virtual_force = f
        self.torque = self.jv.T @ f
        generalized = self.torque - self.joint_damping * self.qd  # τ - c·q̇, per joint
        if W.size:
            jr_w, jr_a = self.jr[:, W], self.jr[:, A]
            pinv = jr_w.T @ np.linalg.inv(jr_w @ jr_w.T + WRIST_DLS_DAMPING**2 * np.eye(3))
            T = np.zeros((len(self.joint_names), len(A)))
            T[A, np.arange(len(A))] = 1.0
            T[W] = -pinv @ jr_a
            h = T.T @ self.inertia() @ T
            qdd = np.linalg.solve(h, T.T @ generalized)
        elif self.use_model_inertia:
            qdd = np.linalg.solve(self.inertia(), generalized)
        else:
            qdd = generalized / self.inertia_estimate
        self.acceleration = qdd
        limit = self.max_velocity
        ref = np.clip(self.velocity_reference + qdd * period_s, -limit[A], limit[A])  # once per cycle
        self.velocity_reference = ref
        command = np.zeros(len(self.joint_names))
        command[A] = ref
        if W.size:
            self.orientation_error = rotation_vector(self.target_rotation @ self.rotation.T)
            command[W] = np.clip(pinv @ (self.wrist_gain * self.orientation_error - jr_a @ ref),
                                 -limit[W], limit[W])
        commands = command.tolist()
        self.velocity_command = commands
        for setter, value in zip(self._setters, commands):
            setter(value)


__all__ = ["CartesianAdmittanceController", "FlangeKinematics", "rotation_vector"]

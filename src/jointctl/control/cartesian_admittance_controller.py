"""Natural admittance control of a flange in Cartesian space (chapter 11.6, figure 11.7).

``admittance_controllers/CartesianAdmittanceController`` makes the arm's flange behave like
a virtual mass-spring-damper in the base frame, pushed by the force measured at the
force-torque sensor. It is chained in front of one velocity controller per joint (it writes
their commands) and runs inside the control loop, before them, every cycle::

    p, Jv, Jr  = flange position, translational and rotational Jacobians at the measured q
                 (the robot's own model, :class:`~jointctl.model.dynamics.RobotDynamics`)
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

Cost. The update runs every cycle, so it allocates no arrays and inverts nothing larger than
3 x 3: the pose and Jacobians are views of the dynamics library's buffers, 3-vectors are floats,
H's inverse is kept from the last change of gains, and with H diagonal the wrist's constrained
dynamics are solved in the three dimensions of the flange's rotation (``_wrist_accelerations``:
the same q̈_A as ``(Tᵀ·H·T)⁻¹·Tᵀ·(τ - c·q̇)``, to rounding). ``M(q)`` changes every cycle, so with
``use_model_inertia`` it is factorised (Cholesky, ``_cholesky_solve``: on floats, n x n for n joints, or
``Tᵀ·M·T`` of the arm joints with wrist joints) every cycle.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from jointctl.control.controller import Controller
from jointctl.control.joint_controllers import JointVelocityController
from jointctl.control.params import Params
from jointctl.errors import ConfigError
from jointctl.hardware.interface import HardwareInterface
from jointctl.model.dynamics import RobotDynamics
from jointctl.model.robot_model import RobotModel

#: Damping of the least-squares inverse of the wrist's rotational Jacobian [rad].
WRIST_DLS_DAMPING = 0.01
_CHAPTER_WRIST = (4, 5, 6)


def _quaternion(m0: float, m1: float, m2: float, m3: float, m4: float, m5: float, m6: float, m7: float,
                m8: float) -> tuple[float, float, float, float]:
    """The unit quaternion (w, x, y, z) of a rotation matrix given row by row (MuJoCo's
    ``mju_mat2Quat``: from the largest component, then normalised)."""
    if m0 + m4 + m8 > 0:
        w = 0.5 * math.sqrt(1 + m0 + m4 + m8)
        x, y, z = 0.25 * (m7 - m5) / w, 0.25 * (m2 - m6) / w, 0.25 * (m3 - m1) / w
    elif m0 > m4 and m0 > m8:
        x = 0.5 * math.sqrt(1 + m0 - m4 - m8)
        w, y, z = 0.25 * (m7 - m5) / x, 0.25 * (m1 + m3) / x, 0.25 * (m2 + m6) / x
    elif m4 > m8:
        y = 0.5 * math.sqrt(1 - m0 + m4 - m8)
        w, x, z = 0.25 * (m2 - m6) / y, 0.25 * (m1 + m3) / y, 0.25 * (m5 + m7) / y
    else:
        z = 0.5 * math.sqrt(1 - m0 - m4 + m8)
        w, x, y = 0.25 * (m3 - m1) / z, 0.25 * (m2 + m6) / z, 0.25 * (m5 + m7) / z
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if abs(norm - 1.0) > 1e-15:
        inverse = 1.0 / norm
        w, x, y, z = w * inverse, x * inverse, y * inverse, z * inverse
    return w, x, y, z


def _rotation_vector(m0: float, m1: float, m2: float, m3: float, m4: float, m5: float, m6: float, m7: float,
                     m8: float) -> tuple[float, float, float]:
    w, x, y, z = _quaternion(m0, m1, m2, m3, m4, m5, m6, m7, m8)
    if w < 0:
        w, x, y, z = -w, -x, -y, -z
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        return 2.0 * x, 2.0 * y, 2.0 * z  # small-angle limit
    k = 2.0 * math.atan2(s, w) / s
    return k * x, k * y, k * z


def rotation_vector(rotation) -> np.ndarray:
    """Axis times angle [rad] (angle in [0, π]) of a rotation matrix."""
    return np.array(_rotation_vector(*np.asarray(rotation, dtype=float).ravel().tolist()))


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
        return tuple((name, "reference") for name in self.velocity_controllers)

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
        self.dynamics = RobotDynamics(robot, gravity, joints=self.joint_names)
        self.flange = self.dynamics.frame(self.frame)
        self.sensor_frame = self.dynamics.frame(spec.link)
        self.hardware = hardware
        self.wrench = hardware.wrenches[self.sensor]
        # Joint values straight from the hardware's lists when its joints are these, in order.
        self._gather = None if self.indices == list(range(len(hardware.joint_names))) else self.indices
        self._allocate()

    def _allocate(self) -> None:
        """The cycle's work buffers and constants (with H diagonal, update() allocates no arrays)."""
        n = len(self.joint_names)
        self._qd = np.zeros(n)
        self.velocity = np.zeros(3)          # flange velocity Jv·q̇, base frame [m/s]
        self.torque = np.zeros(n)            # Jvᵀ·f [N·m]
        self._generalized = np.zeros(n)      # τ - c·q̇ [N·m]
        arm_then_wrist = self.arm_joints + self.wrist_joints
        self._joint_order = [arm_then_wrist.index(k) for k in range(n)]  # where joint k is in that list
        limit = self.max_velocity.tolist()
        self._arm_limits = [(-limit[k], limit[k]) for k in self.arm_joints]
        self._wrist_limits = [(-limit[k], limit[k]) for k in self.wrist_joints]
        if self.use_model_inertia:
            self._mass = np.zeros((n, n))
        self._cache_gains()

    def _cache_gains(self) -> None:
        """The gains as floats for the cycle (after every change)."""
        self._gains = (*self.stiffness.tolist(), *self.damping.tolist(), *self.attractor.tolist())
        if self.inertia_estimate is not None:
            self._inertia = self.inertia_estimate.tolist()
            self._inverse_inertia = (1.0 / self.inertia_estimate).tolist()

    def bind_downstream(self, controllers: dict[str, Controller]) -> None:
        """Receive the velocity controllers this controller commands, one per joint, in order."""
        self.targets = []
        for k, (name, joint) in enumerate(zip(self.velocity_controllers, self.joint_names)):
            target = controllers[name]
            if not isinstance(target, JointVelocityController) or target.joints != (joint,):
                raise ConfigError(f"must name a velocity controller of joint {joint!r}", source=self.source,
                                  field=f"{self.field}.velocity_controllers[{k}]", value=name)
            self.targets.append(target)
        # Their reference interfaces (chained mode), written in place every cycle: by slice when
        # the velocity controllers' joints are consecutive hardware joints, in order.
        self._velocities = self.targets[0].context.reference_velocities
        indices = [t.index for t in self.targets]
        consecutive = indices == list(range(indices[0], indices[0] + len(indices)))
        self._span = slice(indices[0], indices[0] + len(indices)) if consecutive else None
        self._target_indices = indices

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
        if hasattr(self, "_gains"):  # configured
            self._cache_gains()

    # -- the cycle ---------------------------------------------------------------------
    def _measure(self) -> None:
        """Joint state, the pose and Jacobians at it, and the sensed force in the base frame."""
        hw, gather = self.hardware, self._gather
        if gather is None:
            position, self._qd[:] = hw.position, hw.velocity
        else:
            position = [hw.position[i] for i in gather]
            self._qd[:] = [hw.velocity[i] for i in gather]
        self.dynamics.set_pose(position, inertia=self.use_model_inertia)
        self.jv, self.jr = self.flange.jacobians()
        self.position = self.flange.position
        self.rotation = self.flange.rotation
        (r0, r1, r2), (r3, r4, r5), (r6, r7, r8) = self.sensor_frame.rotation.tolist()
        w = self.wrench
        w0, w1, w2 = w[0], w[1], w[2]
        self.sensed_force = (r0 * w0 + r1 * w1 + r2 * w2, r3 * w0 + r4 * w1 + r5 * w2,
                             r6 * w0 + r7 * w1 + r8 * w2)  # base frame, before tare

    def start(self, time_s: float) -> None:
        self.hardware.read()
        self._measure()
        self.tare_force = np.array(self.sensed_force) if self.tare else np.zeros(3)
        self._tare = tuple(self.tare_force.tolist())
        self._tare_sum, self._tare_count = np.zeros(3), 0
        self._tare_until_s = time_s + self.tare_time_s if self.tare else -math.inf
        self.target_rotation = self.rotation.copy()
        self.orientation_error = (0.0, 0.0, 0.0)
        self.velocity_reference = [0.0] * len(self.arm_joints)
        self.velocity_command = [0.0] * len(self.joint_names)

    def inertia(self) -> np.ndarray:
        """H: the model's M(q) at the measured pose, or diag(inertia_estimate)."""
        if self.use_model_inertia:
            return self.dynamics.mass_matrix()
        return np.diag(self.inertia_estimate)

    def update(self, time_s: float, period_s: float) -> None:
        self._measure()
        if time_s < self._tare_until_s - 1e-9:  # taring: hold still, average the reading
            self._tare_sum += self.sensed_force
            self._tare_count += 1
            self.tare_force = self._tare_sum / self._tare_count
            self._tare = tuple(self.tare_force.tolist())
            self._hand_over([0.0] * len(self.joint_names))
            return
        qd, jv = self._qd, self.jv
        # Products and sums one by one, in a fixed order (not BLAS's, which may pair or fuse them otherwise):
        # the compiled cycle's kernel does the same operations.
        q = qd.tolist()
        jx, jy, jz = jv.tolist()
        vx, vy, vz = jx[0] * q[0], jy[0] * q[0], jz[0] * q[0]  # v = Jv·q̇
        for j in range(1, len(q)):
            vx += jx[j] * q[j]; vy += jy[j] * q[j]; vz += jz[j] * q[j]  # noqa: E702
        self.velocity[:] = vx, vy, vz
        px, py, pz = self.position.tolist()
        (sx, sy, sz), (tx, ty, tz) = self.sensed_force, self._tare
        self.force = (sx - tx, sy - ty, sz - tz)
        kx, ky, kz, bx, by, bz, ax, ay, az = self._gains
        f = self.virtual_force = [kx * (ax - px) - bx * vx + (sx - tx),
                                  ky * (ay - py) - by * vy + (sy - ty),
                                  kz * (az - pz) - bz * vz + (sz - tz)]
        f0, f1, f2 = f
        self.torque[:] = [f0 * x + f1 * y + f2 * z for x, y, z in zip(jx, jy, jz)]  # τ = Jvᵀ·f
        generalized = np.multiply(self.joint_damping, qd, out=self._generalized)
        np.subtract(self.torque, generalized, out=generalized)  # τ - c·q̇, per joint
        if self.use_model_inertia:
            qdd = self._model_accelerations(generalized)
        elif self.wrist_joints:
            qdd = self._wrist_accelerations(generalized.tolist())
        else:
            qdd = [g / h for g, h in zip(generalized.tolist(), self._inertia)]
        self.acceleration = qdd
        # q̇_cmd += q̈·dt once per cycle, within the limits
        ref = self.velocity_reference = [
            lower if r < lower else upper if r > upper else r
            for r, (lower, upper) in zip([r + a * period_s for r, a in zip(self.velocity_reference, qdd)],
                                         self._arm_limits)]
        values = ref + self._wrist_command(ref) if self.wrist_joints else ref  # arm joints, then wrist joints
        self._hand_over([values[k] for k in self._joint_order])

    def _hand_over(self, velocities: list[float]) -> None:
        """Write ``velocities`` [rad/s or m/s], per joint in ``joints`` order, into the velocity
        controllers' reference interfaces."""
        self.velocity_command = velocities
        if self._span is not None:
            self._velocities[self._span] = velocities
        else:
            for i, v in zip(self._target_indices, velocities):
                self._velocities[i] = v

    # The wrist, with H diagonal, worked in the three dimensions of the flange's rotation. With
    # G = Jr_W·Jr_Wᵀ + λ²·I and Jr_W⁺ = Jr_Wᵀ·G⁻¹ (row w: p_wᵀ, p_w = G⁻¹·jr_w), P = Jr_W⁺·Jr_A, so
    #     Tᵀ·H·T = H_A + Pᵀ·H_W·P = H_A + Jr_Aᵀ·Q·Jr_A,   Q = Σ_w H_w·p_w·p_wᵀ,
    #     Tᵀ·g   = g_A - Jr_Aᵀ·t,                         t = Σ_w g_w·p_w,
    # and by the push-through identity (no inverse of Q: it is singular with fewer than three
    # wrist joints, or where Jr_W is)
    #     (H_A + Jr_Aᵀ·Q·Jr_A)⁻¹·x = u - H_A⁻¹·Jr_Aᵀ·Q·(I + K·Q)⁻¹·(Jr_A·u),   u = H_A⁻¹·x,
    # with K = Jr_A·H_A⁻¹·Jr_Aᵀ: every inverse is of a 3 x 3 matrix, whatever the joints. The p_w
    # are formed before any product with H_W or g_W: G⁻¹ alone is large (up to 1/λ²) along
    # rotations the wrist cannot make, Jr_W⁺ is not.
    def _wrist_rows(self) -> tuple[list, list]:
        """Jr's columns (per joint) and the rows of Jr_W⁺ = Jr_Wᵀ·(Jr_W·Jr_Wᵀ + λ²·I)⁻¹ (per wrist joint), kept in
        ``jr_columns`` and ``_dls_rows``."""
        jr = self.jr_columns = self.jr.T.tolist()  # per joint: its column of Jr
        g00 = g01 = g02 = g11 = g12 = g22 = 0.0  # Jr_W·Jr_Wᵀ
        for j in self.wrist_joints:
            x, y, z = jr[j]
            g00 += x * x; g01 += x * y; g02 += x * z; g11 += y * y; g12 += y * z; g22 += z * z  # noqa: E702
        lam2 = WRIST_DLS_DAMPING**2
        gi = _symmetric_inverse(g00 + lam2, g01, g02, g11 + lam2, g12, g22 + lam2)
        self._dls_rows = rows = [_symmetric_times(gi, *jr[j]) for j in self.wrist_joints]
        return jr, rows

    def _wrist_accelerations(self, g: list[float]) -> list[float]:
        """q̈_A with the wrist holding the flange orientation, H = diag(inertia_estimate)."""
        jr, rows = self._wrist_rows()  # Jr's columns, the p_w
        h, h_inverse = self._inertia, self._inverse_inertia
        q00 = q01 = q02 = q11 = q12 = q22 = 0.0  # Q
        t0 = t1 = t2 = 0.0                       # t
        for j, (x, y, z) in zip(self.wrist_joints, rows):
            gj, hx, hy, hz = g[j], h[j] * x, h[j] * y, h[j] * z
            q00 += hx * x; q01 += hx * y; q02 += hx * z; q11 += hy * y; q12 += hy * z; q22 += hz * z  # noqa: E702
            t0 += gj * x; t1 += gj * y; t2 += gj * z  # noqa: E702
        k00 = k01 = k02 = k11 = k12 = k22 = 0.0  # K
        y0 = y1 = y2 = 0.0                       # Jr_A·u
        u = []
        for j in self.arm_joints:
            x, y, z = jr[j]
            hi = h_inverse[j]
            uj = (g[j] - (x * t0 + y * t1 + z * t2)) * hi
            u.append(uj)
            y0 += x * uj; y1 += y * uj; y2 += z * uj  # noqa: E702
            hx, hy, hz = hi * x, hi * y, hi * z
            k00 += hx * x; k01 += hx * y; k02 += hx * z; k11 += hy * y; k12 += hy * z; k22 += hz * z  # noqa: E702
        w0, w1, w2 = _solve3(  # (I + K·Q)·w = Jr_A·u
            1.0 + k00 * q00 + k01 * q01 + k02 * q02, k00 * q01 + k01 * q11 + k02 * q12,
            k00 * q02 + k01 * q12 + k02 * q22,
            k01 * q00 + k11 * q01 + k12 * q02, 1.0 + k01 * q01 + k11 * q11 + k12 * q12,
            k01 * q02 + k11 * q12 + k12 * q22,
            k02 * q00 + k12 * q01 + k22 * q02, k02 * q01 + k12 * q11 + k22 * q12,
            1.0 + k02 * q02 + k12 * q12 + k22 * q22, y0, y1, y2)
        z0, z1, z2 = _symmetric_times((q00, q01, q02, q11, q12, q22), w0, w1, w2)
        return [uj - (x * z0 + y * z1 + z * z2) * h_inverse[j]
                for uj, j, (x, y, z) in zip(u, self.arm_joints, (jr[j] for j in self.arm_joints))]

    def _model_accelerations(self, generalized: np.ndarray) -> list[float]:
        """q̈_A with H = M(q), the model's inertia: ``(Tᵀ·M·T)·q̈_A = Tᵀ·g``, T = [I; -P], P = Jr_W⁺·Jr_A
        (the Cholesky solve on floats, in the order the compiled kernel repeats)."""
        mass = self.dynamics.mass_matrix(self._mass).tolist()
        g = generalized.tolist()
        if not self.wrist_joints:
            return _cholesky_solve(mass, g)
        jr, rows = self._wrist_rows()  # Jr's columns, Jr_W⁺ row by row
        arm, wrist = self.arm_joints, self.wrist_joints
        p = [[x * jr[a][0] + y * jr[a][1] + z * jr[a][2] for a in arm] for x, y, z in rows]  # P = Jr_W⁺·Jr_A
        mt = []  # M·T, row by row
        for row in mass:
            out = []
            for b, a in enumerate(arm):
                value = row[a]
                for w, j in enumerate(wrist):
                    value -= row[j] * p[w][b]
                out.append(value)
            mt.append(out)
        system, rhs = [], []  # Tᵀ·M·T, Tᵀ·g
        for b, a in enumerate(arm):
            row, value = list(mt[a]), g[a]
            for w, j in enumerate(wrist):
                pw, mj = p[w][b], mt[j]
                for c in range(len(arm)):
                    row[c] -= pw * mj[c]
                value -= pw * g[j]
            system.append(row)
            rhs.append(value)
        return _cholesky_solve(system, rhs)

    def _wrist_command(self, ref: list[float]) -> list[float]:
        """``q̇_W = Jr_W⁺·(k·e - Jr_A·q̇_A)``, within the limits: the flange's rotation by the arm joints
        cancelled, any orientation error e decaying at the wrist gain k."""
        (t0, t1, t2), (t3, t4, t5), (t6, t7, t8) = self.target_rotation.tolist()
        (r0, r1, r2), (r3, r4, r5), (r6, r7, r8) = self.rotation.tolist()
        m0, m1, m2 = t0 * r0 + t1 * r1 + t2 * r2, t0 * r3 + t1 * r4 + t2 * r5, t0 * r6 + t1 * r7 + t2 * r8  # R_0·Rᵀ
        m3, m4, m5 = t3 * r0 + t4 * r1 + t5 * r2, t3 * r3 + t4 * r4 + t5 * r5, t3 * r6 + t4 * r7 + t5 * r8
        m6, m7, m8 = t6 * r0 + t7 * r1 + t8 * r2, t6 * r3 + t7 * r4 + t8 * r5, t6 * r6 + t7 * r7 + t8 * r8
        e0, e1, e2 = self.orientation_error = _rotation_vector(m0, m1, m2, m3, m4, m5, m6, m7, m8)
        k, jr = self.wrist_gain, self.jr_columns
        b0, b1, b2 = k * e0, k * e1, k * e2
        for j, r in zip(self.arm_joints, ref):
            x, y, z = jr[j]
            b0 -= x * r; b1 -= y * r; b2 -= z * r  # noqa: E702
        out = []
        for (x, y, z), (lower, upper) in zip(self._dls_rows, self._wrist_limits):  # Jr_W⁺·b, row by row
            c = x * b0 + y * b1 + z * b2
            out.append(lower if c < lower else upper if c > upper else c)
        return out


# -- 3 x 3 arithmetic on floats (symmetric matrices as their upper triangle a00 a01 a02 a11 a12 a22) --
def _symmetric_inverse(a00: float, a01: float, a02: float, a11: float, a12: float,
                       a22: float) -> tuple[float, ...]:
    """The inverse of a symmetric positive definite 3 x 3 matrix (adjugate over determinant)."""
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    d = 1.0 / (a00 * c00 + a01 * c01 + a02 * c02)
    return c00 * d, c01 * d, c02 * d, c11 * d, c12 * d, c22 * d


def _symmetric_times(a: Sequence[float], x0: float, x1: float, x2: float) -> tuple[float, float, float]:
    """``A·x`` for a symmetric A."""
    a00, a01, a02, a11, a12, a22 = a
    return (a00 * x0 + a01 * x1 + a02 * x2, a01 * x0 + a11 * x1 + a12 * x2, a02 * x0 + a12 * x1 + a22 * x2)


def _solve3(m00: float, m01: float, m02: float, m10: float, m11: float, m12: float, m20: float, m21: float,
            m22: float, b0: float, b1: float, b2: float) -> tuple[float, float, float]:
    """``M⁻¹·b`` for an invertible 3 x 3 matrix M (Cramer's rule)."""
    c00, c10, c20 = m11 * m22 - m12 * m21, m12 * m20 - m10 * m22, m10 * m21 - m11 * m20
    d = 1.0 / (m00 * c00 + m01 * c10 + m02 * c20)
    return ((c00 * b0 + (m02 * m21 - m01 * m22) * b1 + (m01 * m12 - m02 * m11) * b2) * d,
            (c10 * b0 + (m00 * m22 - m02 * m20) * b1 + (m02 * m10 - m00 * m12) * b2) * d,
            (c20 * b0 + (m01 * m20 - m00 * m21) * b1 + (m00 * m11 - m01 * m10) * b2) * d)


def _cholesky_solve(a: list[list[float]], b: list[float]) -> list[float]:
    """``A⁻¹·b`` for a symmetric positive definite n x n ``A`` (lists of floats; its lower triangle is read):
    ``A = L·Lᵀ`` column by column, then ``L·y = b`` and ``Lᵀ·x = y``. Raises ``np.linalg.LinAlgError`` when
    ``A`` is not positive definite (a pivot not above zero), as numpy's solvers do: the loop's failure policy
    stops the controller. The compiled kernel does the same operations in the same order."""
    n = len(b)
    lower = [[0.0] * n for _ in range(n)]
    for j in range(n):
        lj = lower[j]
        pivot = a[j][j]
        for k in range(j):
            pivot -= lj[k] * lj[k]
        if not pivot > 0.0:  # (also NaN)
            raise np.linalg.LinAlgError(f"not positive definite (pivot {pivot!r} at row {j})")
        d = lj[j] = math.sqrt(pivot)
        for i in range(j + 1, n):
            li = lower[i]
            value = a[i][j]
            for k in range(j):
                value -= li[k] * lj[k]
            li[j] = value / d
    y = [0.0] * n
    for i in range(n):  # L·y = b
        li = lower[i]
        value = b[i]
        for k in range(i):
            value -= li[k] * y[k]
        y[i] = value / li[i]
    x = [0.0] * n
    for i in range(n - 1, -1, -1):  # Lᵀ·x = y
        value = y[i]
        for k in range(i + 1, n):
            value -= lower[k][i] * x[k]
        x[i] = value / lower[i][i]
    return x


__all__ = ["CartesianAdmittanceController", "rotation_vector"]

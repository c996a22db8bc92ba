"""Single-joint effort controllers: ``effort_controllers/JointPositionController`` and
``effort_controllers/JointVelocityController``.

Both read ``joint`` and ``pid`` from their YAML entry, claim the joint's
effort interface, and clamp their PID output to the joint's effort limit.

Their reference (input) comes one way: the reference interfaces of their joint in the
manager's :class:`~jointctl.control.context.ControlContext` (position, velocity,
acceleration), read every update. An upstream controller in the loop (chained mode) writes
those slots directly; edges use :meth:`~JointPositionController.set_reference`, which
refuses a value that is not a finite number with :class:`~jointctl.errors.InvalidCommand`
(the previous reference stays), refuses while the controller is chained (its upstream owns
the reference), and writes the same slots, read by the next cycle. Position references are
clamped to the joint's range and velocity references to its velocity limit, as ros_control
does; the clamped value is the reference in use (``reference``, the trace's column). Clamping is
counted, not silent: ``clamped_cycles`` and the reference furthest outside, ``clamped_furthest``
(:func:`jointctl.commands.limits.clamp_warning` words them).
"""

from __future__ import annotations

import math

from jointctl.control.context import ControlContext
from jointctl.control.controller import Controller
from jointctl.control.params import Params
from jointctl.control.pid import Pid, PidGains
from jointctl.errors import ConfigError, InvalidCommand
from jointctl.hardware.interface import EFFORT, HardwareInterface
from jointctl.model.robot_model import RobotModel
from jointctl.validate import finite_number


class _EffortJointController(Controller):
    """Shared parts: one joint, one PID, the effort interface."""

    def __init__(self, name: str, params: Params) -> None:
        super().__init__(name, params)
        self.joint = params.string("joint")
        self.joints = (self.joint,)
        self._pid_params = params.child("pid") if params.has("pid") else Params(
            {}, source=params.source, field=params.path("pid"))
        params.reject_unknown({"type"})
        self.pid: Pid | None = None
        #: Cycles whose reference was outside the joint's limits and clamped, and the reference furthest outside
        #: (None before the first).
        self.clamped_cycles = 0
        self.clamped_furthest: float | None = None

    def _clamp(self, value: float, low: float, high: float) -> float:
        """``value`` clamped to [low, high], counted (the rare path of a reference outside the limits)."""
        self.clamped_cycles += 1
        bound = low if value < low else high
        furthest = self.clamped_furthest
        if furthest is None or abs(value - bound) > abs(furthest - (low if furthest < low else high)):
            self.clamped_furthest = value
        return bound

    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        return ((self.joint, EFFORT),)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        self.index = hardware.joint_index(self.joint, source=self.source, field=f"{self.field}.joint")
        if not robot.has_joint(self.joint):
            raise ConfigError("the robot model has no joint of that name", source=self.source,
                              field=f"{self.field}.joint", value=self.joint)
        joint = robot.joint(self.joint)
        if EFFORT not in hardware.command_interfaces(self.joint):
            raise ConfigError("the joint has no effort command interface (no transmission)",
                              source=self.source, field=f"{self.field}.joint", value=self.joint)
        limits = joint.limits
        self.effort_limit = limits.effort if limits is not None and limits.effort > 0 else math.inf
        self.velocity_limit = limits.velocity if limits is not None and limits.velocity > 0 else math.inf
        self.lower = limits.lower if limits is not None and limits.lower is not None else -math.inf
        self.upper = limits.upper if limits is not None and limits.upper is not None else math.inf
        self.pid = Pid(PidGains.from_params(self._pid_params, default_i_clamp=self.effort_limit),
                       self.effort_limit)
        self.hardware = hardware
        self.effort_command = hardware.command_buffer(EFFORT)
        if self.context is None:  # built outside a manager
            self.context = ControlContext(hardware, robot)
        context = self.context
        self.references = context.references
        # The joint's reference interfaces (shared lists, indexed by hardware joint).
        self._positions = context.reference_positions
        self._velocities = context.reference_velocities
        self._accelerations = context.reference_accelerations

    @property
    def reference(self) -> float:
        """The reference in use (position in m or rad, or velocity in m/s or rad/s), after clamping."""
        return self.references[self.index]

    def _check_edge(self, value: float) -> None:
        """Refuse an edge's reference while an upstream controller owns this one's (chained mode)."""
        if self.upstream is not None:
            raise InvalidCommand(f"the reference comes from controller {self.upstream!r} (chained)",
                                 source=self.name, field="reference", value=value)

    def set_gains(self, gains: PidGains) -> None:
        """Change the PID gains while running; applied at the next cycle."""
        self.pid.set_gains(gains)

    def _finite(self, value: float, what: str) -> float:
        """``value`` as a finite float, or InvalidCommand naming ``what``."""
        # Fast path for the common case (a finite float); x - x is 0.0 only when x is finite.
        if type(value) is float and value - value == 0.0:
            return value
        number = finite_number(value)
        if number is None:
            raise InvalidCommand("command must be a finite number", source=self.name, field=what,
                                 value=value)
        return number


FEEDFORWARD_TERMS = ("gravity", "damping", "inertia")
#: The position controller's derivative laws (its ``derivative`` parameter): ros_control's (the
#: error's difference for a plain command, the velocity error for a reference with a velocity)
#: and jointctl's (the velocity error always: derivative on measurement for a plain command).
DERIVATIVE_ERROR, DERIVATIVE_MEASUREMENT = "error", "measurement"
DERIVATIVE_LAWS = (DERIVATIVE_ERROR, DERIVATIVE_MEASUREMENT)


class _Plain(float):
    """The default velocity of :meth:`JointPositionController.set_reference`: none given (a plain
    position command); a float 0.0 so that it reads as no velocity feed-forward."""

    def __repr__(self) -> str:
        return "PLAIN"


PLAIN = _Plain(0.0)


def derivative_law(parameters: dict) -> str:
    """The derivative law a position controller's YAML entry (a dict) asks for: its ``derivative``,
    else ``error`` (ros_controllers' law, which a real ros_control robot runs)."""
    return str(parameters.get("derivative", DERIVATIVE_ERROR)) if isinstance(parameters, dict) else DERIVATIVE_ERROR


_TWO_PI = 2.0 * math.pi


def wrap_angle(angle: float) -> float:
    """``angle`` [rad] plus the whole turns that bring it into (-π, π] [rad]."""
    wrapped = angle - _TWO_PI * math.ceil((angle - math.pi) / _TWO_PI)
    # Rounding in the subtraction can land a hair outside the interval; fold it back.
    if wrapped <= -math.pi:
        wrapped += _TWO_PI
    elif wrapped > math.pi:
        wrapped -= _TWO_PI
    return wrapped


class JointPositionController(_EffortJointController):
    """Effort from a PID on position error, plus optional model-based feed-forward.

    The derivative term follows ros_controllers' ``effort_controllers/JointPositionController``
    (``derivative: error``, the default), choosing by whether the reference *carries a velocity*:

    - it carries one when an upstream controller writes it (chained mode: a trajectory executor,
      whose velocity may be 0 without feed-forward, as ros_control's ``setCommand(pos, vel)``) or
      when an edge gives ``set_reference(position, velocity)`` with a velocity (the simulated
      industrial controller does): the d term acts on ``velocity reference - measured velocity``;
    - a plain position command (``set_reference(position)``: the ``command`` topic, the tuning
      page, autotune's and bode's steps and sines, a scenario's reference source) carries none:
      the d term acts on the backward difference of the error, ``(e - e_last)/period`` (the rate
      of the last call with a velocity, else 0, on the first call after start), as
      control_toolbox's ``computeCommand(error, dt)``: a step of Δ gives one cycle of ``d·Δ/period``
      (the derivative kick), then ``-d·q̇`` (as a difference).

    ``derivative: measurement`` keeps jointctl's own law: the d term always acts on
    ``velocity reference - measured velocity`` (0 reference for a plain command), so a plain
    command gives exactly ``p·err - d·q̇``: no kick, no differencing, the law of the book's
    minimal_joint_controller and of the mass-spring-damper ``p / (m s² + (b + d) s + p)``. The loop
    models of ``bode`` and ``autotune`` follow the law the controller runs (:attr:`derivative`).
    On start the controller holds the joint where it is (a plain command).

    On a continuous joint (no position limits) the error is the shortest way
    round: ``command - position`` wrapped to (-π, π] rad, as ros_control's
    controller and the book's minimal_joint_controller do, so a command of
    3 rad with the joint at -3 rad turns it 0.28 rad backwards, not 6 rad forwards.

    ``feedforward: {gravity: true, damping: true, inertia: true}`` adds, from the
    robot model: the effort holding the measured pose against gravity, the
    joint damping ``b·q̇_ref``, and ``M(q)·q̈_ref`` for the acceleration
    reference. The sum is clamped to the joint's effort limit.
    """

    controlled = "position"  # the quantity the reference is compared with

    def __init__(self, name: str, params: Params) -> None:
        self._ff_params = params.child("feedforward") if params.has("feedforward") else None
        # Read before the base class refuses unknown keys.
        self.derivative = params.string("derivative", DERIVATIVE_ERROR)
        if self.derivative not in DERIVATIVE_LAWS:
            raise params.error(f"must be one of {', '.join(DERIVATIVE_LAWS)}", "derivative", self.derivative)
        super().__init__(name, params)
        ff = self._ff_params
        self.feedforward_terms = tuple(t for t in FEEDFORWARD_TERMS if ff is not None and ff.boolean(t, False))
        if ff is not None:
            ff.reject_unknown()

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        super().configure(hardware, robot)
        self.joint_damping = robot.joint(self.joint).damping
        self.continuous = robot.joint(self.joint).type == "continuous"
        self._gravity = "gravity" in self.feedforward_terms
        self._damping = "damping" in self.feedforward_terms
        self._inertia = "inertia" in self.feedforward_terms
        self.uses_model = self._gravity or self._inertia
        self.uses_model_inertia = self._inertia
        self._model = self.context.feedforward if self.uses_model else None
        self._on_error = self.derivative == DERIVATIVE_ERROR
        self._edge_velocity = False
        self._reset_difference()

    def _reset_difference(self) -> None:
        """control_toolbox's ``Pid::reset()``: no last error yet, the last rate 0."""
        self._last_error = 0.0
        self._last_valid = False
        self._last_rate = 0.0

    def set_reference(self, position: float, velocity: float = PLAIN, acceleration: float = 0.0) -> None:
        """The edge door: a position [m or rad] with optional velocity [/s] and acceleration [/s²]
        references, validated, into the joint's reference interfaces (refused while chained). With
        a velocity (even 0) the reference carries one; without, it is a plain position command
        (see the class docstring for what the derivative then acts on)."""
        carries = velocity is not PLAIN
        if not carries:
            velocity = 0.0
        # One check for the usual case, three finite floats (x - x is 0.0 only for a finite x).
        if not (type(position) is float and type(velocity) is float and type(acceleration) is float
                and position - position + velocity - velocity + acceleration - acceleration == 0.0):
            position = self._finite(position, "reference.position")
            velocity = self._finite(velocity, "reference.velocity")
            acceleration = self._finite(acceleration, "reference.acceleration")
        self._check_edge(position)
        i = self.index
        self._velocities[i], self._accelerations[i] = velocity, acceleration
        self._edge_velocity = carries
        self._positions[i] = position

    @property
    def reference_input(self) -> tuple[float, float, float]:
        """The reference as given (position, velocity, acceleration), before clamping."""
        i = self.index
        return self._positions[i], self._velocities[i], self._accelerations[i]

    def start(self, time_s: float) -> None:
        self.hardware.read()
        i = self.index
        self._positions[i], self._velocities[i], self._accelerations[i] = self.hardware.position[i], 0.0, 0.0
        self._edge_velocity = False  # ros_control's starting(): setCommand(position), a plain command
        self.pid.reset()
        self._reset_difference()

    def update(self, time_s: float, period_s: float) -> None:
        i = self.index
        position, velocity = self._positions[i], self._velocities[i]
        lower, upper = self.lower, self.upper
        if position < lower or position > upper:
            position = self._clamp(position, lower, upper)
        self.references[i] = position
        hw = self.hardware
        error = position - hw.position[i]
        if self.continuous and not -math.pi < error <= math.pi:
            error = wrap_angle(error)
        if self._on_error and self.upstream is None and not self._edge_velocity:
            # A plain command, ros_control's law: computeCommand(error, dt) differentiates the error.
            if self._last_valid:
                rate = (error - self._last_error) / period_s
            else:
                rate = self._last_rate
                self._last_valid = True
            self._last_error = error
        else:
            rate = velocity - hw.velocity[i]
        self._last_rate = rate
        effort = self.pid.compute(error, rate, period_s)
        if self.feedforward_terms:
            model = self._model
            if self._gravity:
                effort += model.gravity[i]
            if self._damping:
                effort += self.joint_damping * velocity
            if self._inertia:
                effort += model.inertia[i]
            limit = self.effort_limit
            effort = limit if effort > limit else -limit if effort < -limit else effort
        self.effort_command[i] = effort


class JointVelocityController(_EffortJointController):
    """Effort from a PID on velocity error; ``d`` acts on the error's backward difference (0 on
    the first update after start, as control_toolbox's ``computeCommand(error, dt)``).

    On start the reference is zero velocity.

    ``command_timeout_s`` (optional, positive; default none: no watchdog, as ros_control): a
    reference from an edge older than this in loop time (since the cycle that first saw it) is
    replaced by zero velocity, every cycle, until a new one arrives: a silent commander holds the
    joint instead of driving it on forever. In chained mode the watchdog is off: the upstream
    controller writes the reference every cycle of the same loop.
    """

    controlled = "velocity"  # the quantity the reference is compared with

    def __init__(self, name: str, params: Params) -> None:
        # Read before the base class refuses unknown keys.
        self.command_timeout_s = params.number("command_timeout_s", None, positive=True)
        super().__init__(name, params)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        super().configure(hardware, robot)
        self._last_error = 0.0
        self._last_valid = False
        self._token = self._seen = None
        self._command_time = 0.0
        self.timed_out = False

    def set_reference(self, velocity: float) -> None:
        """The edge door: a velocity [m/s or rad/s], validated, into the joint's reference
        interface (refused while chained)."""
        velocity = self._finite(velocity, "reference")
        self._check_edge(velocity)
        self._velocities[self.index] = velocity
        # Stored after the reference: a cycle that sees this token sees it (or a newer one).
        self._token = object()

    @property
    def reference_input(self) -> float:
        """The reference as given, before clamping [m/s or rad/s]."""
        return self._velocities[self.index]

    def start(self, time_s: float) -> None:
        self._velocities[self.index] = 0.0
        self._last_error = 0.0
        self._token = self._seen = None
        self._command_time = time_s
        self.timed_out = False
        self.pid.reset()
        self._last_valid = False

    def update(self, time_s: float, period_s: float) -> None:
        i = self.index
        velocity = self._velocities[i]
        timeout = self.command_timeout_s
        if timeout is not None and self.upstream is None:
            token = self._token
            if token is not self._seen:  # a new reference: its age counts from this cycle
                self._seen = token
                self._command_time = time_s
                velocity = self._velocities[i]
            self.timed_out = time_s - self._command_time > timeout
            if self.timed_out:
                velocity = 0.0
        limit = self.velocity_limit
        if velocity < -limit or velocity > limit:
            velocity = self._clamp(velocity, -limit, limit)
        self.references[i] = velocity
        error = velocity - self.hardware.velocity[i]
        rate = (error - self._last_error) / period_s if self._last_valid else 0.0
        self._last_valid = True
        self._last_error = error
        self.effort_command[i] = self.pid.compute(error, rate, period_s)

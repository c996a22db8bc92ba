"""``pid_controller/PidController``: ros2_controllers 4.18's PID controller, computing as it does.

Parameters (the controller's ``ros__parameters``, as ros2_controllers declares them)::

    pid_controller:
      ros__parameters:
        dof_names: [joint1]                        # the joints it commands
        command_interface: effort                  # the interface it writes
        reference_and_state_interfaces: [position, velocity]   # 1 or 2; the 2nd the 1st's derivative
        reference_and_state_dof_names: []          # optional: the joints it reads (default dof_names)
        use_external_measured_states: false        # true: the state comes through set_measured_state
        gains:
          joint1: {p: 400.0, i: 0.0, d: 20.0, i_clamp_max: 0.0, i_clamp_min: 0.0,
                   feedforward_gain: 0.0, antiwindup: false, angle_wraparound: false}

Every gain defaults to 0 (false), as ros2_controllers declares them; a gain entry may be left out.

What it computes each cycle, per dof (``update_and_write_commands``): nothing until its reference is a
number (before the first reference the reference, error and output it reports are NaN and it writes no
command); then ``error = reference - state`` (the shortest angle with ``angle_wraparound``) and

- with two interfaces and both derivatives known: ``command = ff + Pid(error, reference_dot - state_dot)``;
- otherwise: ``command = ff + Pid(error)``, the rate being the error's backward difference (derivative
  on the error: a reference step gives one cycle of ``d·Δ/period``, and the first computation after
  loading ``d·error/period``);

``Pid`` is control_toolbox 3.4.0's (:class:`~jointctl.control.toolbox_pid.ToolboxPid`: the integral
clamped as a term without ``antiwindup``, so the default clamps 0/0 silence ``i``); ``ff`` is
``feedforward_gain · reference_dot`` while feed-forward is on (:meth:`PidController.set_feedforward`,
the ``~/set_feedforward_control`` service; off at start), else 0. Like ros2_controllers 4.18 the PIDs
are not reset when the controller starts again: their integral and last error carry over. There is no
output limit in the controller; the hardware's effort limit applies.

Doors, for edges (a ROS 2 node's callbacks) and command sources; each call is validated at once
(:class:`~jointctl.errors.InvalidCommand` on refusal, nothing changed) and the loop takes it at the start
of its next cycle:

- :meth:`PidController.set_reference` (``~/reference``, control_msgs/MultiDOFCommand),
- :meth:`PidController.set_measured_state` (``~/measured_state``, with ``use_external_measured_states``),
- :meth:`PidController.set_feedforward` (``~/set_feedforward_control``),
- :meth:`PidController.set_parameter` / :meth:`PidController.set_gains` (``gains.<dof>.<field>``),

and :attr:`PidController.latest_state` (``~/controller_state``, control_msgs/MultiDOFStateStamped: one
:class:`DofState` per dof) with :meth:`PidController.subscribe` for every cycle's state.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from jointctl.control.controller import Controller
from jointctl.control.params import Params, unknown_field_message
from jointctl.control.toolbox_pid import ToolboxGains, ToolboxPid, period_ns, shortest_angular_distance
from jointctl.errors import ConfigError, InvalidCommand
from jointctl.hardware.interface import HardwareInterface
from jointctl.model.robot_model import RobotModel
from jointctl.validate import real_number

NAN = math.nan
#: The state interfaces jointctl's hardware has, by name.
STATE_INTERFACES = ("position", "velocity", "effort")
#: ``gains.<dof>.<field>``: the numbers and the switches, with ros2_controllers' defaults (0, false).
GAIN_NUMBERS = ("p", "i", "d", "i_clamp_max", "i_clamp_min", "feedforward_gain")
GAIN_SWITCHES = ("antiwindup", "angle_wraparound")
#: Parameters ros2_controllers declares read-only (set at load, not while running).
READ_ONLY = ("dof_names", "reference_and_state_dof_names", "command_interface", "reference_and_state_interfaces",
             "use_external_measured_states")


@dataclass(frozen=True)
class DofGains:
    """``gains.<dof>``: PID gains in command units per error unit, the integral clamps [command units], the
    feed-forward gain on the reference's derivative, and the two switches."""

    p: float = 0.0
    i: float = 0.0
    d: float = 0.0
    i_clamp_max: float = 0.0
    i_clamp_min: float = 0.0
    feedforward_gain: float = 0.0
    antiwindup: bool = False
    angle_wraparound: bool = False

    def toolbox(self) -> ToolboxGains:
        return ToolboxGains(self.p, self.i, self.d, self.i_clamp_max, self.i_clamp_min, self.antiwindup)


@dataclass(frozen=True)
class DofState:
    """control_msgs/SingleDOFState: one dof's reference, measured ``feedback`` (and ``feedback_dot``), their
    ``error`` (and ``error_dot``), the ``time_step`` [s] of the cycle and the ``output`` (the command written;
    NaN until the first). With one reference interface ``feedback_dot`` and ``error_dot`` stay 0, as
    ros2_controllers leaves them."""

    name: str
    reference: float
    feedback: float
    feedback_dot: float
    error: float
    error_dot: float
    time_step: float
    output: float


@dataclass(frozen=True)
class PidControllerState:
    """control_msgs/MultiDOFStateStamped at loop time ``time_s``: one :class:`DofState` per dof, in order."""

    time_s: float
    dof_states: tuple[DofState, ...]


def string_list(params: Params, key: str, default=None, *, required: bool = False) -> tuple[str, ...]:
    """A list of unique non-empty strings at ``key`` (``default`` when absent, ConfigError when ``required``)."""
    value = params.raw(key) if required else params.raw(key, default if default is not None else [])
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise params.error("must be a list of names", key, value)
    if required and not value:
        raise params.error("must not be empty", key, value)
    for k, name in enumerate(value):
        if name in value[:k]:
            raise params.error("names must be unique", key, name)
    return tuple(value)


class PidController(Controller):
    """ros2_controllers' ``pid_controller/PidController`` (see the module docstring)."""

    def __init__(self, name: str, params: Params) -> None:
        super().__init__(name, params)
        self.dof_names = string_list(params, "dof_names", required=True)
        self.state_dof_names = string_list(params, "reference_and_state_dof_names") or self.dof_names
        if len(self.state_dof_names) != len(self.dof_names):
            raise params.error(f"must name as many dofs as dof_names ({len(self.dof_names)})",
                               "reference_and_state_dof_names", list(self.state_dof_names))
        self.command_interface = params.string("command_interface")
        self.interfaces = string_list(params, "reference_and_state_interfaces", required=True)
        if len(self.interfaces) > 2:
            raise params.error("must name one interface, or two (the second the first's derivative)",
                               "reference_and_state_interfaces", list(self.interfaces))
        self.use_external_measured_states = params.boolean("use_external_measured_states", False)
        gains = params.child("gains") if params.has("gains") else Params({}, source=params.source,
                                                                           field=params.path("gains"))
        self.gains: tuple[DofGains, ...] = tuple(
            self._read_gains(gains.child(dof)) if gains.has(dof) else DofGains() for dof in self.dof_names)
        gains.reject_unknown()
        params.reject_unknown({"type"})
        self.joints = self.dof_names
        self.latest_state: PidControllerState | None = None
        self._subscribers: list[Callable[[PidControllerState], None]] = []
        self._two = len(self.interfaces) == 2
        n = len(self.dof_names)
        self.reference = [NAN] * n
        self.reference_dot = [NAN] * n
        self.feedforward = False
        self._pending_reference: tuple | None = None
        self._external: tuple[tuple[float, ...], tuple[float, ...]] = ((NAN,) * n, (NAN,) * n)

    @staticmethod
    def _read_gains(p: Params) -> DofGains:
        numbers = {k: p.number(k, 0.0) for k in GAIN_NUMBERS}
        switches = {k: p.boolean(k, False) for k in GAIN_SWITCHES}
        p.reject_unknown()
        if numbers["i_clamp_min"] > numbers["i_clamp_max"]:
            raise p.error("is above i_clamp_max (ros2_controllers would load the PID with every gain 0)",
                          "i_clamp_min", numbers["i_clamp_min"])
        return DofGains(**numbers, **switches)

    # -- controller contract -------------------------------------------------------------------
    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        return tuple((dof, self.command_interface) for dof in self.dof_names)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        field = self.field
        self.hardware = hardware
        self.command_index = [hardware.joint_index(dof, source=self.source, field=f"{field}.dof_names[{k}]")
                              for k, dof in enumerate(self.dof_names)]
        for dof in self.dof_names:
            offered = hardware.command_interfaces(dof)
            if self.command_interface not in offered:
                raise ConfigError(f"joint {dof!r} has no {self.command_interface} command interface on this hardware "
                                  f"(it has: {', '.join(sorted(offered)) or 'none'})", source=self.source,
                                  field=f"{field}.command_interface", value=self.command_interface)
        self.state_index = [hardware.joint_index(dof, source=self.source,
                                                 field=f"{field}.reference_and_state_dof_names[{k}]")
                            for k, dof in enumerate(self.state_dof_names)]
        lists = {"position": hardware.position, "velocity": hardware.velocity, "effort": hardware.effort}
        for k, interface in enumerate(self.interfaces):
            if interface not in lists:
                raise ConfigError(f"jointctl's hardware has the state interfaces {', '.join(STATE_INTERFACES)}",
                                  source=self.source, field=f"{field}.reference_and_state_interfaces[{k}]",
                                  value=interface)
        self._state = lists[self.interfaces[0]]
        self._state_dot = lists[self.interfaces[1]] if self._two else None
        self.command = hardware.command_buffer(self.command_interface)
        # Configured once (ros2_controllers' on_configure): the PIDs keep their state across restarts.
        self.pids = [ToolboxPid(g.toolbox()) for g in self.gains]
        self._written = [False] * len(self.dof_names)
        #: The trace's ``<joint>.reference``: the manager's per-joint references in use (a list of its own when
        #: built outside a manager).
        self._in_use = self.context.references if self.context is not None else [NAN] * len(hardware.joint_names)

    def start(self, time_s: float) -> None:
        """``on_activate``: the reference (and an external state) back to NaN; the PIDs are not reset."""
        n = len(self.dof_names)
        self.reference[:] = [NAN] * n
        self.reference_dot[:] = [NAN] * n
        self._pending_reference = None
        self._external = ((NAN,) * n, (NAN,) * n)
        self._written = [False] * n

    def subscribe(self, callback: Callable[[PidControllerState], None]) -> None:
        """``callback(state)`` every cycle, in the loop thread, after the commands are written: it must only queue."""
        self._subscribers.append(callback)

    # -- doors (any thread) --------------------------------------------------------------------
    def _ordered(self, what: str, values: Sequence[float], values_dot: Sequence[float] | None,
                 dof_names: Sequence[str] | None, *, allow_nan: bool) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """``values`` (and ``values_dot``) as numbers in this controller's dof order; InvalidCommand naming the
        field when a name is unknown, a size is wrong or a value is not a number (or infinite)."""
        names = self.state_dof_names
        n = len(names)
        values = list(values)
        dots = [] if values_dot is None else list(values_dot)
        if len(values) != n:
            raise InvalidCommand(f"needs {n} values, for {', '.join(names)}", source=self.name,
                                 field=f"{what}.values", value=values)
        if dots and len(dots) != n:
            raise InvalidCommand(f"needs {n} values (or none), for {', '.join(names)}", source=self.name,
                                 field=f"{what}.values_dot", value=dots)
        if dots and not self._two:
            raise InvalidCommand("values_dot needs two reference_and_state_interfaces", source=self.name,
                                 field=f"{what}.values_dot", value=dots)
        checked = []
        for key, row in (("values", values), ("values_dot", dots)):
            out = []
            for k, x in enumerate(row):
                number = real_number(x)
                if number is None or math.isinf(number) or (math.isnan(number) and not allow_nan):
                    raise InvalidCommand("must be a finite number" + (" (or NaN: unchanged)" if allow_nan else ""),
                                         source=self.name, field=f"{what}.{key}[{k}]", value=x)
                out.append(number)
            checked.append(out or [NAN] * n)
        values, dots = checked
        if dof_names:
            given = list(dof_names)
            if sorted(given) != sorted(names):
                raise InvalidCommand(f"must name the dofs {', '.join(names)}", source=self.name,
                                     field=f"{what}.dof_names", value=given)
            order = [given.index(name) for name in names]
            values, dots = [values[k] for k in order], [dots[k] for k in order]
        return tuple(values), tuple(dots)

    def set_reference(self, values: Sequence[float], values_dot: Sequence[float] | None = None,
                      dof_names: Sequence[str] | None = None) -> None:
        """The ``~/reference`` door (control_msgs/MultiDOFCommand): one value per dof [m or rad for a position
        interface, per second for its derivative], in ``dof_names`` order when given (else the controller's
        ``reference_and_state_dof_names`` order); a single number is the reference of every dof (a scenario's
        command source). A NaN leaves that dof's reference as it is, as ros2_controllers does; ``values_dot``
        (two interfaces only) is the reference's derivative, used for the derivative error and the
        feed-forward. The last call before a cycle is the one it takes."""
        if real_number(values) is not None:
            values = [values] * len(self.state_dof_names)
        self._pending_reference = self._ordered("reference", values, values_dot, dof_names, allow_nan=True)

    def set_measured_state(self, values: Sequence[float], values_dot: Sequence[float] | None = None,
                           dof_names: Sequence[str] | None = None) -> None:
        """The ``~/measured_state`` door (with ``use_external_measured_states``): the state the PID compares the
        reference with, instead of the hardware's; kept until the next call."""
        if not self.use_external_measured_states:
            raise InvalidCommand("the controller reads its state from the hardware (use_external_measured_states "
                                 "is false)", source=self.name, field="measured_state")
        self._external = self._ordered("measured_state", values, values_dot, dof_names, allow_nan=True)

    def set_feedforward(self, enabled: bool) -> None:
        """The ``~/set_feedforward_control`` door (std_srvs/SetBool): add ``feedforward_gain · reference_dot``."""
        if not isinstance(enabled, bool):
            raise InvalidCommand("must be true or false", source=self.name, field="feedforward", value=enabled)
        if enabled and not self._two:
            raise InvalidCommand("feed-forward needs the reference's derivative: two reference_and_state_interfaces",
                                 source=self.name, field="feedforward", value=enabled)
        self.feedforward = enabled

    def set_gains(self, dof: str, **fields) -> DofGains:
        """Change some of ``gains.<dof>`` (``p=...``, ``antiwindup=...``) while running; applied at the next
        cycle, the PID's integral and last error kept. Returns the gains now in force."""
        if dof not in self.dof_names:
            raise InvalidCommand(f"no such dof (dofs: {', '.join(self.dof_names)})", source=self.name,
                                 field="gains", value=dof)
        k = self.dof_names.index(dof)
        changes = {}
        for key, value in fields.items():
            where = f"gains.{dof}.{key}"
            if key in GAIN_NUMBERS:
                number = real_number(value)
                if number is None or not math.isfinite(number):
                    raise InvalidCommand("must be a finite number", source=self.name, field=where, value=value)
                changes[key] = number
            elif key in GAIN_SWITCHES:
                if not isinstance(value, bool):
                    raise InvalidCommand("must be true or false", source=self.name, field=where, value=value)
                changes[key] = value
            else:
                raise InvalidCommand(unknown_field_message(key, GAIN_NUMBERS + GAIN_SWITCHES), source=self.name,
                                     field=where, value=value)
        gains = dataclasses.replace(self.gains[k], **changes)
        if gains.i_clamp_min > gains.i_clamp_max:
            raise InvalidCommand("i_clamp_min would be above i_clamp_max", source=self.name,
                                 field=f"gains.{dof}.i_clamp_min", value=gains.i_clamp_min)
        self.gains = self.gains[:k] + (gains,) + self.gains[k + 1:]
        if hasattr(self, "pids"):
            self.pids[k].set_gains(gains.toolbox())
        return gains

    def set_parameter(self, name: str, value) -> None:
        """Set a parameter by its ROS 2 name while running (what ``ros2 param set /pid_controller NAME VALUE``
        asks): ``gains.<dof>.<field>``; the read-only ones are refused."""
        if name in READ_ONLY:
            raise InvalidCommand("is read-only", source=self.name, field=name, value=value)
        parts = name.split(".")
        if len(parts) != 3 or parts[0] != "gains":
            raise InvalidCommand("jointctl changes gains.<dof>.<field> while running", source=self.name, field=name,
                                 value=value)
        self.set_gains(parts[1], **{parts[2]: value})

    # -- the cycle ------------------------------------------------------------------------------
    def update(self, time_s: float, period_s: float) -> None:
        pending, self._pending_reference = self._pending_reference, None
        reference, reference_dot = self.reference, self.reference_dot
        if pending is not None:  # update_reference_from_subscribers: the numbers given, NaN keeps
            values, dots = pending
            for i, x in enumerate(values):
                if x == x:
                    reference[i] = x
                    if self._two and dots[i] == dots[i]:
                        reference_dot[i] = dots[i]
        if self.use_external_measured_states:
            state, state_dot = self._external
        else:
            state = [self._state[j] for j in self.state_index]
            state_dot = [self._state_dot[j] for j in self.state_index] if self._two else None
        dt_ns = period_ns(period_s)
        two = self._two
        in_use = self._in_use
        for i, pid in enumerate(self.pids):
            ref, meas = reference[i], state[i]
            if ref != ref or meas != meas:
                continue
            gains = self.gains[i]
            command = reference_dot[i] * gains.feedforward_gain if self.feedforward else 0.0
            error = shortest_angular_distance(meas, ref) if gains.angle_wraparound else ref - meas
            if two and reference_dot[i] == reference_dot[i] and state_dot[i] == state_dot[i]:
                command += pid.compute_with_rate(error, reference_dot[i] - state_dot[i], dt_ns)
            else:
                command += pid.compute(error, dt_ns)
            self.command[self.command_index[i]] = command
            self._written[i] = True
            in_use[self.command_index[i]] = ref
        self._publish(time_s, period_s, state, state_dot)

    def _publish(self, time_s: float, period_s: float, state, state_dot) -> None:
        dofs = []
        for i, name in enumerate(self.state_dof_names):
            ref, meas = self.reference[i], state[i]
            error = shortest_angular_distance(meas, ref) if self.gains[i].angle_wraparound else ref - meas
            feedback_dot = state_dot[i] if self._two else 0.0
            error_dot = self.reference_dot[i] - state_dot[i] if self._two else 0.0
            output = self.command[self.command_index[i]] if self._written[i] else NAN
            dofs.append(DofState(name, ref, meas, feedback_dot, error, error_dot, period_s, output))
        self.latest_state = snapshot = PidControllerState(time_s, tuple(dofs))
        for callback in self._subscribers:
            callback(snapshot)


__all__ = ["DofGains", "DofState", "PidController", "PidControllerState", "string_list"]

"""The compiled forms of :class:`~jointctl.control.joint_controllers.JointPositionController` and
:class:`~jointctl.control.joint_controllers.JointVelocityController`: their ``update`` and ``set_reference``
(fed by a command source) on arrays, statement for statement.

A controller is a row of parameters and a row of state (floats, indexed by the names below; flags are 1.0
or 0.0), row ``c`` of the compiled cycle's tables. :func:`pack_position` and :func:`pack_velocity` make them from the Python controller, and
:func:`unpack_position` and :func:`unpack_velocity` put the state back, so a run can go on in Python at any
cycle boundary. Covered: both derivative laws, position and velocity limits (clamps counted as in Python),
continuous joints, the integral with its clamp and antiwindup, the feed-forward (damping, and the model's gravity
and inertia read from the arrays of ``context_kernel``), chained mode (the upstream writes the reference interfaces
as the Python does), the velocity controller's command watchdog.
"""

from __future__ import annotations

import math

from jointctl.control.joint_controllers import JointPositionController, JointVelocityController
from jointctl.control.pid_kernel import GAINS, OUTPUT_LIMIT, pid_compute, pid_gains
from jointctl.jit import kernel

#: The parameters row: the hardware joint index, the position range [m or rad], flags (a continuous joint,
#: the derivative on the error's difference, the damping feed-forward), the joint damping [N·s/m or N·m·s/rad],
#: the velocity limit [m/s or rad/s], then the PID's gains from ``PID``; after them a velocity controller's
#: command timeout [s] (0: no watchdog), then flags: the gravity and inertia feed-forward, and whether the
#: reference comes from an upstream controller (chained).
JOINT, LOWER, UPPER, CONTINUOUS, ON_ERROR, FF_DAMPING, JOINT_DAMPING, VELOCITY_LIMIT, PID = range(9)
COMMAND_TIMEOUT, FF_GRAVITY, FF_INERTIA, CHAINED = range(PID + GAINS, PID + GAINS + 4)
PARAMETERS = PID + GAINS + 4
#: The state row: the PID's integral, the last error and whether there is one, the last rate, whether the
#: edge's reference carries a velocity, the clamped cycles and the reference furthest outside (and whether any);
#: the watchdog's: when the reference in hand was first seen [s], whether one came since the last update, and
#: whether the last update found it too old.
I_STATE, LAST_ERROR, LAST_VALID, LAST_RATE, EDGE_VELOCITY, CLAMPED, FURTHEST, HAS_FURTHEST = range(8)
COMMAND_TIME, FRESH, TIMED_OUT = range(8, 11)
STATE = 11

_TWO_PI = 2.0 * math.pi


def _parameters(c, continuous: bool, on_error: bool, ff_damping: bool, joint_damping: float,
                command_timeout_s: float = 0.0) -> list[float]:
    return [float(c.index), c.lower, c.upper, float(continuous), float(on_error), float(ff_damping), joint_damping,
            c.velocity_limit, *pid_gains(c.pid), command_timeout_s]


def _state(c, last_error: float, last_valid: bool, last_rate: float, edge_velocity: bool) -> list[float]:
    furthest = c.clamped_furthest
    return [c.pid.i_state, last_error, float(last_valid), last_rate, float(edge_velocity), float(c.clamped_cycles),
            0.0 if furthest is None else furthest, 0.0 if furthest is None else 1.0]


def _unpack_common(c, state) -> None:
    c.pid.i_state = float(state[I_STATE])
    c.clamped_cycles = int(state[CLAMPED])
    c.clamped_furthest = float(state[FURTHEST]) if state[HAS_FURTHEST] else None


def pack_position(c: JointPositionController) -> tuple[list[float], list[float]]:
    """The parameters and state rows of a position controller."""
    parameters = _parameters(c, c.continuous, c._on_error, c._damping, c.joint_damping)
    parameters += [float(c._gravity), float(c._inertia), float(c.upstream is not None)]
    return parameters, _state(c, c._last_error, c._last_valid, c._last_rate, c._edge_velocity)


def unpack_position(c: JointPositionController, state) -> None:
    """Put a position controller's state row back into the controller."""
    _unpack_common(c, state)
    c._last_error = float(state[LAST_ERROR])
    c._last_valid = bool(state[LAST_VALID])
    c._last_rate = float(state[LAST_RATE])
    c._edge_velocity = bool(state[EDGE_VELOCITY])


def pack_velocity(c: JointVelocityController) -> tuple[list[float], list[float]]:
    """The parameters and state rows of a velocity controller (not chained)."""
    timeout = c.command_timeout_s if c.command_timeout_s is not None and c.upstream is None else 0.0
    state = _state(c, c._last_error, c._last_valid, 0.0, False)
    state[COMMAND_TIME:] = [c._command_time, float(c._token is not c._seen), float(c.timed_out)]
    return _parameters(c, False, False, False, 0.0, timeout), state


def unpack_velocity(c: JointVelocityController, state) -> None:
    """Put a velocity controller's state row back into the controller (a reference not yet seen by an update
    stays unseen: its age counts from the next update's cycle, as in Python)."""
    _unpack_common(c, state)
    c._last_error = float(state[LAST_ERROR])
    c._last_valid = bool(state[LAST_VALID])
    c._command_time = float(state[COMMAND_TIME])
    c.timed_out = bool(state[TIMED_OUT])
    if not state[FRESH]:
        c._seen = c._token
    elif c._token is c._seen:
        c._token = object()


@kernel
def wrap_angle(angle):
    """``wrap_angle`` of joint_controllers: ``angle`` [rad] into (-π, π] [rad]."""
    wrapped = angle - _TWO_PI * math.ceil((angle - math.pi) / _TWO_PI)
    if wrapped <= -math.pi:
        wrapped += _TWO_PI
    elif wrapped > math.pi:
        wrapped -= _TWO_PI
    return wrapped


@kernel
def clamp_counted(state, c, value, low, high):
    """``value`` clamped to [low, high], counted in ``state[c]`` (``_EffortJointController._clamp``)."""
    state[c, CLAMPED] += 1.0
    bound = low if value < low else high
    if state[c, HAS_FURTHEST] == 0.0:
        state[c, FURTHEST] = value
        state[c, HAS_FURTHEST] = 1.0
    else:
        furthest = state[c, FURTHEST]
        if abs(value - bound) > abs(furthest - (low if furthest < low else high)):
            state[c, FURTHEST] = value
    return bound


@kernel
def feed_position(parameters, state, c, value, positions, velocities, accelerations):
    """``JointPositionController.set_reference(value)``: a plain position command."""
    i = int(parameters[c, JOINT])
    velocities[i] = 0.0
    accelerations[i] = 0.0
    state[c, EDGE_VELOCITY] = 0.0
    positions[i] = value


@kernel
def feed_velocity(parameters, state, c, value, velocities):
    """``JointVelocityController.set_reference(value)``: a new reference (the watchdog sees it as new)."""
    velocities[int(parameters[c, JOINT])] = value
    state[c, FRESH] = 1.0


@kernel
def position_update(parameters, state, c, positions, velocities, references, position, velocity, effort_command,
                    period_s, gravity, inertia):
    """``JointPositionController.update``: the reference interfaces and measured state in (and the model
    feed-forward's ``gravity`` and ``inertia`` efforts per hardware joint), the effort out."""
    i = int(parameters[c, JOINT])
    reference, reference_velocity = positions[i], velocities[i]
    lower, upper = parameters[c, LOWER], parameters[c, UPPER]
    if reference < lower or reference > upper:
        reference = clamp_counted(state, c, reference, lower, upper)
    references[i] = reference
    error = reference - position[i]
    if parameters[c, CONTINUOUS] != 0.0 and not -math.pi < error <= math.pi:
        error = wrap_angle(error)
    if parameters[c, ON_ERROR] != 0.0 and parameters[c, CHAINED] == 0.0 and state[c, EDGE_VELOCITY] == 0.0:
        if state[c, LAST_VALID] != 0.0:
            rate = (error - state[c, LAST_ERROR]) / period_s
        else:
            rate = state[c, LAST_RATE]
            state[c, LAST_VALID] = 1.0
        state[c, LAST_ERROR] = error
    else:
        rate = reference_velocity - velocity[i]
    state[c, LAST_RATE] = rate
    effort, state[c, I_STATE] = pid_compute(parameters, c, PID, state[c, I_STATE], error, rate, period_s)
    ff_gravity, ff_damping = parameters[c, FF_GRAVITY], parameters[c, FF_DAMPING]
    ff_inertia = parameters[c, FF_INERTIA]
    if ff_gravity != 0.0 or ff_damping != 0.0 or ff_inertia != 0.0:
        if ff_gravity != 0.0:
            effort += gravity[i]
        if ff_damping != 0.0:
            effort += parameters[c, JOINT_DAMPING] * reference_velocity
        if ff_inertia != 0.0:
            effort += inertia[i]
        limit = parameters[c, PID + OUTPUT_LIMIT]  # the joint's effort limit
        effort = limit if effort > limit else -limit if effort < -limit else effort
    effort_command[i] = effort


@kernel
def velocity_update(parameters, state, c, velocities, references, velocity, effort_command, t, period_s):
    """``JointVelocityController.update`` at loop time ``t`` [s]: the reference interface and measured state in,
    the effort out."""
    i = int(parameters[c, JOINT])
    reference = velocities[i]
    timeout = parameters[c, COMMAND_TIMEOUT]
    if timeout != 0.0:  # the watchdog: a reference older than the timeout is replaced by zero velocity
        if state[c, FRESH] != 0.0:
            state[c, FRESH] = 0.0
            state[c, COMMAND_TIME] = t
        timed_out = t - state[c, COMMAND_TIME] > timeout
        state[c, TIMED_OUT] = 1.0 if timed_out else 0.0
        if timed_out:
            reference = 0.0
    limit = parameters[c, VELOCITY_LIMIT]
    if reference < -limit or reference > limit:
        reference = clamp_counted(state, c, reference, -limit, limit)
    references[i] = reference
    error = reference - velocity[i]
    rate = (error - state[c, LAST_ERROR]) / period_s if state[c, LAST_VALID] != 0.0 else 0.0
    state[c, LAST_VALID] = 1.0
    state[c, LAST_ERROR] = error
    effort, state[c, I_STATE] = pid_compute(parameters, c, PID, state[c, I_STATE], error, rate, period_s)
    effort_command[i] = effort

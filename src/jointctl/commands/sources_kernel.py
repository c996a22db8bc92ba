"""The compiled forms of the constant, step and sine command sources: :func:`source_sample` is their
``sample(t)``, operation for operation (an expression source has none: a run with one stays in Python).

A source is a row of parameters (its kind, then its numbers) and a row of state (the sine's held message), row
``f`` of the compiled cycle's tables; :func:`pack_source` makes them and :func:`unpack_source` puts the state back.
"""

from __future__ import annotations

import math

from jointctl.commands.sources import ConstantSource, SineSource, StepSource
from jointctl.jit import kernel

CONSTANT, STEP, SINE = range(3)
#: The parameters row: the kind, then a constant's value; a step's from, to, at [s] and ramp [s]; a sine's
#: amplitude, frequency [Hz], offset, rate [Hz] and whether it gives the derivative (1.0 or 0.0).
KIND = 0
VALUE = 1
INITIAL, FINAL, AT, RAMP = 1, 2, 3, 4
AMPLITUDE, FREQUENCY, OFFSET, RATE, DERIVATIVE = 1, 2, 3, 4, 5
PARAMETERS = 6
#: The state row: the held message's number (a whole number), its value, and whether one is held.
HELD_K, HELD_VALUE, HOLDS = range(3)
STATE = 3

_EPSILON = 1e-9  # sources._EPSILON


def pack_source(source) -> tuple[list[float], list[float]]:
    """The parameters and state rows of a constant, step or sine source."""
    params = [0.0] * PARAMETERS
    state = [0.0] * STATE
    if type(source) is ConstantSource:
        params[KIND], params[VALUE] = CONSTANT, source.value
    elif type(source) is StepSource:
        params[KIND] = STEP
        params[INITIAL], params[FINAL], params[AT], params[RAMP] = (source.initial, source.final, source.at_s,
                                                                    source.ramp_s)
    elif type(source) is SineSource:
        params[KIND] = SINE
        params[AMPLITUDE], params[FREQUENCY], params[OFFSET] = source.amplitude, source.frequency_hz, source.offset
        params[RATE], params[DERIVATIVE] = source.rate_hz, float(source.derivative)
        hold = source._hold
        if hold.k is not None:
            state[HELD_K], state[HELD_VALUE], state[HOLDS] = float(hold.k), hold.value, 1.0
    else:
        raise TypeError(f"{type(source).__name__} has no compiled form")
    return params, state


def unpack_source(source, state) -> None:
    """Put a source's state row back (a sine's held message)."""
    if type(source) is SineSource and state[HOLDS]:
        source._hold.k = int(state[HELD_K])
        source._hold.value = float(state[HELD_VALUE])


@kernel
def source_sample(parameters, state, f, t):
    """Source ``f``'s value at loop time ``t`` [s], in the unit of the command it feeds."""
    kind = parameters[f, KIND]
    if kind == CONSTANT:
        return parameters[f, VALUE]
    if kind == STEP:
        at = parameters[f, AT]
        if t < at:
            return parameters[f, INITIAL]
        if t >= at + parameters[f, RAMP]:
            return parameters[f, FINAL]
        initial = parameters[f, INITIAL]
        return initial + (parameters[f, FINAL] - initial) * (t - at) / parameters[f, RAMP]
    rate = parameters[f, RATE]
    k = math.floor(t * rate + _EPSILON)
    if state[f, HOLDS] == 0.0 or k != state[f, HELD_K]:
        omega = 2.0 * math.pi * parameters[f, FREQUENCY]
        t_k = k / rate
        if parameters[f, DERIVATIVE] != 0.0:
            state[f, HELD_VALUE] = omega * parameters[f, AMPLITUDE] * math.cos(omega * t_k)
        else:
            state[f, HELD_VALUE] = parameters[f, OFFSET] + parameters[f, AMPLITUDE] * math.sin(omega * t_k)
        state[f, HELD_K] = k
        state[f, HOLDS] = 1.0
    return state[f, HELD_VALUE]

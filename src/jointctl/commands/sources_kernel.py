"""The compiled forms of the command sources: :func:`source_sample` is the constant's, step's, sine's and
chirp's ``sample(t)``, operation for operation.

An expression is evaluated in Python, by its own ``sample``, a message at a time (its language is Python's
arithmetic on closures): before a stretch of cycles, :func:`fill_table` samples it at each of the stretch's cycles
where a new message is due and writes the values held over the stretch into a table row, which the kernel reads
(kind ``TABLE``). The source's hold, its rejected messages and its first error are then what the Python loop leaves.

A source is a row of parameters (its kind, then its numbers) and a row of state (the sine's held message), row
``f`` of the compiled cycle's tables; :func:`pack_source` makes them and :func:`unpack_source` puts the state back.
"""

from __future__ import annotations

import math

import numpy as np

from jointctl.commands.sources import ChirpSource, ConstantSource, ExpressionSource, SineSource, StepSource
from jointctl.jit import kernel

CONSTANT, STEP, SINE, CHIRP, TABLE = range(5)
#: The parameters row: the kind, then a constant's value; a step's from, to, at [s] and ramp [s]; a sine's
#: amplitude, frequency [Hz], offset, rate [Hz] and whether it gives the derivative (1.0 or 0.0); a chirp's
#: amplitude, start and end frequencies [Hz], duration [s], offset and start [s]. A table has none.
KIND = 0
VALUE = 1
INITIAL, FINAL, AT, RAMP = 1, 2, 3, 4
AMPLITUDE, FREQUENCY, OFFSET, RATE, DERIVATIVE = 1, 2, 3, 4, 5
F_START, F_END, DURATION, CHIRP_OFFSET, CHIRP_AT = 2, 3, 4, 5, 6
PARAMETERS = 7
#: The state row: the held message's number (a whole number), its value, and whether one is held.
HELD_K, HELD_VALUE, HOLDS = range(3)
STATE = 3

_EPSILON = 1e-9  # sources._EPSILON


def pack_source(source) -> tuple[list[float], list[float]]:
    """The parameters and state rows of a constant, step, sine, chirp or expression source."""
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
    elif type(source) is ChirpSource:
        params[KIND] = CHIRP
        params[AMPLITUDE], params[F_START], params[F_END] = source.amplitude, source.f_start_hz, source.f_end_hz
        params[DURATION], params[CHIRP_OFFSET], params[CHIRP_AT] = source.duration_s, source.offset, source.at_s
    elif type(source) is ExpressionSource:
        params[KIND] = TABLE
    else:
        raise TypeError(f"{type(source).__name__} has no compiled form")
    return params, state


def unpack_source(source, state) -> None:
    """Put a source's state row back (a sine's held message)."""
    if type(source) is SineSource and state[HOLDS]:
        source._hold.k = int(state[HELD_K])
        source._hold.value = float(state[HELD_VALUE])


def fill_table(source: ExpressionSource, row: np.ndarray, k0: int, n: int, period_s: float) -> None:
    """Sample ``source`` in Python at the cycles ``k0`` to ``k0 + n - 1`` (loop times ``k·period_s`` [s]) where
    a new message is due, as the loop would, and write the value it holds at each cycle into ``row[:n]``.

    A message that fails with no value to hold raises its :class:`~jointctl.errors.ExpressionError` as the
    loop's ``sample`` does; that can only be the first sampled (after it, the source holds a value), so the
    stretch fails at its first cycle, where the Python loop fails."""
    times = (k0 + np.arange(n, dtype=np.int64)) * period_s
    messages = np.floor(times * source.rate_hz + _EPSILON)
    starts = [0, *(np.flatnonzero(np.diff(messages)) + 1).tolist(), n]
    for start, stop in zip(starts[:-1], starts[1:]):
        row[start:stop] = source.sample(float(times[start]))


@kernel
def source_sample(parameters, state, tables, f, t, j):
    """Source ``f``'s value at loop time ``t`` [s] (cycle ``j`` of the stretch), in the unit of the command it
    feeds."""
    kind = parameters[f, KIND]
    if kind == TABLE:
        return tables[f, j]
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
    if kind == CHIRP:
        tau = t - parameters[f, CHIRP_AT]
        duration = parameters[f, DURATION]
        if tau < 0.0 or tau > duration:
            return parameters[f, CHIRP_OFFSET]
        f_start = parameters[f, F_START]
        phase = 2.0 * math.pi * (f_start * tau + 0.5 * (parameters[f, F_END] - f_start) * tau * tau / duration)
        return parameters[f, CHIRP_OFFSET] + parameters[f, AMPLITUDE] * math.sin(phase)
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


@kernel
def source_values(parameters, state, times, out):
    """Source 0's values at ``times`` [s], in order, into ``out`` (its ``sample`` at each)."""
    tables = parameters[:1, :1]  # (a source with a table samples in Python)
    for j in range(times.shape[0]):
        out[j] = source_sample(parameters, state, tables, 0, times[j], 0)


def sample_times(source, times) -> np.ndarray:
    """``source.sample(t)`` at each of ``times`` [s], in order (compiled for a constant, step, sine or chirp; the
    source's state afterwards as ``sample`` leaves it)."""
    times = np.ascontiguousarray(times, dtype=float)
    if type(source) not in (ConstantSource, StepSource, SineSource, ChirpSource):
        return np.array([float(source.sample(float(t))) for t in times])
    parameters, state = (np.array([row]) for row in pack_source(source))
    out = np.empty(times.size)
    source_values(parameters, state, times, out)
    unpack_source(source, state[0])
    return out

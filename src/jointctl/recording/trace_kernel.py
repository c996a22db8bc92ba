"""The compiled form of :class:`~jointctl.recording.trace.TraceRecorder`'s row: :func:`trace_due` is its
decimation (one cycle in ``every``), :func:`trace_row` the row it packs (time, then per joint the reference,
position, velocity and effort, then each sensor's wrench). The rows go to the recorder's spool with
:meth:`~jointctl.recording.trace.TraceRecorder.add_block`."""

from __future__ import annotations

from jointctl.jit import kernel
from jointctl.recording.trace import TraceRecorder

#: The state row: cycles still to skip, and ``every``.
COUNTDOWN, EVERY = range(2)


def pack_trace(recorder: TraceRecorder) -> list[float]:
    return [float(recorder._countdown), float(recorder.every)]


def unpack_trace(recorder: TraceRecorder, state) -> None:
    recorder._countdown = int(state[COUNTDOWN])


@kernel
def trace_due(state):
    """Whether this cycle is kept (``TraceRecorder.__call__``'s countdown)."""
    if state[COUNTDOWN] != 0.0:
        state[COUNTDOWN] -= 1.0
        return False
    state[COUNTDOWN] = state[EVERY] - 1.0
    return True


@kernel
def trace_row(rows, r, time_s, references, position, velocity, effort, wrench):
    """Fill row ``r`` of ``rows`` (the trace's columns) at loop time ``time_s`` [s]; ``wrench`` is sensors x 6."""
    n = position.shape[0]
    rows[r, 0] = time_s
    for j in range(n):
        rows[r, 1 + j] = references[j]
        rows[r, 1 + n + j] = position[j]
        rows[r, 1 + 2 * n + j] = velocity[j]
        rows[r, 1 + 3 * n + j] = effort[j]
    column = 1 + 4 * n
    for s in range(wrench.shape[0]):
        for a in range(6):
            rows[r, column] = wrench[s, a]
            column += 1

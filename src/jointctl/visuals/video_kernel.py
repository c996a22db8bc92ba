"""The compiled form of :class:`~jointctl.visuals.video.FrameCapture`: :func:`frame_due` is its timing (a
frame every ``1 / fps`` of loop time); the compiled cycle copies the world's ``qpos`` on the frames it says, and
:func:`unpack_frames` hands them to the capture."""

from __future__ import annotations

from jointctl.jit import kernel
from jointctl.visuals.video import FrameCapture

#: The state row: the next frame's loop time [s], and the frame period [s].
NEXT_S, PERIOD = range(2)


def pack_frames(capture: FrameCapture) -> list[float]:
    return [capture._next_s, capture.period_s]


def unpack_frames(capture: FrameCapture, state, qpos, times, model) -> None:
    """Keep the frames a compiled stretch took (``qpos``: frames x nq, ``times`` [s]) of ``model``."""
    capture._next_s = float(state[NEXT_S])
    for row, time_s in zip(qpos, times.tolist()):
        capture.frames.append((model, row.copy(), time_s))


@kernel
def frame_due(state, time_s):
    """Whether a frame is kept at loop time ``time_s`` [s] (``FrameCapture.__call__``)."""
    if time_s + 1e-9 >= state[NEXT_S]:
        state[NEXT_S] += state[PERIOD]
        return True
    return False

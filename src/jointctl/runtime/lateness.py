"""How late the paced loop's cycles end against their ideal wall-clock times: its jitter, reported once a second.

A cycle cannot start before its due time (the pacer waits for it), so each lateness is >= 0: ``perf_counter()`` at
the end of the cycle minus ``origin_s + t / speed``. Every second of loop time the p50, p99 and max [ms] go to the
edge's ``report`` (ROS 1's and ROS 2's ``loop_lateness`` topics).
"""

from __future__ import annotations

import time
from collections.abc import Callable


def watch_lateness(loop, report: Callable[[float, float, float], None], speed: Callable[[], float]) -> None:
    """Add an observer to ``loop`` (paced by a WallClockPacer) that hands ``report(p50_ms, p99_ms, max_ms)`` each
    second's lateness; ``speed()`` is the pacing speed (loop seconds per wall second)."""
    late: list[float] = []
    per_report = max(1, round(1.0 / loop.period_s))

    def measure(t: float) -> None:
        late.append(time.perf_counter() - loop.clock.origin_s - t / speed())
        if len(late) >= per_report:
            ordered = sorted(late)
            late.clear()
            report(1e3 * ordered[len(ordered) // 2], 1e3 * ordered[int(0.99 * len(ordered))], 1e3 * ordered[-1])

    loop.add_observer(measure)


__all__ = ["watch_lateness"]

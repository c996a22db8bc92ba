"""Clocks for the loop: simulated time (as fast as possible) or wall-clock pacing.

Loop time is always ``cycle * period``: the clock only decides whether the
loop waits for the wall clock before starting the next cycle. Simulated time
makes runs deterministic and as fast as the machine allows.
"""

from __future__ import annotations

import time

SPIN_S = 3e-4  # the final stretch of a wait spent spinning, not sleeping [s]


class SimulatedClock:
    """Never waits: simulated time runs as fast as the computer can step it."""

    realtime = False
    overruns = 0

    def start(self) -> None:
        pass

    def wait_for(self, loop_time_s: float) -> None:
        pass


class WallClockPacer:
    """Waits so loop time advances at ``speed`` times the wall clock (1.0: real time).

    A cycle that finishes late is an *overrun*: the pacer does not wait and
    does not try to catch up faster than the loop can run; ``overruns`` counts them.
    """

    realtime = True

    def __init__(self, speed: float = 1.0) -> None:
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed}")
        self.speed = speed
        self.overruns = 0
        self._origin = 0.0

    def start(self) -> None:
        self._origin = time.perf_counter()

    @property
    def origin_s(self) -> float:
        """``time.perf_counter()`` at loop time zero: loop time t is due at origin_s + t / speed."""
        return self._origin

    def wait_for(self, loop_time_s: float) -> None:
        deadline = self._origin + loop_time_s / self.speed
        remaining = deadline - time.perf_counter()
        if remaining < 0:
            self.overruns += 1
            return
        # Sleep through most of the wait (it releases the GIL: ROS and web threads need it to
        # run at all) and spin only the last SPIN_S, where sleep would overshoot.
        if remaining > SPIN_S:
            time.sleep(remaining - SPIN_S)
        while time.perf_counter() < deadline:
            pass

class StampClock:
    """Loop time [s] -> the time the edges stamp messages with [s]: the wall clock at loop time zero plus loop time
    (at speed 1), or loop time itself on simulated time (``/clock``). ROS 1's and ROS 2's edges turn
    :meth:`seconds` into their own time types."""

    def __init__(self, loop, sim_time: bool) -> None:
        self.loop = loop
        self.sim_time = sim_time
        self.origin_s = 0.0

    def start(self) -> None:
        """Fix the origin: now on the wall clock is the loop's present time."""
        self.origin_s = 0.0 if self.sim_time else time.time() - self.loop.time_s

    def ros_time_at_loop_zero(self) -> float:
        return self.origin_s

    def seconds(self, loop_s: float) -> float:
        return self.origin_s + loop_s

    def loop_now(self) -> float:
        return self.loop.time_s


"""The loop thread of a tuning session: runs the tuner's loop paced to the wall clock.

The loop runs until the tuner asks it to stop between cycles (pause, reset, shutdown); the
runner then resets, or applies changes while paused, and runs the loop again. Loop time goes on
where it stopped: a pause freezes the simulation, it does not skip time.
"""

from __future__ import annotations

import sys
import threading
import time

from jointctl.runtime.clock import WallClockPacer
from jointctl.tuning.tuner import Tuner

SWITCH_INTERVAL_S = 2e-4  # GIL hand-over interval: the loop thread gets the GIL back quickly [s]
PAUSED_POLL_S = 0.01  # how often a paused runner applies queued changes [s]


class CountingPacer(WallClockPacer):
    """The wall-clock pacer, counting the cycles it paced (``cycles``) beside the late ones (``overruns``)."""

    def __init__(self, speed: float = 1.0) -> None:
        super().__init__(speed)
        self.cycles = 0

    def wait_for(self, loop_time_s: float) -> None:
        self.cycles += 1
        super().wait_for(loop_time_s)


class LiveRunner:
    """Runs ``tuner``'s loop on a thread of its own at ``speed`` times the wall clock."""

    def __init__(self, tuner: Tuner, speed: float = 1.0) -> None:
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed}")
        self.tuner = tuner
        self.speed = speed
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._main, name="jointctl-tune-loop", daemon=True)
        self._previous_switch = sys.getswitchinterval()

    def start(self) -> None:
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        self.tuner.shutdown = True
        self.tuner.loop.request_stop()
        if self._thread.is_alive():
            self._thread.join(timeout_s)
        sys.setswitchinterval(self._previous_switch)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    def _main(self) -> None:
        tuner, loop = self.tuner, self.tuner.loop
        try:
            while not tuner.shutdown:
                if tuner.reset_wanted:
                    tuner.reset()
                if tuner.paused:
                    tuner.apply_pending()
                    time.sleep(PAUSED_POLL_S)
                    continue
                clock = CountingPacer(self.speed)
                loop.clock = clock
                loop.run()  # until the tuner's door asks it to stop
                tuner.close_timing(clock)
        except BaseException as exc:  # noqa: BLE001  (reported to the page and the command line)
            self.error = exc
            tuner.shutdown = True

"""Clock behaviour beyond the loop tests: overrun counting."""

from __future__ import annotations

import time

from jointctl.runtime.clock import WallClockPacer


def test_late_cycles_count_as_overruns_and_do_not_wait():
    pacer = WallClockPacer()
    pacer.start()
    time.sleep(0.02)
    start = time.perf_counter()
    pacer.wait_for(0.001)  # already about 19 ms late
    assert time.perf_counter() - start < 10.0  # a hang guard: it would wait ~forever if it tried to catch up
    assert pacer.overruns == 1

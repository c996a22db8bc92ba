"""A stop asked before the controller's loop began (a SIGTERM right at start-up) is honoured, not lost."""

from __future__ import annotations

import threading

from jointctl.industrial_controller.controller import SimulatedController
from jointctl.scenario.spec import scenario_for_robot


def test_a_stop_asked_before_run_returns_at_once() -> None:
    controller = SimulatedController(scenario_for_robot("one_dof", "servo"), motion_port=0, state_port=0)
    try:
        controller.stop()  # before run(): the loop resets its own stop flag when it begins
        done = threading.Event()
        runner = threading.Thread(target=lambda: (controller.run(), done.set()), daemon=True)
        runner.start()
        runner.join(timeout=60)
        assert done.is_set()
        assert controller.session.loop.time_s < 0.01  # it did not go on serving (at most a cycle)
    finally:
        controller.close()

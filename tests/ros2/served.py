"""``jointctl serve --ros2`` started for a test, and the questions a test asks of it through ROS 2's own tools."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests.processes import stop_process
from tests.ros2.environment import ros2
from tests.waiting import wait_until

PROBE = Path(__file__).with_name("probe.py")


class ServedRobot:
    """``jointctl COMMAND ROBOT --ros2 ARGS...`` (``serve``, or ``tune``) in ``env`` (a child process; its output in
    ``log``)."""

    def __init__(self, env: dict, log: Path, robot: str, *args: str, command: str = "serve") -> None:
        self.env, self.log = env, log
        self._out = open(log, "w")
        self.process = subprocess.Popen([sys.executable, "-m", "jointctl.cli", command, robot, "--ros2", *args],
                                        env=env, stdout=self._out, stderr=subprocess.STDOUT)

    def wait_up(self, controllers: list[str]) -> str:
        """Wait until ``ros2 control list_controllers`` lists ``controllers`` active; its output."""
        def listed():
            if self.process.poll() is not None:
                raise AssertionError(f"jointctl serve --ros2 ended: {self.log.read_text()}")
            out = ros2(self.env, "control", "list_controllers", timeout_s=60).stdout
            lines = [line for line in out.splitlines() if "active" in line]
            return out if all(any(c in line for line in lines) for c in controllers) else None
        return wait_until(listed, f"controllers {controllers} listed active", timeout_s=90, every_s=0.5)

    def rest(self, joint: str, timeout_s: float = 60.0, what: str = "rest", *options: str) -> dict:
        """Where ``joint`` comes to rest (``what="steady"``: to a steady speed), from /joint_states
        (tests/ros2/probe.py)."""
        done = subprocess.run([sys.executable, str(PROBE), what, joint, "--timeout", str(timeout_s), *options],
                              env=self.env, capture_output=True, text=True, timeout=timeout_s + 30)
        result = json.loads(done.stdout.strip().splitlines()[-1])
        assert done.returncode == 0, result
        return result

    def stop(self) -> None:
        stop_process(self.process)
        self._out.close()


__all__ = ["ServedRobot"]

"""``jointctl bode --hardware industrial``: an industrial controller's own position loop measured over
simple_message in real time (the simulated controller in its own process)."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys

import pytest

from tests.test_cli import assert_one_line_error, jointctl

STREAM_PERIOD_S = 0.02  # a streamed point is reached one stream period after it is sent, at the earliest


@pytest.fixture
def controller():
    process = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "controller", "one_dof", "--host", "127.0.0.1",
                                "--motion-port", "0", "--state-port", "0"], stdout=subprocess.PIPE,
                               stderr=subprocess.DEVNULL, text=True)
    ports = re.search(r"motion port (\d+), state port (\d+)", process.stdout.readline())
    assert ports, "the controller did not start"
    yield ports.group(1), ports.group(2)
    process.terminate()
    process.wait(15)


def test_the_controllers_loop_is_measured_over_the_socket(controller, tmp_path) -> None:
    motion, state = controller
    result = jointctl("bode", "one_dof", "--joint", "joint1", "--hardware", "industrial", "--robot-ip", "127.0.0.1",
                      "--motion-port", motion, "--state-port", state, "--f-min-hz", "1", "--f-max-hz", "4",
                      "--points", "3", "--amplitude", "0.1", "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["frequencies_hz"] == pytest.approx([1.0, 2.0, 4.0])
    gain, phase = metrics["gain_db"], metrics["phase_deg"]
    assert abs(gain[0]) < 2.0  # it follows at 1 Hz
    for f, lag in zip(metrics["frequencies_hz"], phase):
        assert -lag >= math.degrees(2 * math.pi * f * STREAM_PERIOD_S)  # never ahead of the stream's delay
    assert phase[0] > phase[1] > phase[2]  # more lag the faster
    assert (tmp_path / "bode.png").is_file()


def test_bode_over_the_bridge_needs_a_joint_and_a_reachable_controller(tmp_path) -> None:
    assert_one_line_error(jointctl("bode", "one_dof", "--hardware", "industrial", "--robot-ip", "127.0.0.1",
                                   "--out", tmp_path), "--joint")
    assert_one_line_error(jointctl("bode", "one_dof", "--joint", "joint1", "--hardware", "industrial",
                                   "--robot-ip", "127.0.0.1", "--motion-port", "1", "--state-port", "1",
                                   "--out", tmp_path), "no industrial controller answers")

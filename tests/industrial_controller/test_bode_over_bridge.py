"""``jointctl bode --hardware industrial``: an industrial controller's own position loop measured over
simple_message in real time (the simulated controller in its own process)."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from jointctl.identification.frequency_response import LoopModel, model_plant
from jointctl.model.loader import load_robot_model
from jointctl.scenario.spec import load_scenario

from tests.test_cli import assert_one_line_error, jointctl

STREAM_PERIOD_S = 0.02  # a streamed point is reached one stream period after it is sent, at the earliest
STATE_PERIOD_S = 0.02  # the controller reports the joint's position 50 times a second
#: What the model leaves out: the 1 kHz sampling of the servo and the two sides' wall-clock pacing (a point a
#: few ms late shortens or stretches one segment); the model's gains at 1, 2 and 4 Hz differ by 0.5 to 1 dB.
GAIN_TOLERANCE_DB = 0.2


def model_gain_db(frequencies_hz) -> np.ndarray:
    """The gain [dB] the sweep should measure. The controller's servo (one_dof_servo_params.yaml: p 400 N/m, d 30
    N·s/m on the velocity error, the model's gravity, damping and inertia fed forward) makes
    m·q̈ + (b + d)·q̇ + p·q = p·r + (b + d)·ṙ + m·r̈ (m, b: the robot model's mass and damping); its reference r is
    the streamed points (one every 20 ms) joined by straight segments, whose r̈ is 0 within a segment: the servo's
    response is ((b + d)·s + p) / (m·s² + (b + d)·s + p). Straight segments through samples have the gain sinc²
    of f·T (T the stream period), and the positions the controller reports 50 times a second, held between
    reports, sinc of f·T_state."""
    robot = load_robot_model(load_scenario("one_dof_step").robot.description)
    mass, damping = model_plant(robot, "joint1", {"joint1": 0.0})
    p, d = 400.0, 30.0
    f = np.asarray(frequencies_hz, dtype=float)
    s = 2j * np.pi * f
    servo = ((damping + d) * s + p) / (mass * s**2 + (damping + d) * s + p)
    return 20 * np.log10(np.abs(servo) * np.sinc(f * STREAM_PERIOD_S) ** 2 * np.sinc(f * STATE_PERIOD_S))


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
    expected = model_gain_db(metrics["frequencies_hz"])
    assert gain == pytest.approx(list(expected), abs=GAIN_TOLERANCE_DB)
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

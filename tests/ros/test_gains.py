"""PID gains changed on a running node through dynamic_reconfigure, checked with ROS's own tools.

Tests that leave the gains as they found them (reading them, or having invalid ones refused) share
one served robot (``position_served``); a test that changes them serves its own.
"""

from __future__ import annotations

import json
import os
import re
import sys
from pathlib import Path

import pytest

from tests.ros.conftest import joint_position, run, served_graph, settle_to, wait_for_topic, wait_until

try:
    import dynamic_reconfigure.server  # noqa: F401
except ImportError:
    if os.environ.get("JOINTCTL_REQUIRE_ROS"):
        raise  # make ros installs it; CI must not skip
    pytest.skip("dynamic_reconfigure is not installed (make ros)", allow_module_level=True)

HERE = Path(__file__).parent
CLIENT = str(HERE / "reconfigure_client.py")
JOINT_STATES = "/one_DOF_robot/joint_states"
POSITION_PID = "/one_DOF_robot/joint1_position_controller/pid"
POSITION_STATE = "/one_DOF_robot/joint1_position_controller/state"
DROOP = 1.01 * 9.81 / 400  # the P-only position loop's gravity droop at p = 400 [m]


@pytest.fixture
def serve_gains(serve):
    """``jointctl serve ARGS``, once joint states flow (the node attaches the gain servers itself)."""
    return lambda *args: serve(*args, wait_topic=JOINT_STATES)


@pytest.fixture(scope="module")
def position_served(tmp_path_factory):
    """one_dof under its position controller for the tests that leave its gains as they are: the
    graph (its env; the node's output in ``folder/serve.log``)."""
    with served_graph(tmp_path_factory.mktemp("gains"), "one_dof", "--controllers", "position",
                      wait_topic=JOINT_STATES) as (graph, _):
        yield graph


def position(env) -> float:
    return joint_position(env, JOINT_STATES)


def reconfigure(env, server: str, changes: dict | None = None) -> dict:
    args = [sys.executable, CLIENT, server] + ([json.dumps(changes)] if changes is not None else [])
    return json.loads(run(env, *args, timeout=60).stdout.strip().splitlines()[-1])


def state_gains(env, topic: str = POSITION_STATE) -> dict:
    text = wait_for_topic(env, topic)
    return {k: float(re.search(rf"^{k}: (\S+)$", text, re.M).group(1)) for k in ("p", "i", "d")}


def test_a_new_p_gain_applies_on_the_running_loop(ros_env, serve_gains, probe):
    serve_gains("one_dof", "--controllers", "position")
    assert settle_to(ros_env, -0.5 - DROOP, tol=0.001) == pytest.approx(-0.5 - DROOP, abs=0.001)
    config = reconfigure(ros_env, POSITION_PID, {"p": 800})
    assert config["p"] == 800.0
    # The controller's state reports the new gain, and the gravity droop halves.
    wait_until(lambda: state_gains(ros_env)["p"] == 800.0, "the controller's state to report p 800")
    assert settle_to(ros_env, -0.5 - DROOP / 2, tol=0.001) == pytest.approx(-0.5 - DROOP / 2, abs=0.001)
    # dynamic_reconfigure mirrors the configuration on the parameter server, as rqt expects.
    assert probe.param(f"{POSITION_PID}/p") == 800.0


def test_the_velocity_controller_gets_a_server_too(ros_env, serve_gains):
    serve_gains("one_dof", "--controllers", "velocity")
    server = "/one_DOF_robot/joint1_velocity_controller/pid"
    before = reconfigure(ros_env, server)
    config = reconfigure(ros_env, server, {"d": 1.5, "antiwindup": True})
    assert config["d"] == 1.5 and config["antiwindup"] is True and config["p"] == before["p"]
    assert state_gains(ros_env, "/one_DOF_robot/joint1_velocity_controller/state")["d"] == 1.5


class _FakeController:
    """Just the two doors the reconfigure callback uses."""

    def __init__(self, gains):
        from jointctl.control.pid import Pid
        self.pid = Pid(gains)

    def set_gains(self, gains):
        self.pid.set_gains(gains)


def test_the_callback_validates_widens_ints_and_keeps_unbounded_clamps():
    from dynamic_reconfigure.encoding import Config, encode_description

    from jointctl.control.pid import PidGains
    from jointctl.ros.gains import _callback, pid_config_type

    start = PidGains(400.0, 0.0, 0.0, -float("inf"), float("inf"))  # a joint without effort limit
    kind = pid_config_type(start)
    encode_description(kind)  # the description a Server publishes encodes
    assert kind.min["p"] == 0.0 and kind.max["p"] == float("inf") and kind.all_level == 1
    controller = _FakeController(start)
    callback = _callback(controller, "/robot/c/pid")
    config = Config(kind.defaults, p=800)  # an int, as a YAML ``p: 800`` on the parameter server gives
    answer = callback(config, ~0)
    assert controller.pid.gains.p == 800.0 and type(answer["p"]) is float  # encodes as a double
    refused = callback(Config(answer, p=-1.0), 1)
    assert refused["p"] == 800.0 and controller.pid.gains.p == 800.0
    refused = callback(Config(answer, antiwindup=1.0), 1)
    assert refused["antiwindup"] is False and controller.pid.gains == answer_gains(answer)


def answer_gains(config):
    from jointctl.control.pid import PidGains
    return PidGains(config["p"], config["i"], config["d"], config["i_clamp_min"], config["i_clamp_max"],
                    config["antiwindup"])


# -- gains left as they are: one served robot for these (last, so that it runs alone) -------------

def test_the_server_starts_from_the_yaml_gains(position_served):
    config = reconfigure(position_served.env, POSITION_PID)
    assert (config["p"], config["i"], config["d"]) == (400.0, 0.0, 0.0)
    assert config["antiwindup"] is False
    assert config["i_clamp_max"] == 1000.0 and config["i_clamp_min"] == -1000.0  # the effort limit
    described = config["_descriptions"]
    assert {n: d["type"] for n, d in described.items()} == {
        "p": "double", "i": "double", "d": "double", "i_clamp_min": "double", "i_clamp_max": "double",
        "antiwindup": "bool"}
    assert all(described[n]["min"] == 0.0 for n in "pid")


@pytest.mark.parametrize("changes", [{"p": -5.0}, {"d": float("nan")}, {"i": float("inf")},
                                     {"i_clamp_min": 10.0, "i_clamp_max": 5.0}])
def test_invalid_gains_are_refused_and_the_gains_stay(position_served, changes):
    env, log = position_served.env, position_served.folder / "serve.log"
    # The shared robot as served (a change that got through in an earlier case would show here).
    assert state_gains(env) == {"p": 400.0, "i": 0.0, "d": 0.0}
    refusals = log.read_text().count("refused gains")
    config = reconfigure(env, POSITION_PID, changes)
    # The request arrived (the server answered it, and said so in its log) and changed nothing.
    wait_until(lambda: log.read_text().count("refused gains") == refusals + 1, "the node to log the refusal")
    assert (config["p"], config["i"], config["d"]) == (400.0, 0.0, 0.0)  # the answer: unchanged
    assert (config["i_clamp_min"], config["i_clamp_max"]) == (-1000.0, 1000.0)
    assert state_gains(env) == {"p": 400.0, "i": 0.0, "d": 0.0}  # a state published after the answer
    assert position(env) == pytest.approx(-0.5 - DROOP, abs=0.001)
    assert position_served.probe.param(f"{POSITION_PID}/p") == 400.0

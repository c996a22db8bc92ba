"""jointctl serve --hardware industrial on a real ROS graph, against a simple_message peer on
loopback that servos ideally (it jumps to each point it receives): the node's wiring, ROS-Industrial's
names, goals through joint_trajectory_action, stale state and an unreachable controller."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.hardware.test_industrial import Peer
from tests.ros.conftest import free_port, joint_positions, run, wait_for_topic

CLIENT = str(Path(__file__).with_name("action_client.py"))
SERVER = "/joint_trajectory_action"


@pytest.fixture
def peer():
    p = Peer(positions=[-0.5], follow=True)
    yield p
    p.close()


def serve_industrial(serve, peer, *extra):
    return serve("one_dof", "--hardware", "industrial", "--robot-ip", "127.0.0.1",
                 "--motion-port", str(peer.motion_port), "--state-port", str(peer.state_port), *extra,
                 wait_topic="/feedback_states")


def goal_args(points) -> list[str]:
    return [sys.executable, CLIENT, "follow", SERVER, json.dumps({"joint_names": ["joint1"], "points": points})]


def test_a_goal_through_joint_trajectory_action_streams_points_and_succeeds(ros_env, serve, peer):
    serve_industrial(serve, peer)
    assert run(ros_env, "rosparam", "get", "/controller_joint_names").stdout.strip() == "- joint1"
    assert run(ros_env, "rosparam", "get", "/robot_ip_address").stdout.strip() == "127.0.0.1"
    status = wait_for_topic(ros_env, "/robot_status")
    assert "mode: \n  val: 2" in status and "in_motion: \n  val: 0" in status
    feedback = wait_for_topic(ros_env, "/feedback_states")
    assert "-0.5" in feedback  # the peer's reported position
    result = run(ros_env, *goal_args([[1.0, [-0.4]], [2.0, [-0.3]]]), timeout=90)
    done = json.loads(result.stdout.strip().splitlines()[-1])
    assert done["state"] == "SUCCEEDED", done
    assert peer.points[0].sequence == 0  # a motion from rest: a new trajectory
    assert [p.sequence for p in peer.points] == list(range(len(peer.points)))
    assert len(peer.points) > 20  # streamed at 50 Hz over the goal's 2 s, not sent whole
    assert all(p.duration == pytest.approx(0.02) for p in peer.points)
    assert peer.points[-1].positions[0] == pytest.approx(-0.3, abs=1e-6)
    assert "-0.3" in wait_for_topic(ros_env, "/joint_states")  # ROS-I's global joint_states


def test_stale_state_aborts_the_goal_saying_why(ros_env, serve, peer):
    serve_industrial(serve, peer)
    client = subprocess.Popen(goal_args([[6.0, [-0.2]]]), env=ros_env, stdout=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 30
    while len(peer.points) < 5:  # the goal runs: points arrive
        assert time.monotonic() < deadline, "no points streamed"
        time.sleep(0.05)
    peer.publishing.clear()  # the controller stops reporting
    out, _ = client.communicate(timeout=60)
    done = json.loads(out.strip().splitlines()[-1])
    assert done["state"] == "ABORTED", done
    assert "no joint state from 127.0.0.1" in done["text"]


def test_an_unreachable_controller_is_one_error_line_and_exit_2(ros_env):
    port = free_port()  # nobody listens there
    result = run(ros_env, sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--hardware", "industrial",
                 "--robot-ip", "127.0.0.1", "--motion-port", str(port), "--state-port", str(port),
                 timeout=60, check=False)
    assert result.returncode == 2
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert lines == [f"jointctl: error: robot_ip: no industrial controller answers on its state port "
                     f"(Connection refused) (got '127.0.0.1:{port}')"], result.stderr


def test_robot_ip_is_required_with_industrial_hardware(ros_env):
    result = run(ros_env, sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--hardware", "industrial",
                 timeout=60, check=False)
    assert result.returncode == 2 and "--robot-ip: is required with --hardware industrial" in result.stderr


def test_every_state_report_is_relayed_once_as_ros_is_robot_state_does(ros_env, serve, peer):
    serve_industrial(serve, peer)
    peer.period_s = 0.05  # 20 Hz: 50 of the node's 1 ms cycles between reports
    peer.step_per_report = 0.0009765625  # 2^-10 m, exact in float32: reports are told apart by their value
    seen = joint_positions(ros_env, "/joint_states", 40)
    steps = [b - a for a, b in zip(seen, seen[1:])]
    assert steps == pytest.approx([2**-10] * len(steps), abs=1e-7)  # none skipped, none twice

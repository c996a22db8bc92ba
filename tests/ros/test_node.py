"""jointctl serve on a real ROS graph, driven and read with ROS's own tools and clients.

The tests that only read the robot share one served robot (``position_served``, a graph of its
own); the others serve their own. Reads go through the module's probe node (tests/ros/conftest.py);
``rostopic pub``, ``rosparam`` and ``rosbag`` are used where the test is about the tool's way.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.ros.conftest import (joint_position, joint_positions, printed_until, run, served_graph, settle_to,
                                stop_and_read, wait_for_topic, wait_until)

JOINT_STATES = "/one_DOF_robot/joint_states"
COMMAND = "/one_DOF_robot/joint1_position_controller/command"
CLIENT = str(Path(__file__).with_name("action_client.py"))
DROOP = 1.01 * 9.81 / 400  # the P-only position loop's gravity droop [m]


def position(env) -> float:
    return joint_position(env, JOINT_STATES)


@pytest.fixture(scope="module")
def position_served(tmp_path_factory):
    """one_dof under its position controller, only read by the tests that use it: the env."""
    with served_graph(tmp_path_factory.mktemp("position_served"), "one_dof", "--controllers", "position",
                      wait_topic=JOINT_STATES) as (graph, _):
        yield graph.env


def test_joint_states_commands_and_parameters(ros_env, serve, probe):
    serve("one_dof", "--controllers", "position", wait_topic=JOINT_STATES)
    text = wait_for_topic(ros_env, JOINT_STATES)
    assert "joint1" in text and "effort" in text
    # Spawned mid-range, it holds -0.5 minus the gravity droop.
    assert settle_to(ros_env, -0.5 - DROOP) == pytest.approx(-0.5 - DROOP, abs=0.002)
    probe.publish(COMMAND, "std_msgs/Float64", {"data": -0.3})
    assert settle_to(ros_env, -0.3 - DROOP) == pytest.approx(-0.3 - DROOP, abs=0.002)
    # The chapter's YAML is on the parameter server as rosparam load would put it.
    assert run(ros_env, "rosparam", "get", "/one_DOF_robot/joint1_position_controller/pid/p").stdout.strip() == "400.0"
    state = wait_for_topic(ros_env, "/one_DOF_robot/joint1_position_controller/state")
    assert "set_point: -0.3" in state


def test_non_finite_commands_are_refused_and_the_joint_holds(ros_env, serve, probe):
    node = serve("one_dof", "--controllers", "position", wait_topic=JOINT_STATES)
    # Commands on this topic do arrive: a valid one moves the joint.
    probe.publish(COMMAND, "std_msgs/Float64", {"data": -0.4})
    assert settle_to(ros_env, -0.4 - DROOP) == pytest.approx(-0.4 - DROOP, abs=0.002)
    # YAML spellings: rostopic reads its arguments as YAML. One at a time: the node subscribes with a
    # queue of one, as ros_control does, so a second message could replace the first unread. Each
    # rostopic is stopped once the node has logged the refusal (it would linger 3 s, latching).
    for count, bad in enumerate((".nan", ".inf"), start=1):
        pub = subprocess.Popen(["rostopic", "pub", "-1", COMMAND, "std_msgs/Float64", "--", bad], env=ros_env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            printed_until(node, lambda text: text.count("jointctl: refused") >= count, f"{bad} to be refused")
        finally:
            pub.terminate()
            pub.wait(10)
    # Both arrived and were refused; a state published after that: the last valid command holds.
    assert position(ros_env) == pytest.approx(-0.4 - DROOP, abs=0.002)
    out = stop_and_read(node)
    assert out.count("jointctl: refused") == 2, out[-2000:]  # both arrived, and both were refused
    assert "must be a finite number" in out


def client(env, kind, server, joint_names, points, *extra):
    result = run(env, sys.executable, CLIENT, kind, server,
                 json.dumps({"joint_names": joint_names, "points": points}), *extra, timeout=90)
    return json.loads(result.stdout.strip().splitlines()[-1])


SEQUENCE = str(Path(__file__).with_name("goal_sequence_client.py"))


def test_follow_joint_trajectory_succeeds_and_bad_goals_are_rejected(ros_env, serve):
    serve("one_dof", "--controllers", "trajectory", wait_topic=JOINT_STATES)
    server = "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory"
    # One client process; each goal sent once the one before it has ended.
    goals = [{"joint_names": ["joint1"], "points": [[1.0, [-0.4]], [2.0, [-0.3]]]},
             {"after_previous": True, "joint_names": ["joint9"], "points": [[1.0, [-0.4]]]},
             {"after_previous": True, "joint_names": ["joint1"], "points": [[1.0, [0.5]]]}]
    result = run(ros_env, sys.executable, SEQUENCE, "follow", server, json.dumps(goals), timeout=90)
    done, refused, beyond = json.loads(result.stdout.strip().splitlines()[-1])
    assert done["state"] == "SUCCEEDED" and done["result"]["error_code"] == 0
    assert done["feedback"] > 10
    assert refused["state"] == "REJECTED" and refused["result"]["error_code"] == -2  # INVALID_JOINTS
    assert "joint9" in refused["text"]
    assert beyond["state"] == "REJECTED" and beyond["result"]["error_code"] == -1
    # Feed-forward: no droop; and the rejected goals moved nothing (states published after them).
    assert position(ros_env) == pytest.approx(-0.3, abs=0.002)


def test_the_chapters_trajectory_action_server(ros_env, serve):
    serve("one_dof", "--controllers", "trajectory", wait_topic=JOINT_STATES)
    done = client(ros_env, "traj", "example_traj_action_server", ["joint1"], [[0.5, [-0.45]], [1.0, [-0.4]]])
    assert done["state"] == "SUCCEEDED" and done["result"]["rtn_status"] == 0


def test_cancel_ends_the_goal_preempted_and_the_joint_stops(ros_env, serve, probe):
    serve("one_dof", "--controllers", "trajectory", wait_topic=JOINT_STATES)
    server = "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory"
    done = client(ros_env, "follow", server, ["joint1"], [[6.0, [-0.1]]], "--cancel-after", "1.0")
    assert done["state"] == "PREEMPTED"
    # Stopped: it comes to rest (however long the machine takes to show it), then stays, short of the goal.
    wait_until(lambda: abs(probe.message(JOINT_STATES)["velocity"][0]) < 1e-3, "the joint to come to rest")
    rest = joint_positions(ros_env, JOINT_STATES, 25)  # half a second at 50 Hz
    assert max(rest) - min(rest) < 0.002
    assert rest[-1] < -0.15  # short of the goal


def test_sim_time_publishes_clock_and_stamps_in_loop_time(ros_env, serve, probe):
    serve("one_dof", "--controllers", "position", "--sim-time", wait_topic=JOINT_STATES)
    clock = wait_for_topic(ros_env, "/clock")
    secs = int(re.search(r"secs: (\d+)", clock).group(1))
    assert secs < 120  # loop time since start, not the wall clock's ~1.8e9 s
    assert probe.param("/use_sim_time") is True
    stamp = int(re.search(r"secs: (\d+)", wait_for_topic(ros_env, JOINT_STATES)).group(1))
    assert stamp < 120


# -- read only: one served robot for these (last, so that it runs alone) --------------------------

def test_joint_states_are_stamped_every_period_in_order_and_the_force_sensor(position_served):
    # publish_rate 50: consecutive samples are one 20 ms period of loop time apart, none lost, in
    # order (the wall-clock rate belongs to make bench). A second of them.
    stamps = joint_positions(position_served, JOINT_STATES, 50, "field.header.stamp")
    steps = [b - a for a, b in zip(stamps, stamps[1:])]
    assert steps == pytest.approx([0.02e9] * len(steps), abs=1e3)  # ns, within 1 µs
    wrench = wait_for_topic(position_served, "/ft_sensor_topic")
    force_z = float(re.search(r"force:\s*\n\s*x: \S+\n\s*y: \S+\n\s*z: (\S+)", wrench).group(1))
    assert force_z == pytest.approx(-0.01 * 9.81, abs=1e-3)  # the plate's own weight, negative


def test_rosbag_records_the_robot(position_served, tmp_path):
    bag = tmp_path / "run.bag"
    # --limit: rosbag stops by itself once it has recorded that many messages of each topic.
    run(position_served, "rosbag", "record", "--limit", "60", "-O", str(bag), JOINT_STATES, "/ft_sensor_topic",
        timeout=60)
    info = run(position_served, "rosbag", "info", str(bag)).stdout
    assert "sensor_msgs/JointState" in info and "geometry_msgs/WrenchStamped" in info
    for topic in (JOINT_STATES, "/ft_sensor_topic"):
        assert int(re.search(rf"{topic}\s+(\d+) msgs", info).group(1)) == 60  # over a second at 50 Hz


def test_the_node_reports_its_loop_lateness(position_served):
    text = wait_for_topic(position_served, "/one_DOF_robot/loop_lateness")
    p50, p99, worst = (float(x) for x in re.search(r"data: \[([^\]]+)\]", text).group(1).split(","))
    assert 0 <= p50 <= p99 <= worst  # milliseconds; how late is the machine's business, not the test's

"""jointctl serve on a real ROS graph, driven and read with ROS's own tools and clients."""

from __future__ import annotations

import json
import re
import sys
import time
from pathlib import Path

import pytest

from tests.ros.conftest import joint_position, joint_positions, run, settle_to, wait_for_topic

JOINT_STATES = "/one_DOF_robot/joint_states"
COMMAND = "/one_DOF_robot/joint1_position_controller/command"
CLIENT = str(Path(__file__).with_name("action_client.py"))
DROOP = 1.01 * 9.81 / 400  # the P-only position loop's gravity droop [m]


def position(env) -> float:
    return joint_position(env, JOINT_STATES)


def test_joint_states_commands_and_parameters(ros_env, serve):
    serve("one_dof", "--controllers", "position", wait_topic=JOINT_STATES)
    text = wait_for_topic(ros_env, JOINT_STATES)
    assert "joint1" in text and "effort" in text
    # Spawned mid-range, it holds -0.5 minus the gravity droop.
    assert position(ros_env) == pytest.approx(-0.5 - DROOP, abs=0.002)
    run(ros_env, "rostopic", "pub", "-1", COMMAND, "std_msgs/Float64", "--", "-0.3")
    assert settle_to(ros_env, -0.3 - DROOP) == pytest.approx(-0.3 - DROOP, abs=0.002)
    # The chapter's YAML is on the parameter server as rosparam load would put it.
    assert run(ros_env, "rosparam", "get", "/one_DOF_robot/joint1_position_controller/pid/p").stdout.strip() == "400.0"
    state = wait_for_topic(ros_env, "/one_DOF_robot/joint1_position_controller/state")
    assert "set_point: -0.3" in state


def test_non_finite_commands_are_refused_and_the_joint_holds(ros_env, serve):
    node = serve("one_dof", "--controllers", "position", wait_topic=JOINT_STATES)
    # Commands on this topic do arrive: a valid one moves the joint.
    run(ros_env, "rostopic", "pub", "-1", COMMAND, "std_msgs/Float64", "--", "-0.4")
    assert settle_to(ros_env, -0.4 - DROOP) == pytest.approx(-0.4 - DROOP, abs=0.002)
    for bad in (".nan", ".inf"):  # YAML spellings: rostopic reads its arguments as YAML
        run(ros_env, "rostopic", "pub", "-1", COMMAND, "std_msgs/Float64", "--", bad)
    assert position(ros_env) == pytest.approx(-0.4 - DROOP, abs=0.002)  # the last valid command holds
    node.terminate()
    out = node.communicate(timeout=20)[0]
    assert out.count("jointctl: refused") == 2, out[-2000:]  # both arrived, and both were refused
    assert "must be a finite number" in out


def test_joint_states_are_stamped_every_period_in_order_and_the_force_sensor(ros_env, serve):
    serve("one_dof", "--controllers", "position", wait_topic=JOINT_STATES)
    # publish_rate 50: consecutive samples are one 20 ms period of loop time apart, none lost, in
    # order (the wall-clock rate belongs to make bench).
    stamps = joint_positions(ros_env, JOINT_STATES, 100, "field.header.stamp")
    steps = [b - a for a, b in zip(stamps, stamps[1:])]
    assert steps == pytest.approx([0.02e9] * len(steps), abs=1e3)  # ns, within 1 µs
    wrench = wait_for_topic(ros_env, "/ft_sensor_topic")
    force_z = float(re.search(r"force:\s*\n\s*x: \S+\n\s*y: \S+\n\s*z: (\S+)", wrench).group(1))
    assert force_z == pytest.approx(-0.01 * 9.81, abs=1e-3)  # the plate's own weight, negative


def test_rosbag_records_the_robot(ros_env, serve, tmp_path):
    serve("one_dof", "--controllers", "position", wait_topic=JOINT_STATES)
    bag = tmp_path / "run.bag"
    run(ros_env, "timeout", "-s", "INT", "4", "rosbag", "record", "-O", str(bag), JOINT_STATES,
        "/ft_sensor_topic", check=False, timeout=30)
    info = run(ros_env, "rosbag", "info", str(bag)).stdout
    assert "sensor_msgs/JointState" in info and "geometry_msgs/WrenchStamped" in info
    count = int(re.search(rf"{JOINT_STATES}\s+(\d+) msgs", info).group(1))
    assert count >= 50  # at least a second of joint states at 50 Hz


def client(env, kind, server, joint_names, points, *extra):
    result = run(env, sys.executable, CLIENT, kind, server,
                 json.dumps({"joint_names": joint_names, "points": points}), *extra, timeout=90)
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_follow_joint_trajectory_succeeds_and_bad_goals_are_rejected(ros_env, serve):
    serve("one_dof", "--controllers", "trajectory", wait_topic=JOINT_STATES)
    server = "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory"
    done = client(ros_env, "follow", server, ["joint1"], [[1.0, [-0.4]], [2.0, [-0.3]]])
    assert done["state"] == "SUCCEEDED" and done["result"]["error_code"] == 0
    assert done["feedback"] > 10
    assert position(ros_env) == pytest.approx(-0.3, abs=0.002)  # feed-forward: no droop
    refused = client(ros_env, "follow", server, ["joint9"], [[1.0, [-0.4]]])
    assert refused["state"] == "REJECTED" and refused["result"]["error_code"] == -2  # INVALID_JOINTS
    assert "joint9" in refused["text"]
    beyond = client(ros_env, "follow", server, ["joint1"], [[1.0, [0.5]]])
    assert beyond["state"] == "REJECTED" and beyond["result"]["error_code"] == -1
    assert position(ros_env) == pytest.approx(-0.3, abs=0.002)  # nothing moved


def test_the_chapters_trajectory_action_server(ros_env, serve):
    serve("one_dof", "--controllers", "trajectory", wait_topic=JOINT_STATES)
    done = client(ros_env, "traj", "example_traj_action_server", ["joint1"], [[0.5, [-0.45]], [1.0, [-0.4]]])
    assert done["state"] == "SUCCEEDED" and done["result"]["rtn_status"] == 0


def test_cancel_ends_the_goal_preempted_and_the_joint_stops(ros_env, serve):
    serve("one_dof", "--controllers", "trajectory", wait_topic=JOINT_STATES)
    server = "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory"
    done = client(ros_env, "follow", server, ["joint1"], [[6.0, [-0.1]]], "--cancel-after", "2.0")
    assert done["state"] == "PREEMPTED"
    q1 = position(ros_env)
    time.sleep(1.0)
    assert position(ros_env) == pytest.approx(q1, abs=0.002)  # at rest, short of the goal
    assert q1 < -0.15


def test_sim_time_publishes_clock_and_stamps_in_loop_time(ros_env, serve):
    serve("one_dof", "--controllers", "position", "--sim-time", wait_topic=JOINT_STATES)
    clock = wait_for_topic(ros_env, "/clock")
    secs = int(re.search(r"secs: (\d+)", clock).group(1))
    assert secs < 120  # loop time since start, not the wall clock's ~1.8e9 s
    assert run(ros_env, "rosparam", "get", "/use_sim_time").stdout.strip() == "true"
    stamp = int(re.search(r"secs: (\d+)", wait_for_topic(ros_env, JOINT_STATES)).group(1))
    assert stamp < 120


def test_the_node_reports_its_loop_lateness(ros_env, serve):
    serve("one_dof", "--controllers", "position", wait_topic=JOINT_STATES)
    text = wait_for_topic(ros_env, "/one_DOF_robot/loop_lateness")
    p50, p99, worst = (float(x) for x in re.search(r"data: \[([^\]]+)\]", text).group(1).split(","))
    assert 0 <= p50 <= p99 <= worst  # milliseconds; how late is the machine's business, not the test's

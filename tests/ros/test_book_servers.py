"""The chapter's action servers behave as the book's SimpleActionServers do, against clients that
behave as the book's clients do; ``follow_joint_trajectory`` keeps joint_trajectory_controller's
semantics beside them."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from jointctl.model.loader import load_robot_model
from jointctl.scenario.analyses.minimal_robot import pendulum_theory
from jointctl.trajectory.timing import chapter_timing
from tests.ros.conftest import joint_positions, run, settle_to, wait_for_topic, wait_until

ONE_DOF_STATES = "/one_DOF_robot/joint_states"
ARM_STATES = "/arm7dof/joint_states"
SEQUENCE = str(Path(__file__).with_name("goal_sequence_client.py"))
#: The book's arm clients time paths with these limits at half speed (chapter11-facts section 8).
CLIENT_VMAX = np.array([0.17, 0.17, 0.3, 0.3, 0.4, 0.4, 0.4])
PRE_POSE = [0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0]
ABORT_BEFORE_REJECT = "To transition to an aborted state"


def send_goals(env, kind: str, server: str, goals: list[dict]) -> list[dict]:
    result = run(env, sys.executable, SEQUENCE, kind, server, json.dumps(goals), timeout=180)
    return json.loads(result.stdout.strip().splitlines()[-1])


def timed_path(path, names=None) -> dict:
    """A goal as the book's arm clients make one: the chapter's timing from the first pose."""
    path = np.asarray(path, dtype=float)
    times = chapter_timing(path, CLIENT_VMAX, velocity_fraction=0.5)
    return {"joint_names": names or [f"joint{i}" for i in range(7)],
            "points": [[float(t), q.tolist()] for t, q in zip(times, path)]}


def arm_pose(env) -> list[float]:
    return [joint_positions(env, ARM_STATES, 1, f"field.position{i}")[-1] for i in range(7)]


def stop_and_read(process) -> str:
    process.terminate()
    return process.communicate(timeout=20)[0]


#: Loop time per wall-clock time where a test waits out the book's long goals: goals are timed in
#: loop time, so a wall-clock span of a goal is its duration / SPEED at the least.
SPEED = 2.0


def test_the_prompters_second_goal_waits_for_the_first_and_starts_where_it_ended(ros_env, serve):
    serve("arm7dof", "--controllers", "trajectory", "--speed", str(SPEED), wait_topic=ARM_STATES)
    first = timed_path([[0.0] * 7, PRE_POSE])
    assert first["points"][-1][0] == pytest.approx(13.333, abs=1e-3)
    target = PRE_POSE[:6] + [0.3]
    second = timed_path([PRE_POSE, target])  # from the last commanded pose, at time 0
    # As the prompter: while the first still runs (it takes 13.3 s / SPEED of wall clock at least).
    second["send_at_s"] = 10.0 / SPEED
    one, two = send_goals(ros_env, "arm", "trajActionServer", [first, second])
    assert one["state"] == "SUCCEEDED", one
    assert two["state"] == "SUCCEEDED", two
    # The second ran after the first: it ended at least its own duration after the first ended.
    assert two["ended_s"] >= one["ended_s"] + second["points"][-1][0] / SPEED
    assert two["result"]["return_val"] == one["result"]["return_val"] + 1  # goals served so far
    assert arm_pose(ros_env) == pytest.approx(target, abs=0.02)


def test_a_goal_stamped_in_the_past_runs_whole_from_when_it_starts(ros_env, serve):
    serve("arm7dof", "--controllers", "trajectory", wait_topic=ARM_STATES)
    # 0.1 rad at 0.2 rad/s: a 0.5 s first segment. Honouring a 0.4 s old stamp would leave 0.1 s
    # for it, 1 rad/s against joint 4's 0.4 rad/s limit.
    path = [[0.0] * 7, [0, 0, 0, 0, 0.1, 0.1, 0.1], [0, 0, 0, 0, 0.3, 0.2, 0.3]]
    goal = dict(timed_path(path), stamp_age_s=0.4)
    follow = send_goals(ros_env, "follow",
                        "/arm7dof/arm7dof_trajectory_controller/follow_joint_trajectory", [goal])[0]
    assert follow["state"] == "REJECTED" and "limit" in follow["text"]  # stamps honoured there
    done = send_goals(ros_env, "arm", "trajActionServer", [goal])[0]
    assert done["state"] == "SUCCEEDED", done
    assert arm_pose(ros_env) == pytest.approx(path[-1], abs=0.02)


def test_a_newer_waiting_goal_replaces_the_older_waiting_one(ros_env, serve):
    process = serve("one_dof", "--controllers", "trajectory", wait_topic=ONE_DOF_STATES)
    # 6 s: long enough that both later goals arrive while it runs, however busy the machine.
    running = {"joint_names": ["joint1"], "points": [[0.0, [-0.5]], [6.0, [-0.3]]]}
    replaced = {"send_at_s": 0.5, "joint_names": ["joint1"], "points": [[0.0, [-0.3]], [1.0, [-0.4]]]}
    last = {"send_at_s": 1.0, "joint_names": ["joint1"], "points": [[0.0, [-0.3]], [1.0, [-0.2]]]}
    a, b, c = send_goals(ros_env, "traj", "example_traj_action_server", [running, replaced, last])
    assert a["state"] == "SUCCEEDED" and a["result"]["rtn_status"] == 0
    # SimpleActionServer cancels the goal that waited: a pending goal canceled ends RECALLED.
    assert b["state"] == "RECALLED" and "another goal" in b["text"]
    assert c["state"] == "SUCCEEDED"
    assert c["ended_s"] >= a["ended_s"] + 1.0
    assert settle_to(ros_env, -0.2) == pytest.approx(-0.2, abs=0.002)  # feed-forward: no droop
    assert ABORT_BEFORE_REJECT not in stop_and_read(process)


def test_a_queued_goal_that_does_not_start_where_the_last_ended_is_aborted(ros_env, serve):
    serve("one_dof", "--controllers", "trajectory", wait_topic=ONE_DOF_STATES)
    running = {"joint_names": ["joint1"], "points": [[0.0, [-0.5]], [1.5, [-0.3]]]}
    elsewhere = {"send_at_s": 0.3, "joint_names": ["joint1"], "points": [[0.0, [-0.45]], [1.0, [-0.1]]]}
    a, b = send_goals(ros_env, "traj", "example_traj_action_server", [running, elsewhere])
    assert a["state"] == "SUCCEEDED"
    assert b["state"] == "ABORTED" and "current position" in b["text"] and b["result"]["rtn_status"] == -1
    assert settle_to(ros_env, -0.3) == pytest.approx(-0.3, abs=0.002)  # it stayed at the first goal's end


def test_bad_goals_are_rejected_on_arrival_without_an_abort_first(ros_env, serve):
    process = serve("one_dof", "--controllers", "trajectory", wait_topic=ONE_DOF_STATES)
    move = {"joint_names": ["joint1"], "points": [[0.0, [-0.5]], [1.0, [-0.4]]]}
    unknown = {"joint_names": ["joint9"], "points": [[1.0, [-0.4]]]}
    beyond = {"joint_names": ["joint1"], "points": [[1.0, [0.5]]]}
    ok, = send_goals(ros_env, "traj", "example_traj_action_server", [move])
    assert ok["state"] == "SUCCEEDED"  # delivered and executed: the server is there
    no_joint, = send_goals(ros_env, "traj", "example_traj_action_server", [unknown])
    assert no_joint["state"] == "REJECTED" and no_joint["result"]["rtn_status"] == -2 and "joint9" in no_joint["text"]
    out_of_range, = send_goals(ros_env, "traj", "example_traj_action_server", [beyond])
    assert out_of_range["state"] == "REJECTED" and out_of_range["result"]["rtn_status"] == -1
    follow, = send_goals(ros_env, "follow", "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory",
                         [unknown])
    assert follow["state"] == "REJECTED"
    assert settle_to(ros_env, -0.4) == pytest.approx(-0.4, abs=0.002)  # nothing moved
    out = stop_and_read(process)
    assert ABORT_BEFORE_REJECT not in out


def test_a_follow_goals_own_path_tolerance_is_honoured(ros_env, serve):
    """control_msgs: a goal's path_tolerance replaces the controller's (none here). 1 µm is below any real move's
    tracking error: ABORTED with PATH_TOLERANCE_VIOLATED; the same goal without it succeeds."""
    serve("one_dof", "--controllers", "trajectory", wait_topic=ONE_DOF_STATES)
    server = "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory"
    move = {"joint_names": ["joint1"], "points": [[1.0, [-0.4]]]}
    plain, = send_goals(ros_env, "follow", server, [move])
    assert plain["state"] == "SUCCEEDED"
    strict, = send_goals(ros_env, "follow", server, [dict(move, points=[[1.0, [-0.5]]],
                                                          path_tolerance={"joint1": 1e-6})])
    assert strict["state"] == "ABORTED" and strict["result"]["error_code"] == -4, strict


def test_a_cancel_of_the_running_goal_stops_it_and_the_next_goal_runs(ros_env, serve, probe):
    serve("one_dof", "--controllers", "trajectory", wait_topic=ONE_DOF_STATES)
    long = {"joint_names": ["joint1"], "points": [[0.0, [-0.5]], [6.0, [-0.1]]], "cancel_at_s": 1.5}
    a, = send_goals(ros_env, "traj", "example_traj_action_server", [long])
    assert a["state"] == "PREEMPTED"
    # Stopped: it comes to rest (however long the machine takes to show it), then stays, short of the goal. A
    # joint that kept following the canceled goal would come to rest only at its end, -0.1.
    wait_until(lambda: abs(probe.message(ONE_DOF_STATES)["velocity"][0]) < 1e-3, "the joint to come to rest")
    rest = joint_positions(ros_env, ONE_DOF_STATES, 25)  # half a second at 50 Hz
    assert max(rest) - min(rest) < 0.002
    assert -0.5 < rest[-1] < -0.15  # on the way, short of the goal
    # The next goal runs, from where the joint stopped.
    after = {"joint_names": ["joint1"], "points": [[0.0, [rest[-1]]], [1.0, [-0.4]]]}
    b, = send_goals(ros_env, "traj", "example_traj_action_server", [after])
    assert b["state"] == "SUCCEEDED" and b["result"]["rtn_status"] == 0
    assert settle_to(ros_env, -0.4) == pytest.approx(-0.4, abs=0.002)  # feed-forward: no droop


# -- Part 2's minimal robot, as the book's trajectory example runs on it -----------------------

MINIMAL_GOAL = Path(__file__).resolve().parents[2] / "robots" / "minimal_robot" / "goals" / "example_trajectory_client.yaml"


def test_the_book_clients_sine_goal_succeeds_on_the_minimal_robot(ros_env, serve):
    serve("minimal_robot", "--controllers", "trajectory", wait_topic=ONE_DOF_STATES)
    points = yaml.safe_load(MINIMAL_GOAL.read_text())["points"]
    goal = {"joint_names": ["joint1"], "points": [[p["time_from_start"], p["positions"]] for p in points]}
    assert max(q for _, (q,) in goal["points"]) > 0.99  # the book's 0..1 rad sine, outside one_dof's range
    done, = send_goals(ros_env, "traj", "example_traj_action_server", [goal])
    assert done["state"] == "SUCCEEDED" and done["result"]["rtn_status"] == 0
    final = goal["points"][-1][1][0]
    # Kp 10 with the model's gravity fed forward: the pendulum settles on the goal's last point.
    assert settle_to(ros_env, final, timeout_s=10.0) == pytest.approx(final, abs=0.02)


def test_the_global_pos_cmd_topic_commands_the_minimal_robots_position_loop(ros_env, serve, probe):
    serve("minimal_robot", "--controllers", "position", wait_topic=ONE_DOF_STATES)
    serve_robot = load_robot_model(MINIMAL_GOAL.parents[1] / "urdf" / "minimal_robot.xacro")
    theory = pendulum_theory(serve_robot, "joint1", (0.0, 0.0, -9.81), kp=10.0, kv=3.0)
    probe.publish("/pos_cmd", "std_msgs/Float64", {"data": 0.3})
    wait_until(lambda: "set_point: 0.3" in wait_for_topic(ros_env, "/one_DOF_robot/joint1_position_controller/state"),
               "the position loop's set point to be 0.3")
    # The book's loop without compensation holds where Kp·(0.3 - q) balances gravity's torque.
    rest = theory.equilibrium(0.3)
    assert rest > 0.35  # gravity pulls the inverted pendulum past its command
    assert settle_to(ros_env, rest, timeout_s=15.0) == pytest.approx(rest, abs=0.002)

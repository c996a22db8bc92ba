"""Faults on a real ROS graph: a client killed mid-goal, the velocity command watchdog, a NaN
command, the master restarting. Real processes throughout (rospy: one node per process)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.ports import check_free, restart_safe_ports
from tests.processes import stop_process
from tests.ros.conftest import Master, Probe, printed_until, run, stop_and_read, wait_until

JOINT_STATES = "/one_DOF_robot/joint_states"
TRAJ_SERVER = "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory"
VEL_COMMAND = "/one_DOF_robot/joint1_velocity_controller/command"
VEL_STATE = "/one_DOF_robot/joint1_velocity_controller/state"
CLIENT = str(Path(__file__).with_name("action_client.py"))
SEQUENCE = str(Path(__file__).with_name("goal_sequence_client.py"))
ACTIVE, PREEMPTED, SUCCEEDED = 1, 2, 3  # actionlib_msgs/GoalStatus


def client(env, points, *extra, timeout=90) -> dict:
    result = run(env, sys.executable, CLIENT, "follow", TRAJ_SERVER,
                 json.dumps({"joint_names": ["joint1"], "points": points}), *extra, timeout=timeout)
    return json.loads(result.stdout.strip().splitlines()[-1])


def joint(probe) -> tuple[float, float]:
    """(position, velocity) of the next joint_states sample."""
    msg = probe.message(JOINT_STATES)
    return msg["position"][0], msg["velocity"][0]


def at_rest(probe, samples: int = 25) -> list[float]:
    """Once the joint has come to rest (however long the machine takes to show it), the positions
    of the next ``samples`` joint states (half a second at 50 Hz): it stays there."""
    wait_until(lambda: abs(joint(probe)[1]) < 1e-3, "the joint to come to rest")
    return [m["position"][0] for m in probe.since(JOINT_STATES, probe.cursor(JOINT_STATES), samples)]


# -- (a) a client killed mid-goal ----------------------------------------------------------

def test_a_client_killed_mid_goal_leaves_the_server_serving(ros_env, serve, probe):
    serve("one_dof", "--controllers", "trajectory", wait_topic=JOINT_STATES)
    # Every result and status the server sends from now on.
    results, status = probe.cursor(f"{TRAJ_SERVER}/result"), probe.cursor(f"{TRAJ_SERVER}/status")
    first = subprocess.Popen([sys.executable, CLIENT, "follow", TRAJ_SERVER,
                              json.dumps({"joint_names": ["joint1"], "points": [[20.0, [-0.3]]]})],
                             env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        # Kill it once its goal is active on the server.
        wait_until(lambda: any(s["status"] == ACTIVE for m in probe.since(f"{TRAJ_SERVER}/status", status)
                               for s in m["status_list"]), "the first goal to become active")
    finally:
        first.send_signal(signal.SIGKILL)
        first.wait(10)
    # The killed client's goal (20 s long) is still running: the next goal replaces it. Then a last
    # goal, once that one has ended: its result, last on the topic, shows that every earlier one has
    # been sent (one publisher, in order), so none can come after the count below.
    goals = [{"joint_names": ["joint1"], "points": [[1.0, [-0.4]]]},
             {"after_previous": True, "joint_names": ["joint1"], "points": [[0.2, [-0.4]]]}]
    second, last = json.loads(run(ros_env, sys.executable, SEQUENCE, "follow", TRAJ_SERVER, json.dumps(goals),
                                  timeout=90).stdout.strip().splitlines()[-1])
    assert second["state"] == "SUCCEEDED" and last["state"] == "SUCCEEDED", (second, last)
    rest = at_rest(probe)
    assert rest[-1] == pytest.approx(-0.4, abs=0.003) and max(rest) - min(rest) < 0.001
    probe.since(f"{TRAJ_SERVER}/result", results, 3)  # the last goal's result has arrived ...
    ended = [(m["status"]["goal_id"]["id"], m["status"]["status"])  # ... so these are all of them
             for m in probe.since(f"{TRAJ_SERVER}/result", results)]
    ids = [goal for goal, _ in ended]
    assert len(ids) == 3 and len(set(ids)) == 3, ended  # each goal ended exactly once
    assert [s for _, s in ended] == [PREEMPTED, SUCCEEDED, SUCCEEDED]  # the killed client's goal PREEMPTED


# -- (b) the velocity watchdog over ROS, (c) NaN refused ------------------------------------

#: The controller's state is published at serve's 50 Hz: each change of its set_point is seen within
#: one 20 ms period.
STATE_PERIOD_S = 1 / 50
LOOP_PERIOD_S = 0.001


def set_point_edges(states: list[dict]) -> list[tuple[float, float]]:
    """(stamp [s, loop time], new set_point) at each change of the controller state's set_point."""
    edges, last = [], None
    for msg in states:
        if msg["set_point"] != last:
            last = msg["set_point"]
            edges.append((msg["header"]["stamp"]["s"], last))
    return edges


def test_velocity_watchdog_stops_the_joint_when_commands_stop(ros_env, serve, probe):
    serve("one_dof", "--controllers", "velocity", "--set", "gravity=0",
          "--set", "controllers.joint1_velocity_controller.command_timeout_s=0.2", wait_topic=JOINT_STATES)
    states, joints = probe.cursor(VEL_STATE), probe.cursor(JOINT_STATES)
    # Stream 0.05 m/s every 50 ms for a second, the last command 0.06 m/s (to see when it arrived).
    for value in [0.05] * 20 + [0.06]:
        probe.publish(VEL_COMMAND, "std_msgs/Float64", {"data": value})
        time.sleep(0.05)  # the commander's pace, not a synchronisation
    # The watchdog zeroes the reference 0.2 s of loop time after the cycle that first saw the last
    # command. Both changes are read from the controller's state, stamped in loop time, each seen at
    # the first state published after it: late by less than one state period, and the watchdog's
    # strict "older than" adds at most one loop period. So the interval is 0.2 s within
    # STATE_PERIOD_S + LOOP_PERIOD_S, however late this busy machine delivered anything.
    def last_command_then_zero():
        edges = set_point_edges(probe.since(VEL_STATE, states))
        return edges if [v for _, v in edges[-2:]] == [0.06, 0.0] else None

    edges = wait_until(last_command_then_zero, "the set point to go from the last command (0.06) to zero")
    (t_last, _), (t_zero, _) = edges[-2:]
    assert t_zero - t_last == pytest.approx(0.2, abs=STATE_PERIOD_S + LOOP_PERIOD_S), edges
    assert 0.05 in [v for _, v in edges]  # the streamed commands arrived
    moving = [m["velocity"][0] for m in probe.since(JOINT_STATES, joints) if m["header"]["stamp"]["s"] < t_last]
    assert max(moving) == pytest.approx(0.05, abs=0.01)  # it was streaming at 0.05 m/s
    # Then the joint comes to rest and stays: the reference stays zero without new commands.
    rest = at_rest(probe)
    assert max(rest) - min(rest) < 0.001
    assert set_point_edges(probe.since(VEL_STATE, states))[-1] == (t_zero, 0.0)


def test_without_the_watchdog_the_joint_keeps_going(ros_env, serve, probe):
    serve("one_dof", "--controllers", "velocity", "--set", "gravity=0", wait_topic=JOINT_STATES)
    states, joints = probe.cursor(VEL_STATE), probe.cursor(JOINT_STATES)
    probe.publish(VEL_COMMAND, "std_msgs/Float64", {"data": 0.05})  # one command, then silence
    (t_command, _), = wait_until(lambda: [e for e in set_point_edges(probe.since(VEL_STATE, states)) if e[1] == 0.05],
                                 "the command to reach the controller")
    # A second of loop time after it arrived (five times the other test's watchdog), it still drives
    # the joint: ros_control's behaviour.
    wait_until(lambda: probe.since(VEL_STATE, states)[-1]["header"]["stamp"]["s"] > t_command + 1.0,
               "a second of loop time after the command")
    assert [v for _, v in set_point_edges(probe.since(VEL_STATE, states))][-1] == 0.05
    late = [m["velocity"][0] for m in probe.since(JOINT_STATES, joints)
            if t_command + 0.5 < m["header"]["stamp"]["s"] <= t_command + 1.0]
    assert late and min(late) == pytest.approx(0.05, abs=0.01)


def test_a_nan_velocity_command_is_refused_and_the_joint_keeps_its_state(ros_env, serve, probe):
    node = serve("one_dof", "--controllers", "velocity", "--set", "gravity=0", wait_topic=JOINT_STATES)
    # Valid commands first, on the same connection: the joint moves, then stops.
    probe.publish(VEL_COMMAND, "std_msgs/Float64", {"data": 0.05})
    wait_until(lambda: joint(probe)[1] == pytest.approx(0.05, abs=0.005), "the joint to move at 0.05 m/s")
    wait_until(lambda: joint(probe)[0] > -0.5 + 0.02, "the joint to move 2 cm")
    probe.publish(VEL_COMMAND, "std_msgs/Float64", {"data": 0.0})
    stopped = at_rest(probe)
    q_stopped = stopped[-1]
    assert q_stopped > -0.5 + 0.01  # it did move
    # One at a time: the node subscribes with a queue of one (as ros_control does), so a second
    # message could replace the first unread.
    for count, bad in enumerate(("nan", "inf"), start=1):
        probe.publish(VEL_COMMAND, "std_msgs/Float64", {"data": bad})
        printed_until(node, lambda text: text.count("jointctl: refused") >= count, f"{bad} to be refused")
    # States published after both were refused: nothing changed.
    after = probe.since(JOINT_STATES, probe.cursor(JOINT_STATES), 25)
    assert all(abs(m["velocity"][0]) < 1e-3 and m["position"][0] == pytest.approx(q_stopped, abs=1e-4)
               for m in after), after[:3]
    log = stop_and_read(node)
    assert log.count("jointctl: refused") == 2, log[-2000:]  # both bad values arrived and were refused


# -- (d) the master restarting ---------------------------------------------------------------

@pytest.fixture
def own_master(ros_env):
    """A master of the test's own (not the module's), so that the test can kill and restart it on its
    port (one the OS hands out to no one by itself: tests/ports.py), and a probe node on it (to see the
    node serve)."""
    env = dict(ros_env)
    masters = [Master(env, port=restart_safe_ports(1)[0])]
    probe = Probe(env)
    yield env, masters[0].port, masters, probe
    probe.close()
    for m in masters:
        m.stop()


def _serve(env):
    return subprocess.Popen([sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--controllers", "position"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_a_restarted_master_ends_the_node_with_a_clear_message(own_master):
    """rospy never re-registers with a new master: the node says so and exits, instead of running
    on invisible to the graph."""
    env, port, masters, probe = own_master
    node = _serve(env)
    try:
        probe.message(JOINT_STATES, timeout_s=60)
        masters[0].stop(kill=True)
        check_free(port)
        masters.append(Master(env, port=port))
        output, _ = node.communicate(timeout=15)
        assert node.returncode == 2
        assert "master" in output.lower() and f"{port}" in output
    finally:
        stop_process(node)


def test_when_the_master_goes_away_serve_exits_with_a_clear_message(own_master):
    env, port, masters, probe = own_master
    node = _serve(env)
    try:
        probe.message(JOINT_STATES, timeout_s=60)
        masters[0].stop(kill=True)
        try:
            output, _ = node.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            pytest.fail("serve ran on without its master")
        assert node.returncode not in (0, None)
        assert "master" in output.lower() and f"{port}" in output
    finally:
        stop_process(node)


# -- (e) a controller that fails mid-goal ----------------------------------------------------

def test_a_controller_failing_mid_goal_aborts_the_goal_and_logs_an_error(ros_env, probe):
    root = Path(__file__).resolve().parents[2]
    node = subprocess.Popen(
        [sys.executable, "-m", "tests.faulty_controllers", "serve", "one_dof", "--controllers", "trajectory",
         "--set", "controllers.joint1_position_controller.type=test_controllers/FaultyPositionController",
         "--set", "controllers.joint1_position_controller.fail_above=-0.4"],
        cwd=root, env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        probe.message(JOINT_STATES, timeout_s=60)
        done = client(ros_env, [[3.0, [-0.2]]])
        assert done["state"] == "ABORTED" and "chain failed" in done["text"] and "deliberate fault" in done["text"]
        # The node goes on: joint states still flow; with zero effort the piston falls onto its lower stop.
        q = at_rest(probe)
        assert q[-1] == pytest.approx(-1.0, abs=0.005)
    finally:
        stop_process(node)
    log = node.communicate(timeout=20)[0]
    assert "jointctl: controller joint1_position_controller failed at t =" in log, log[-2000:]

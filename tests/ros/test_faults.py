"""Faults on a real ROS graph: a client killed mid-goal, the velocity command watchdog, a NaN
command, the master restarting. Real processes throughout (rospy: one node per process)."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.ros.conftest import free_port, run, wait_for_topic

JOINT_STATES = "/one_DOF_robot/joint_states"
TRAJ_SERVER = "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory"
VEL_COMMAND = "/one_DOF_robot/joint1_velocity_controller/command"
CLIENT = str(Path(__file__).with_name("action_client.py"))

# A probe node: records joint_states (and optionally action results), optionally publishing
# velocity commands first. Prints one JSON object. Bounded: it stops by itself.
PROBE = r'''
import json, sys, time, math
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
args = json.loads(sys.argv[1])
rospy.init_node("jointctl_probe", anonymous=True)
samples, results = [], []
def on_state(msg):
    samples.append((time.time(), msg.header.stamp.to_sec(), msg.position[0], msg.velocity[0]))
rospy.Subscriber(args["states"], JointState, on_state, queue_size=100)
if args.get("results"):
    from control_msgs.msg import FollowJointTrajectoryActionResult
    rospy.Subscriber(args["results"], FollowJointTrajectoryActionResult,
                     lambda m: results.append([m.status.goal_id.id, m.status.status]), queue_size=100)
deadline = time.time() + 20
while not samples and time.time() < deadline:
    time.sleep(0.05)
print("READY", flush=True)
marks = {}
if args.get("command"):
    pub = rospy.Publisher(args["command"], Float64, queue_size=10)
    deadline = time.time() + 10
    while pub.get_num_connections() == 0 and time.time() < deadline:
        time.sleep(0.05)
    marks["start"] = time.time()
    for value in args["values"]:
        pub.publish(Float64(value))
        time.sleep(args.get("every_s", 0.05))
    marks["stop"] = time.time()
time.sleep(args.get("listen_s", 1.0))
print(json.dumps({"samples": samples, "results": results, "marks": marks}), flush=True)
'''


def probe(env, tmp_path, timeout=60, **args) -> dict:
    script = tmp_path / "probe.py"
    script.write_text(PROBE)
    result = run(env, sys.executable, str(script), json.dumps({"states": JOINT_STATES, **args}), timeout=timeout)
    return json.loads(result.stdout.strip().splitlines()[-1])


def state(env, tmp_path) -> tuple[float, float]:
    """(position, velocity) of the latest joint_states sample."""
    samples = probe(env, tmp_path, listen_s=0.2)["samples"]
    return samples[-1][2], samples[-1][3]


def client(env, points, *extra, timeout=90) -> dict:
    result = run(env, sys.executable, CLIENT, "follow", TRAJ_SERVER,
                 json.dumps({"joint_names": ["joint1"], "points": points}), *extra, timeout=timeout)
    return json.loads(result.stdout.strip().splitlines()[-1])


# -- (a) a client killed mid-goal ----------------------------------------------------------

def test_a_client_killed_mid_goal_leaves_the_server_serving(ros_env, serve, tmp_path):
    serve("one_dof", "--controllers", "trajectory", wait_topic=JOINT_STATES)
    script = tmp_path / "probe.py"
    script.write_text(PROBE)
    # Listen to every result the server sends for the whole test.
    listener = subprocess.Popen(
        [sys.executable, str(script), json.dumps({"states": JOINT_STATES, "results": f"{TRAJ_SERVER}/result",
                                                  "listen_s": 14.0})],
        env=ros_env, stdout=subprocess.PIPE, text=True)
    try:
        assert listener.stdout.readline().strip() == "READY"
        first = subprocess.Popen([sys.executable, CLIENT, "follow", TRAJ_SERVER,
                                  json.dumps({"joint_names": ["joint1"], "points": [[20.0, [-0.3]]]})],
                                 env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        # Kill it once the joint is on its way (the goal is active).
        deadline = time.monotonic() + 30
        while state(ros_env, tmp_path)[0] < -0.49 and time.monotonic() < deadline:
            pass
        assert time.monotonic() < deadline, "the first goal never moved the joint"
        first.send_signal(signal.SIGKILL)
        first.wait(10)
        # The killed client's goal (20 s long) is still running: the next goal replaces it.
        second = client(ros_env, [[1.0, [-0.4]]])
        assert second["state"] == "SUCCEEDED", second
        q, v = state(ros_env, tmp_path)
        assert q == pytest.approx(-0.4, abs=0.003)
        assert abs(v) < 0.01
        out = json.loads(listener.communicate(timeout=40)[0].strip().splitlines()[-1])
    finally:
        if listener.poll() is None:
            listener.kill()
    ids = [goal for goal, _ in out["results"]]
    assert len(ids) == 2 and len(set(ids)) == 2, out["results"]  # each goal ended exactly once
    assert [status for _, status in out["results"]] == [2, 3]  # the first PREEMPTED, the second SUCCEEDED


# -- (b) the velocity watchdog over ROS, (c) NaN refused ------------------------------------

def test_velocity_watchdog_stops_the_joint_when_commands_stop(ros_env, serve, tmp_path):
    serve("one_dof", "--controllers", "velocity", "--set", "gravity=0",
          "--set", "controllers.joint1_velocity_controller.command_timeout_s=0.2", wait_topic=JOINT_STATES)
    out = probe(ros_env, tmp_path, command=VEL_COMMAND, values=[0.05] * 20, every_s=0.05, listen_s=2.5)
    samples, stop = out["samples"], out["marks"]["stop"]
    moving = [v for t, _, _, v in samples if out["marks"]["start"] + 0.5 < t < stop]
    assert moving and min(moving) == pytest.approx(0.05, abs=0.01)  # it was streaming at 0.05 m/s
    # The last command went out at stop - 0.05 s; the watchdog holds 0.2 s of loop time after it
    # arrives. A second later (however late this busy machine delivered it) the joint is at rest.
    after = [(t - stop, q, v) for t, _, q, v in samples if t > stop + 1.0]
    assert after and all(abs(v) < 0.005 for _, _, v in after), after[:5]
    positions = [q for _, q, _ in after]
    assert max(positions) - min(positions) < 0.001


def test_without_the_watchdog_the_joint_keeps_going(ros_env, serve, tmp_path):
    serve("one_dof", "--controllers", "velocity", "--set", "gravity=0", wait_topic=JOINT_STATES)
    out = probe(ros_env, tmp_path, command=VEL_COMMAND, values=[0.05] * 10, every_s=0.05, listen_s=2.5)
    after = [v for t, _, _, v in out["samples"] if t > out["marks"]["stop"] + 1.0]
    assert after and min(after) == pytest.approx(0.05, abs=0.01)  # ros_control's behaviour


def test_a_nan_velocity_command_is_refused_and_the_joint_keeps_its_state(ros_env, serve, tmp_path):
    node = serve("one_dof", "--controllers", "velocity", "--set", "gravity=0", wait_topic=JOINT_STATES)
    # Valid commands first, on the same connection: the joint moves, then stops.
    values = [0.05] * 10 + [0.0] * 6 + [float("nan"), float("inf")]
    out = probe(ros_env, tmp_path, command=VEL_COMMAND, values=values, every_s=0.05, listen_s=1.0)
    start, stop = out["marks"]["start"], out["marks"]["stop"]
    moving = [v for t, _, _, v in out["samples"] if start + 0.2 < t < start + 0.45]
    assert moving and min(moving) == pytest.approx(0.05, abs=0.01)  # commands arrive
    after = [(q, v) for t, _, q, v in out["samples"] if t > stop]
    q_stopped = after[0][0]
    assert q_stopped > -0.5 + 0.01  # it did move
    assert all(abs(v) < 1e-3 and q == pytest.approx(q_stopped, abs=1e-4) for q, v in after)
    node.terminate()
    log = node.communicate(timeout=20)[0]
    assert log.count("jointctl: refused") == 2, log[-2000:]  # both bad values arrived and were refused


# -- (d) the master restarting ---------------------------------------------------------------

def _start_master(env, port):
    master = subprocess.Popen(["rosmaster", "--core", "-p", str(port)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 10
    while True:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return master
        except OSError:
            if time.monotonic() > deadline:
                master.kill()
                pytest.fail("the ROS master did not come up")
            time.sleep(0.05)


@pytest.fixture
def own_master(ros_env, tmp_path):
    """A master of the test's own (not the fixture's), so that the test can kill and restart it."""
    port = free_port()
    env = dict(ros_env, ROS_MASTER_URI=f"http://127.0.0.1:{port}")
    masters = [_start_master(env, port)]
    yield env, port, masters
    for m in masters:
        if m.poll() is None:
            m.terminate()
            m.wait(10)


def _serve(env):
    return subprocess.Popen([sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--controllers", "position"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _stop(process):
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5)


def test_a_restarted_master_ends_the_node_with_a_clear_message(own_master):
    """rospy never re-registers with a new master: the node says so and exits, instead of running
    on invisible to the graph."""
    env, port, masters = own_master
    node = _serve(env)
    try:
        wait_for_topic(env, JOINT_STATES)
        masters[0].send_signal(signal.SIGKILL)
        masters[0].wait(5)
        masters.append(_start_master(env, port))
        output, _ = node.communicate(timeout=15)
        assert node.returncode == 2
        assert "master" in output.lower() and f"{port}" in output
    finally:
        _stop(node)


def test_when_the_master_goes_away_serve_exits_with_a_clear_message(own_master):
    env, port, masters = own_master
    node = _serve(env)
    try:
        wait_for_topic(env, JOINT_STATES)
        masters[0].send_signal(signal.SIGKILL)
        masters[0].wait(5)
        try:
            output, _ = node.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            pytest.fail("serve ran on without its master")
        assert node.returncode not in (0, None)
        assert "master" in output.lower() and f"{port}" in output
    finally:
        _stop(node)


# -- (e) a controller that fails mid-goal ----------------------------------------------------

def test_a_controller_failing_mid_goal_aborts_the_goal_and_logs_an_error(ros_env, tmp_path):
    root = Path(__file__).resolve().parents[2]
    node = subprocess.Popen(
        [sys.executable, "-m", "tests.faulty_controllers", "serve", "one_dof", "--controllers", "trajectory",
         "--set", "controllers.joint1_position_controller.type=test_controllers/FaultyPositionController",
         "--set", "controllers.joint1_position_controller.fail_above=-0.4"],
        cwd=root, env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        wait_for_topic(ros_env, JOINT_STATES)
        done = client(ros_env, [[3.0, [-0.2]]])
        assert done["state"] == "ABORTED" and "chain failed" in done["text"] and "deliberate fault" in done["text"]
        # The node goes on: joint states still flow; with zero effort the piston fell onto its lower stop.
        time.sleep(1.0)
        q, v = state(ros_env, tmp_path)
        assert q == pytest.approx(-1.0, abs=0.005) and abs(v) < 0.01
    finally:
        _stop(node)
    log = node.communicate(timeout=20)[0]
    assert "jointctl: controller joint1_position_controller failed at t =" in log, log[-2000:]

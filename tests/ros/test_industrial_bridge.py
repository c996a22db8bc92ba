"""Section 11.5 end to end: ``jointctl controller`` (the robot in MuJoCo behind its own interpolator,
speaking simple_message) driven by ``jointctl serve --hardware industrial`` on a real ROS graph, with
real actionlib clients: the arm's pre-pose against the in-process executor, cancel as STOP, a
controller lost and back, and the two on different hosts (network namespaces)."""

from __future__ import annotations

import functools
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.ports import check_free, restart_safe_ports
from tests.ros.conftest import joint_positions, run, wait_for_topic
from tests.ros.test_across_hosts import ADDR_A, ADDR_B, _env, _in, hosts  # noqa: F401  (a fixture)
from tests.waiting import wait_until as poll_until

CLIENT = str(Path(__file__).with_name("action_client.py"))
SERVER = "/joint_trajectory_action"
PRE_POSE = [0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0]
ARM_JOINTS = [f"joint{k}" for k in range(7)]


def start_controller(env, robot: str, *extra: str, motion_port: int = 0, state_port: int = 0, netns=None):
    """``jointctl controller ROBOT`` in its own process; (process, motion port, state port)."""
    cmd = [sys.executable, "-m", "jointctl.cli", "controller", robot, "--motion-port", str(motion_port),
           "--state-port", str(state_port), *extra]
    process = subprocess.Popen(_in(netns, *cmd) if netns else cmd, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    line = process.stdout.readline()
    match = re.search(r"motion port (\d+), state port (\d+)", line)
    assert match, f"the controller did not start: {line!r} {process.stderr.read() if process.poll() else ''}"
    return process, int(match.group(1)), int(match.group(2))


def stop(process: subprocess.Popen) -> str:
    """Terminate ``process``; its stderr."""
    process.terminate()
    try:
        _, err = process.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        process.kill()
        _, err = process.communicate(timeout=5)
    return err


@pytest.fixture
def controllers():
    started = []

    def start(*args, **kwargs):
        process, motion, state = start_controller(*args, **kwargs)
        started.append(process)
        return process, motion, state

    yield start
    for process in started:
        if process.poll() is None:
            stop(process)


def serve_against(serve, robot: str, motion: int, state: int, *extra: str):
    return serve(robot, "--hardware", "industrial", "--robot-ip", "127.0.0.1", "--motion-port", str(motion),
                 "--state-port", str(state), *extra, wait_topic="/feedback_states")


def follow(env, joint_names, points, *extra, timeout=120) -> dict:
    result = run(env, sys.executable, CLIENT, "follow", SERVER,
                 json.dumps({"joint_names": joint_names, "points": points}), *extra, timeout=timeout)
    return json.loads(result.stdout.strip().splitlines()[-1])


def positions(env, topic: str = "/joint_states") -> list[float]:
    text = wait_for_topic(env, topic)
    return [float(x) for x in re.search(r"position: \[([^\]]*)\]", text).group(1).split(",")]


wait_until = functools.partial(poll_until, timeout_s=60.0, every_s=0.0)  # each poll asks the ROS graph (0.1-1 s)


def at_rest(env) -> bool:
    return "in_motion: \n  val: 0" in wait_for_topic(env, "/robot_status")


def in_process_pre_pose() -> list[float]:
    """Where the in-process executor leaves the arm: the arm7dof_pose experiment's last pose."""
    from jointctl.scenario.session import Session
    from jointctl.scenario.spec import load_scenario

    with Session(load_scenario("arm7dof_pose")) as session:
        session.run()
        return list(session.hardware.position)


@pytest.mark.slow
def test_the_arms_pre_pose_through_the_bridge_ends_where_the_in_process_executor_does(ros_env, serve,
                                                                                       controllers) -> None:
    reference = in_process_pre_pose()
    assert reference == pytest.approx(PRE_POSE, abs=0.01)  # the in-process run itself reached it
    _, motion, state = controllers(ros_env, "arm7dof")
    # The goal has no velocities: ROS-I's client (and so jointctl) would send its 10 % default speed
    # fraction and the controller would take 67 s (joint3's 2 rad at 0.03 rad/s); a speed fraction of 1
    # leaves the timing to the goal's durations, as the in-process executor's.
    serve_against(serve, "arm7dof", motion, state, "--default-speed", "1.0")
    # The chapter's timing for zeros -> pre-pose: joint3's 2 rad at half its 0.3 rad/s: 13.33 s.
    done = follow(ros_env, ARM_JOINTS, [[0.02, [0.0] * 7], [13.35, PRE_POSE]])
    assert done["state"] == "SUCCEEDED", done  # only once the controller said the robot is at rest
    bridged = positions(ros_env)
    assert bridged == pytest.approx(reference, abs=0.01)
    assert "in_motion: \n  val: 0" in wait_for_topic(ros_env, "/robot_status")


def test_a_cancel_over_ros_is_a_stop_at_the_controller(ros_env, serve, controllers) -> None:
    # Big-endian (the _bswap drivers), so that both processes' --big-endian is used; the byte orders
    # themselves are compared in tests/industrial/test_controller.py.
    process, motion, state = controllers(ros_env, "one_dof", "--big-endian")
    serve_against(serve, "one_dof", motion, state, "--big-endian")
    done = follow(ros_env, ["joint1"], [[6.0, [-0.1]]], "--cancel-after", "2.0")
    assert done["state"] == "PREEMPTED", done
    wait_until(lambda: at_rest(ros_env), "the controller to report the robot at rest")
    # 20 consecutive reports (0.4 s at 50 Hz): still, within the servo's settling tail once STATUS
    # says every joint is slower than 1 mm/s; a robot still going to -0.1 m would move some cm.
    seen = joint_positions(ros_env, "/joint_states", 20)
    assert max(seen) - min(seen) < 1e-3
    # The 6 s cubic from -0.5 m is canceled 2 s after the client sent it (about -0.40 m): 0.5 s into
    # it, it has moved 8 mm, and only 4.5 s into it would it reach -0.15 m. So the goal may start
    # 1.5 s late and the stop take 2.5 s on its way.
    assert -0.492 < seen[0] < -0.15  # moved, and stopped well short of -0.1 m
    assert "STOP: decelerating to rest, queue cleared" in stop(process)


def test_a_controller_lost_mid_goal_aborts_it_and_is_found_again(ros_env, serve, controllers) -> None:
    # Ports the OS hands out to no one by itself (tests/ports.py): still free for the restart below,
    # where one the OS had picked could meanwhile be any connection's local port.
    motion, state = restart_safe_ports(2)
    process, _, _ = controllers(ros_env, "one_dof", motion_port=motion, state_port=state)
    serve_against(serve, "one_dof", motion, state)
    client = subprocess.Popen([sys.executable, CLIENT, "follow", SERVER,
                               json.dumps({"joint_names": ["joint1"], "points": [[8.0, [-0.1]]]})],
                              env=ros_env, stdout=subprocess.PIPE, text=True)
    wait_until(lambda: positions(ros_env)[0] > -0.48, "the goal moving the robot")
    process.kill()  # the controller dies mid-goal
    process.wait(10)  # and is gone, its sockets with it
    out, _ = client.communicate(timeout=60)
    done = json.loads(out.strip().splitlines()[-1])
    assert done["state"] == "ABORTED", done
    assert "the hardware cannot be commanded" in done["text"]
    assert "127.0.0.1" in done["text"]
    # Back, on the same ports.
    check_free(motion, state)
    controllers(ros_env, "one_dof", motion_port=motion, state_port=state)
    # The node reconnects by itself: the new controller's state (at its start, -0.5 m) is relayed. Goals
    # are refused until the loop has seen both connections open again; then one succeeds.
    wait_until(lambda: positions(ros_env)[0] == pytest.approx(-0.5, abs=1e-3),
               "the restarted controller's state relayed")

    def succeeded():
        done = follow(ros_env, ["joint1"], [[2.0, [-0.3]]])
        assert done["state"] in ("SUCCEEDED", "REJECTED"), done
        return done["state"] == "SUCCEEDED"

    wait_until(succeeded, "a goal to succeed on the restarted controller")
    assert positions(ros_env)[0] == pytest.approx(-0.3, abs=0.01)


def test_the_controller_and_the_ros_side_on_two_hosts(hosts, tmp_path) -> None:  # noqa: F811
    """The controller on host A (10.200.0.1), master, node and client on host B (10.200.0.2)."""
    ns_a, ns_b = hosts
    env_b = _env(tmp_path, ADDR_B)
    env_b["ROS_MASTER_URI"] = f"http://{ADDR_B}:11311"
    processes, logs = [], {}
    try:
        controller, motion, state = start_controller(_env(tmp_path, ADDR_A), "one_dof", netns=ns_a)
        processes.append(controller)
        processes.append(subprocess.Popen(_in(ns_b, "rosmaster", "--core", "-p", "11311"), env=env_b,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        processes.append(subprocess.Popen(
            _in(ns_b, sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--hardware", "industrial",
                "--robot-ip", ADDR_A, "--motion-port", str(motion), "--state-port", str(state)),
            env=env_b, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True))
        deadline = time.monotonic() + 40
        while True:
            echo = subprocess.run(_in(ns_b, "rostopic", "echo", "-n", "1", "/feedback_states"), env=env_b,
                                  capture_output=True, text=True, timeout=15)
            if echo.returncode == 0 and "-0.5" in echo.stdout:
                break
            assert time.monotonic() < deadline, f"no state from host A: {echo.stderr[-500:]}"
            time.sleep(0.5)
        goal = {"joint_names": ["joint1"], "points": [[1.0, [-0.4]], [2.0, [-0.3]]]}
        result = subprocess.run(_in(ns_b, sys.executable, CLIENT, "follow", SERVER, json.dumps(goal)),
                                env=env_b, capture_output=True, text=True, timeout=90)
        done = json.loads(result.stdout.strip().splitlines()[-1])
        assert done["state"] == "SUCCEEDED", done
    finally:
        for process in reversed(processes):
            logs[process.pid] = stop(process) if process.poll() is None else ""
    assert f"motion client {ADDR_B}:" in logs[controller.pid]  # the client came from the other host


def test_goals_downloaded_whole_with_motion_download(ros_env, serve, controllers) -> None:
    process, motion, state = controllers(ros_env, "one_dof")
    serve_against(serve, "one_dof", motion, state, "--motion", "download")
    done = follow(ros_env, ["joint1"], [[1.0, [-0.4]], [2.0, [-0.3]]])
    assert done["state"] == "SUCCEEDED", done
    assert positions(ros_env)[0] == pytest.approx(-0.3, abs=0.01)
    done = follow(ros_env, ["joint1"], [[4.0, [-0.1]]], "--cancel-after", "1.5")
    assert done["state"] == "PREEMPTED", done
    log = stop(process)
    assert "STOP: decelerating to rest" in log and "refused" not in log

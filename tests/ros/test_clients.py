"""The chapter's clients as their own processes against jointctl serve on a real ROS graph."""

from __future__ import annotations

import os
import pty
import select
import signal
import subprocess
import sys
import time

import pytest

from tests.ros.conftest import joint_positions, run, wait_for_topic, wait_until

ONE_DOF_STATES = "/one_DOF_robot/joint_states"
ARM_STATES = "/arm7dof/joint_states"
JOINTCTL = (sys.executable, "-m", "jointctl.cli")


class Terminal:
    """A process on a pseudo-terminal: read what it prints, type answers."""

    def __init__(self, env, *args: str) -> None:
        self.master, slave = pty.openpty()
        self.process = subprocess.Popen(list(args), env=env, stdin=slave, stdout=slave, stderr=slave,
                                        close_fds=True, start_new_session=True)
        os.close(slave)
        self.text = ""

    def expect(self, needle: str, timeout_s: float = 20.0) -> str:
        deadline = time.monotonic() + timeout_s
        while needle not in self.text:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"{needle!r} not printed within {timeout_s} s; got {self.text!r}")
            ready, _, _ = select.select([self.master], [], [], left)
            if ready:
                try:
                    chunk = os.read(self.master, 4096)
                except OSError:  # the process ended
                    chunk = b""
                if not chunk:
                    raise AssertionError(f"{needle!r} never printed; got {self.text!r}")
                self.text += chunk.decode(errors="replace")
        return self.text

    def type(self, line: str) -> None:
        os.write(self.master, (line + "\n").encode())

    def stop(self) -> int:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        try:
            status = self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            status = self.process.wait(5)
        while select.select([self.master], [], [], 0.2)[0]:  # what it printed on the way out
            try:
                chunk = os.read(self.master, 4096)
            except OSError:
                break
            if not chunk:
                break
            self.text += chunk.decode(errors="replace")
        os.close(self.master)
        return status


def test_the_sine_commander_drives_the_position_controller(ros_env, serve, probe):
    serve("one_dof", "--controllers", "position", wait_topic=ONE_DOF_STATES)
    commander = Terminal(ros_env, *JOINTCTL, "sine")
    try:
        commander.expect("enter displacement amplitude: ")
        commander.type("big")
        commander.expect("not a number")
        commander.expect("enter displacement amplitude: ")  # asked again
        commander.type("0.1")
        commander.expect("enter freq (in Hz): ")
        commander.type("1")
        commander.expect("publishing")
        # The loop's transient decays at ζ·ωn = 5/s: a second of loop time after the sine reaches the
        # loop's set point, less than 1 % of it is left.
        state = "/one_DOF_robot/joint1_position_controller/state"
        mark = probe.cursor(state)
        moving = wait_until(lambda: [m["header"]["stamp"]["s"] for m in probe.since(state, mark)
                                     if m["set_point"] != -0.5], "the sine to reach the loop")
        wait_until(lambda: probe.since(state, mark)[-1]["header"]["stamp"]["s"] > moving[0] + 1.0,
                   "a second of loop time of the sine")
        q = joint_positions(ros_env, ONE_DOF_STATES, 75)  # 1.5 s at 50 Hz: a full period and a half
        amplitude = (max(q) - min(q)) / 2
        centre = (max(q) + min(q)) / 2
        assert amplitude == pytest.approx(0.1, abs=0.02)
        assert centre == pytest.approx(-0.5, abs=0.03)
        # The commanded sine is on the wire too.
        command = float(wait_for_topic(ros_env, "/one_DOF_robot/joint1_position_controller/command")
                        .split("data:")[1].split()[0])
        assert -0.6 - 1e-9 <= command <= -0.4 + 1e-9
    finally:
        status = commander.stop()
    assert status == 0  # SIGTERM ends it cleanly
    assert "stopped after" in commander.text


def test_the_example_trajectory_client_succeeds(ros_env, serve):
    serve("one_dof", "--controllers", "trajectory", wait_topic=ONE_DOF_STATES)
    result = run(ros_env, *JOINTCTL, "traj-client", "--seed", "7", timeout=60)
    out = result.stdout
    assert "result: SUCCEEDED, rtn_status 0" in out
    count = int(out.split("feedback messages: ")[1].split()[0])
    assert count > 10


def test_the_playfile_client_over_ros(ros_env, serve, tmp_path):
    serve("arm7dof", "--controllers", "trajectory", wait_topic=ARM_STATES)
    path = tmp_path / "short.csv"
    path.write_text("0, 0, 0, 0, 0.2, 0.2, 0.2\n0, 0, 0, 0, 0.3, 0.1, 0.3\n")
    result = run(ros_env, *JOINTCTL, "play", str(path), "--ros", timeout=60)
    assert "goal succeeded" in result.stdout
    final = result.stdout.split("final joint angles [")[1].split("]")[0]
    angles = [float(v) for v in final.split(",")]
    assert angles[4:] == pytest.approx([0.3, 0.1, 0.3], abs=0.05)
    # The arm holds there, as its joint states tell.
    for name, expected in (("field.position4", 0.3), ("field.position6", 0.3)):
        assert joint_positions(ros_env, ARM_STATES, 3, name)[-1] == pytest.approx(expected, abs=0.05)


def test_the_playfile_client_refuses_a_bad_row_before_anything_moves(ros_env, serve, tmp_path):
    serve("arm7dof", "--controllers", "trajectory", wait_topic=ARM_STATES)
    path = tmp_path / "bad.csv"
    path.write_text("0, 0, 0, 0, 0.2, 0.2, 0.2\n0, 0, 0, 0, 0.2, 0.2\n")
    result = run(ros_env, *JOINTCTL, "play", str(path), "--ros", timeout=60, check=False)
    assert result.returncode == 2
    assert "line 2" in result.stderr


def test_clients_without_a_master_fail_with_one_line(tmp_path):
    from tests.ros.conftest import free_port

    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{free_port()}", ROS_HOME=str(tmp_path))
    for args in (("traj-client",), ("sine",), ("play", "robots/arm7dof/paths/forward.csv", "--ros")):
        result = run(env, *JOINTCTL, *args, timeout=20, check=False)
        assert result.returncode == 2, args
        assert "no ROS master" in result.stderr


def test_the_prompter_over_ros(ros_env, serve):
    # Twice the wall clock's pace: the pre-pose goal is the book's 13.3 s of loop time.
    serve("arm7dof", "--controllers", "trajectory", "--speed", "2", wait_topic=ARM_STATES)
    prompter = Terminal(ros_env, *JOINTCTL, "prompt", "arm7dof", "--ros")
    try:
        prompter.expect("moving to the pre-pose [0.0000, 1.0000, 0.0000, -2.0000, 0.0000, 1.0000, 0.0000]")
        prompter.expect("enter jnt number (0 through 6; negative to quit): ", timeout_s=40)
        assert "pre-pose: succeeded" in prompter.text
        prompter.type("6")
        prompter.expect("enter angle command: ")
        prompter.type("9")  # beyond the joint's range: refused, nothing sent
        prompter.expect("beyond joint6's limits")
        prompter.expect("enter jnt number", timeout_s=5)
        prompter.type("6")
        prompter.expect("enter angle command: ")
        prompter.type("0.3")
        prompter.expect("joint 6 to 0.3: succeeded", timeout_s=20)
        prompter.expect("enter jnt number", timeout_s=5)
        prompter.type("-1")
        prompter.expect("quitting")
        assert prompter.process.wait(10) == 0
    finally:
        prompter.stop()
    q = [joint_positions(ros_env, ARM_STATES, 2, f"field.position{i}")[-1] for i in range(7)]
    assert q == pytest.approx([0, 1, 0, -2, 0, 1, 0.3], abs=0.05)

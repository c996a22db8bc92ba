"""The chapter's 7-DOF clients: the prompter driven through a pseudo-terminal as a user types,
the playfile client on the shipped paths and on bad files (refused before anything moves)."""

from __future__ import annotations

import io
import math
import os
import re
import select
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from jointctl.errors import JointCtlError
from jointctl.paths import robots_dir
from jointctl.clients.arm import (
    ANGLE_PROMPT,
    PRE_POSE,
    GoalOutcome,
    InProcessGoalSender,
    InputRefused,
    joint_prompt,
    move_joint,
    parse_angle,
    parse_joint_number,
    play_command,
    play_path_file,
    read_path_file,
    run_prompter,
)
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.messages import JointSpec

JOINTCTL = [sys.executable, "-m", "jointctl.cli"]
PATHS = robots_dir() / "arm7dof" / "paths"
JOINT_PROMPT = "enter jnt number (0 through 6; negative to quit): "
REACHED = re.compile(r"reached \[([^\]]*)\]")
FINAL = re.compile(r"final joint angles \[([^\]]*)\]")


def angles(pattern: re.Pattern, text: str) -> list[float]:
    found = pattern.findall(text)
    assert found, text
    return [float(v) for v in found[-1].split(",")]


def jointctl(*args, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([*JOINTCTL, *map(str, args)], capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, MPLBACKEND="Agg"), stdin=subprocess.DEVNULL)


def assert_one_line_error(result: subprocess.CompletedProcess, *fragments: str) -> None:
    assert result.returncode == 2, (result.stdout, result.stderr)
    assert "Traceback" not in result.stderr + result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("jointctl: error: ")
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


# -- the prompter through a pseudo-terminal ---------------------------------------------------

class Terminal:
    """A process whose stdin, stdout and stderr are a pseudo-terminal, read until a string appears."""

    def __init__(self, *args: str) -> None:
        master, slave = os.openpty()
        env = dict(os.environ, TERM="dumb", MPLBACKEND="Agg")
        self.process = subprocess.Popen([*JOINTCTL, *args], stdin=slave, stdout=slave, stderr=slave,
                                        env=env, close_fds=True, start_new_session=True)
        os.close(slave)
        self.fd = master
        self.buffer = ""
        self.transcript = ""

    def _read(self, timeout_s: float) -> bool:
        ready, _, _ = select.select([self.fd], [], [], timeout_s)
        if not ready:
            return False
        try:
            data = os.read(self.fd, 4096)
        except OSError:  # EIO: the process closed the terminal
            data = b""
        if not data:
            raise EOFError
        text = data.decode(errors="replace").replace("\r\n", "\n")
        self.buffer += text
        self.transcript += text
        return True

    def expect(self, text: str, timeout_s: float = 60.0) -> str:
        """Everything before ``text`` (which is consumed); fails after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while text not in self.buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                pytest.fail(f"no {text!r} within {timeout_s} s; the terminal showed:\n{self.transcript}")
            try:
                self._read(remaining)
            except EOFError:
                pytest.fail(f"the process ended before {text!r}; the terminal showed:\n{self.transcript}")
        before, _, self.buffer = self.buffer.partition(text)
        return before

    def send(self, text: str) -> None:
        os.write(self.fd, text.encode())

    def answer(self, line: str, then: str = JOINT_PROMPT) -> str:
        """Type ``line`` and Enter; return what the program printed before the ``then`` prompt."""
        self.send(line + "\n")
        return self.expect(then)

    def finish(self, timeout_s: float = 30.0) -> int:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                self._read(0.1)
            except EOFError:
                break
        code = self.process.wait(timeout=max(0.1, deadline - time.monotonic()))
        os.close(self.fd)
        return code

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()


@pytest.fixture
def terminal():
    started = []

    def start(*args: str) -> Terminal:
        t = Terminal(*args)
        started.append(t)
        return t

    yield start
    for t in started:
        t.kill()


def test_prompter_session_moves_one_joint_and_refuses_bad_answers(terminal):
    t = terminal("prompt", "arm7dof")
    before = t.expect(JOINT_PROMPT)
    assert "pre-pose: succeeded" in before
    assert angles(REACHED, before) == pytest.approx(PRE_POSE, abs=0.01)

    t.answer("4", then=ANGLE_PROMPT)
    reply = t.answer("0.5")
    assert "joint 4 to 0.5: succeeded" in reply
    reached = angles(REACHED, reply)
    assert reached[4] == pytest.approx(0.5, abs=0.01)
    others = [q for k, q in enumerate(reached) if k != 4]
    assert others == pytest.approx([q for k, q in enumerate(PRE_POSE) if k != 4], abs=0.01)

    assert "not a number: 'abc'" in t.answer("abc")
    assert "no joint 9" in t.answer("9")
    assert "whole number 0 through 6, got 3.5" in t.answer("3.5")
    t.answer("3", then=ANGLE_PROMPT)
    assert "angle 3.0 is beyond joint3's limits [-3.1, 2.7]; nothing sent" in t.answer("3.0")
    t.answer("3", then=ANGLE_PROMPT)
    assert "not a number: 'up'" in t.answer("up")

    t.send("-1\n")
    assert t.finish() == 0
    assert "quitting" in t.transcript
    assert "Traceback" not in t.transcript
    assert t.transcript.count("succeeded") == 2  # the pre-pose and joint 4: nothing else moved


@pytest.mark.parametrize("typed", ["", "2\n"], ids=["at-the-joint-prompt", "at-the-angle-prompt"])
def test_prompter_ends_cleanly_at_end_of_input(terminal, typed):
    t = terminal("prompt", "arm7dof")
    t.expect(JOINT_PROMPT)
    if typed:
        t.answer(typed.strip(), then=ANGLE_PROMPT)
    t.send("\x04")  # Ctrl-D on an empty line: end of input
    assert t.finish() == 0
    assert "end of input: quitting" in t.transcript
    assert "Traceback" not in t.transcript


# -- the prompter's logic, without a robot ----------------------------------------------------

SPEC3 = JointSpec("joint3", -3.1, 2.7, 0.3)


@pytest.mark.parametrize(("text", "expected"), [("0", 0), (" 6 ", 6), ("4.0", 4), ("-1", None), ("-0.5", None)])
def test_joint_numbers(text, expected):
    assert parse_joint_number(text, 7) == expected


@pytest.mark.parametrize(("text", "fragment"), [
    ("abc", "not a number: 'abc'"), ("", "enter a joint number"), ("7", "no joint 7"), ("9", "no joint 9"),
    ("3.5", "whole number"), ("nan", "whole number"), ("inf", "whole number")])
def test_bad_joint_numbers(text, fragment):
    with pytest.raises(InputRefused, match=re.escape(fragment)):
        parse_joint_number(text, 7)


def test_angles_within_the_joint_range():
    assert parse_angle("2.7", SPEC3) == 2.7
    assert parse_angle("-3.1", SPEC3) == -3.1
    for text, fragment in [("3.0", "beyond joint3's limits [-3.1, 2.7]"), ("-3.2", "beyond"),
                           ("x", "not a number"), ("nan", "finite"), ("-inf", "finite")]:
        with pytest.raises(InputRefused, match=re.escape(fragment)):
            parse_angle(text, SPEC3)


class FakeSender:
    """A GoalSender without a robot: it records what the client plans and sends. By default each goal
    succeeds at its last point. ``refuse``: joints whose goals are refused before anything moves (the
    executor's InvalidTrajectory, or a REJECTED over ROS). ``reach``: the fraction of each move from
    where the joints are to the goal's last point that is travelled, after which the goal ends aborted
    (a blocked joint, a fault) with ``error``."""

    joint_names = tuple(f"joint{k}" for k in range(7))
    joint_specs = tuple(JointSpec(f"joint{k}", -3.0, 2.7, 0.3) for k in range(7))
    trace_path = None

    def __init__(self, *, refuse=(), reach: float = 1.0, error: str = "blocked") -> None:
        self.q = [0.0] * 7
        self.plans = []
        self.sent = []
        self.refuse, self.reach, self.error = set(refuse), reach, error

    def current_positions(self):
        return tuple(self.q)

    def plan(self, path, *, timing="chapter", joint_names=None):
        self.plans.append((timing, tuple(joint_names or self.joint_names), [list(r) for r in path]))
        return self.plans[-1]

    def send(self, trajectory):
        _, names, path = trajectory
        refused = [name for name in names if name in self.refuse]
        if refused:
            raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL, "the joint is locked", joint=refused[0])
        self.sent.append(trajectory)
        for name, q in zip(names, path[-1]):
            k = self.joint_names.index(name)
            self.q[k] += self.reach * (q - self.q[k])
        if self.reach == 1.0:
            return GoalOutcome("succeeded", "", 1.0, tuple(self.q))
        return GoalOutcome("aborted", self.error, 1.0, tuple(self.q))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass


def test_prompter_logic_through_the_goal_sender_protocol():
    sender = FakeSender()
    answers = iter(["5", "1.25", "7", "2", "-2.5", "-1"])
    asked = []

    def ask(prompt):
        asked.append(prompt)
        return next(answers)

    out = io.StringIO()
    assert run_prompter(sender, ask=ask, out=out) == 0
    assert sender.plans == [("chapter", sender.joint_names, [list(PRE_POSE)]),
                            ("chapter", ("joint5",), [[1.25]]),
                            ("chapter", ("joint2",), [[-2.5]])]
    assert asked == [joint_prompt(7), ANGLE_PROMPT, joint_prompt(7), joint_prompt(7), ANGLE_PROMPT, joint_prompt(7)]
    assert "no joint 7" in out.getvalue()
    assert angles(REACHED, out.getvalue()) == pytest.approx([0, 1, -2.5, -2, 0, 1.25, 0])


def test_prompter_says_refused_moves_nothing_and_asks_again():
    # joint5's goals are refused (nothing moves): one "refused:" line naming the reason, and the next
    # question; joint2 then moves as asked.
    sender = FakeSender(refuse={"joint5"})
    answers = iter(["5", "1.25", "2", "-2.5", "-1"])
    out = io.StringIO()
    assert run_prompter(sender, ask=lambda _prompt: next(answers), out=out, pre_pose=None) == 0
    lines = out.getvalue().splitlines()
    refused = [line for line in lines if line.startswith("refused: ")]
    reason = InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL, "the joint is locked", joint="joint5")
    assert refused == [f"refused: {reason}"], lines
    assert [names for _, names, _ in sender.sent] == [("joint2",)]
    assert sender.q == [0.0, 0.0, -2.5, 0.0, 0.0, 0.0, 0.0]
    assert angles(REACHED, out.getvalue()) == pytest.approx(sender.q)


@pytest.mark.parametrize("start, angle, reach, word", [(0.0, 1.25, 0.8, "short of"), (0.0, -2.5, 0.9, "short of"),
                                                        (0.0, 1.25, 1.2, "past"), (0.5, -1.0, 1.1, "past")])
def test_prompter_notes_a_joint_that_stops_short_of_or_past_its_command(start, angle, reach, word):
    # The joint ends at start + reach (angle - start): |miss| = |1 - reach| |angle - start| rad from the command,
    # before it for reach < 1, beyond it for reach > 1, whichever way it moved.
    sender = FakeSender(reach=reach)
    sender.q[5] = start
    answers = iter(["5", str(angle), "-1"])
    out = io.StringIO()
    assert run_prompter(sender, ask=lambda _prompt: next(answers), out=out, pre_pose=None) == 0
    miss = abs(1.0 - reach) * abs(angle - start)
    assert miss > 0.01  # beyond the prompter's REACH_TOLERANCE: the note is due
    assert f"joint 5 to {angle:g}: aborted in 1.00 s (blocked)" in out.getvalue()
    assert f"note: joint5 stopped {miss:.3f} rad {word} {angle:g} (blocked or still settling?)" in out.getvalue()


def test_prompter_adds_no_note_within_its_tolerance():
    sender = FakeSender(reach=0.995)  # 0.00625 rad short of 1.25: within REACH_TOLERANCE (0.01 rad)
    answers = iter(["5", "1.25", "-1"])
    out = io.StringIO()
    run_prompter(sender, ask=lambda _prompt: next(answers), out=out, pre_pose=None)
    assert "note:" not in out.getvalue()


# -- the playfile client ----------------------------------------------------------------------

@pytest.mark.parametrize("reach, status", [(1.0, 0), (0.5, 1)])
def test_play_exits_1_when_the_goal_does_not_succeed(tmp_path, capsys, reach, status):
    path = tmp_path / "path.csv"
    path.write_text("0, 1, 0, -2, 0, 1, 0\n")
    sender = FakeSender(reach=reach, error="the controller refused point 0")
    assert play_command(sender, path) == status
    printed = capsys.readouterr().out
    if status:
        assert "goal aborted in 1.00 s (the controller refused point 0)" in printed
    else:
        assert "goal succeeded in 1.00 s" in printed
    assert angles(FINAL, printed) == pytest.approx([reach * q for q in PRE_POSE])


@pytest.mark.parametrize("reach, status", [(1.0, 0), (0.5, 1)])
def test_jointctl_play_exits_with_plays_status(tmp_path, monkeypatch, capsys, reach, status):
    # The command line's exit status is play's: 1 when the goal did not succeed (the sender it opens replaced).
    import jointctl.cli.clients as cli_clients
    from jointctl.cli import main

    path = tmp_path / "path.csv"
    path.write_text("0, 1, 0, -2, 0, 1, 0\n")
    monkeypatch.setattr(cli_clients, "_sender", lambda _args: FakeSender(reach=reach))
    assert main(["play", str(path)]) == status
    assert ("goal succeeded" if status == 0 else "goal aborted") in capsys.readouterr().out

def test_shipped_paths_are_within_limits_and_reverse_each_other():
    with InProcessGoalSender.open() as sender:
        specs = sender.joint_specs
    forward = read_path_file(PATHS / "forward.csv", specs)
    reverse = read_path_file(PATHS / "reverse.csv", specs)
    assert 6 <= len(forward) <= 10
    assert reverse == forward[::-1]
    assert forward[0] == list(PRE_POSE)


def test_play_forward_path_from_the_command_line(tmp_path):
    result = jointctl("play", PATHS / "forward.csv", "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    assert "goal succeeded in" in result.stdout
    last = np.loadtxt(PATHS / "forward.csv", delimiter=",", comments="#")[-1]
    assert angles(FINAL, result.stdout) == pytest.approx(last, abs=0.01)
    duration = float(re.search(r"succeeded in ([0-9.]+) s", result.stdout).group(1))
    trace = tmp_path / "trace.csv"
    assert f"wrote {trace}" in result.stderr
    header = trace.open().readline().strip().split(",")
    assert header[0] == "time_s" and "joint6.position" in header
    times = np.loadtxt(trace, delimiter=",", skiprows=1, usecols=0)
    assert times[-1] == pytest.approx(duration, abs=0.02)


def test_play_reverse_path_with_ruckig_timing():
    with InProcessGoalSender.open() as sender:
        outcome = play_path_file(sender, PATHS / "reverse.csv", timing="ruckig")
        assert outcome.succeeded, outcome
        assert outcome.positions == pytest.approx(PRE_POSE, abs=0.01)
        assert outcome.duration_s == pytest.approx(sender.loop.time_s, abs=1e-9)


def test_play_paces_to_the_wall_clock_with_realtime(tmp_path):
    path = tmp_path / "short.csv"
    path.write_text("0, 0, 0, 0, 0.2, 0, 0\n")  # joint4 at 0.2 rad/s: 1 s, plus 0.1 s lead
    started = time.monotonic()
    result = jointctl("play", path, "--realtime", "--speed", "4")
    assert result.returncode == 0, result.stderr
    wall_s = time.monotonic() - started
    assert wall_s >= 1.1 / 4
    assert angles(FINAL, result.stdout)[4] == pytest.approx(0.2, abs=0.01)


BAD_FILES = [
    ("count.csv", "# two good rows, then six values\n0,0,0,0,0,0,0\n\n0,1,0,-2,0,1,0\n0,1,0,-2,0,1\n",
     ["line 5", "needs 7 comma-separated joint angles, found 6", "'0,1,0,-2,0,1'"]),
    ("word.csv", "0,0,0,0,0,0,0\n0,1,0,-2,abc,1,0\n", ["line 2", "joint4 angle is not a number", "'abc'"]),
    ("nan.csv", "0,0,0,0,0,0,0\n\n# NaN is refused\n0,1,nan,-2,0,1,0\n", ["line 4", "joint2", "finite", "'nan'"]),
    ("limit.csv", "0,1,0,-2,0,1,0\n0,1,0,3.0,0,1,0\n",
     ["line 2", "joint3 angle is beyond its limits [-3.1, 2.7]", "3.0"]),
    ("empty.csv", "# only a comment\n\n", ["no poses"]),
]


@pytest.mark.parametrize(("name", "text", "fragments"), BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_play_refuses_a_bad_file_with_one_line(tmp_path, name, text, fragments):
    path = tmp_path / name
    path.write_text(text)
    result = jointctl("play", path)
    assert_one_line_error(result, str(path), *fragments)
    assert result.stdout == ""  # nothing was sent


def test_play_refuses_a_missing_file_and_bad_options(tmp_path):
    assert_one_line_error(jointctl("play", tmp_path / "none.csv"), "none.csv", "cannot read the path file")
    assert_one_line_error(jointctl("play", PATHS / "forward.csv", "--speed", "0"), "--speed")
    assert jointctl("play", PATHS / "forward.csv", "--timing", "fast").returncode == 2
    assert jointctl("prompt", "arm9dof").returncode == 2


@pytest.mark.parametrize(("name", "text", "fragments"), BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_a_bad_file_moves_nothing(tmp_path, name, text, fragments):
    path = tmp_path / name
    path.write_text(text)
    with InProcessGoalSender.open() as sender:
        move_joint(sender, 4, 0.3)  # away from the start, so "unchanged" means something
        cycle, served = sender.loop.cycle, sender.executor.goals_served
        positions = list(sender.session.hardware.position)
        desired = list(sender.executor.desired)
        with pytest.raises(JointCtlError) as refused:
            play_path_file(sender, path)
        for fragment in fragments:
            assert fragment in str(refused.value)
        assert sender.loop.cycle == cycle
        assert sender.executor.goals_served == served
        assert list(sender.session.hardware.position) == positions
        assert list(sender.executor.desired) == desired
        assert math.isclose(positions[sender.hardware.joint_index("joint4")], 0.3, abs_tol=0.01)


def test_unknown_timing_is_refused_before_reading():
    with pytest.raises(JointCtlError, match="timing"):
        play_path_file(FakeSender(), Path("unused.csv"), timing="fast")

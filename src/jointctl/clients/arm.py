"""The chapter's two 7-DOF trajectory clients: the prompter and the playfile client.

* :func:`run_prompter` (``jointctl prompt arm7dof``): moves the arm to the pre-pose
  ``[0, 1, 0, -2, 0, 1, 0]``, then asks for a joint number and an angle, again and
  again, and moves that one joint with a two-point trajectory.
* :func:`play_path_file` (``jointctl play PATHFILE``): reads a CSV path file (seven
  joint angles a line, no times), checks every row before anything moves, prepends
  the current pose, times the path and executes it.

The client logic talks to the robot only through a :class:`GoalSender`: the joint
names and limits, the current joint angles, timing a path and sending a trajectory
until it ends. :class:`InProcessGoalSender` is the simulation in this process: it
submits to the scenario's :class:`~jointctl.trajectory.executor.TrajectoryExecutor`
and runs the 1 kHz loop (simulated time, or paced to the wall clock) until the goal
ends. :class:`~jointctl.ros.arm_client.RosGoalSender` (``--ros``) implements the same protocol as an actionlib
client of a served arm, timing paths with :mod:`jointctl.trajectory.timing` from the
robot description's limits.

Path timing (both clients): ``"chapter"`` is the chapter's "stuff trajectory" rule
(each segment as long as its slowest joint needs at half its velocity limit, at
least 20 ms); ``"ruckig"`` is jointctl's jerk-limited profile within the same
velocity limits. Angles are in rad; times in s.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TextIO

from jointctl.errors import JointCtlError
from jointctl.trajectory.messages import JointSpec, JointTrajectory
from jointctl.trajectory.timing import PATH_TIMINGS

#: The built-in scenario the in-process clients drive, and its trajectory executor.
SCENARIO = "arm7dof_streamer"
EXECUTOR = "arm7dof_trajectory_controller"
#: The prompter's first move (rad), the chapter's pre-pose.
PRE_POSE = (0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0)
TIMINGS = PATH_TIMINGS
ANGLE_PROMPT = "enter angle command: "
#: Extra loop time (s) allowed after a goal's last point and its goal time before it is canceled.
GOAL_MARGIN_S = 2.0
#: The prompter adds a note when the moved joint ends farther than this from its command (rad).
REACH_TOLERANCE = 0.01


def joint_prompt(n_joints: int) -> str:
    """The prompter's first question; for the 7-DOF arm
    ``enter jnt number (0 through 6; negative to quit): ``."""
    return f"enter jnt number (0 through {n_joints - 1}; negative to quit): "


# -- delivery ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class GoalOutcome:
    """How a sent trajectory ended: its status (``"succeeded"``, ``"aborted"``, ...), the
    error text (empty on success), the time from sending to the end (s) and the measured
    joint angles then (rad, in ``joint_names`` order)."""

    status: str
    error: str
    duration_s: float
    positions: tuple[float, ...]

    @property
    def succeeded(self) -> bool:
        return self.status == "succeeded"


class GoalSender(Protocol):
    """How the clients reach the robot (in-process here; over ROS later)."""

    #: The controlled joints, in the order of every position vector below.
    joint_names: tuple[str, ...]
    #: Their limits (range and velocity) from the robot model.
    joint_specs: tuple[JointSpec, ...]

    def current_positions(self) -> tuple[float, ...]:
        """The measured joint angles now."""
        ...

    def plan(self, path: Sequence[Sequence[float]], *, timing: str = "chapter",
             joint_names: Sequence[str] | None = None) -> JointTrajectory:
        """A trajectory from the current pose through ``path`` (rows of ``joint_names``,
        default all joints), timed by ``timing`` within the velocity limits."""
        ...

    def send(self, trajectory: JointTrajectory) -> GoalOutcome:
        """Send ``trajectory`` and block until it ends. Raises
        :class:`~jointctl.trajectory.errors.InvalidTrajectory` when it is refused."""
        ...


class InProcessGoalSender:
    """A :class:`GoalSender` on a :class:`~jointctl.scenario.session.Session` in this process.

    :meth:`send` submits to the executor and runs the session's loop until the goal
    ends (the loop stops on the cycle the result arrives); between goals the loop, and
    so simulated time, stands still. A goal still running ``GOAL_MARGIN_S`` after its
    last point plus the executor's ``goal_time_s`` is canceled (a controlled stop).
    """

    def __init__(self, session, controller: str = EXECUTOR) -> None:
        self.session = session
        self.loop = session.loop
        self.hardware = session.hardware
        self.executor = session.manager.controller(controller)
        self.joint_names = tuple(self.executor.joint_names)
        self.joint_specs = tuple(self.executor.specs)
        self._index = [self.hardware.joint_index(j) for j in self.joint_names]

    @classmethod
    def open(cls, *, realtime: bool = False, speed: float = 1.0, out_dir: str | Path | None = None,
             scenario: str = SCENARIO, controller: str = EXECUTOR) -> InProcessGoalSender:
        """Build the scenario's session (nothing moves yet) and a sender on it; ``close()`` it."""
        from jointctl.scenario.session import Session
        from jointctl.scenario.spec import load_scenario

        session = Session(load_scenario(scenario), out_dir=out_dir, realtime=realtime, speed=speed)
        try:
            return cls(session, controller)
        except BaseException:
            session.close()
            raise

    def current_positions(self) -> tuple[float, ...]:
        position = self.hardware.position
        return tuple(float(position[i]) for i in self._index)

    def plan(self, path: Sequence[Sequence[float]], *, timing: str = "chapter",
             joint_names: Sequence[str] | None = None) -> JointTrajectory:
        return self.executor.plan_path(path, timing=timing, joint_names=joint_names)

    def send(self, trajectory: JointTrajectory) -> GoalOutcome:
        loop = self.loop
        start_s = loop.time_s
        handle = self.executor.submit(trajectory, now_s=start_s,
                                      on_done=lambda _result: loop.request_stop())
        end_s = trajectory.points[-1].time_from_start_s if trajectory.points else 0.0
        loop.run(end_s + self.executor.goal_time_s + GOAL_MARGIN_S)
        if not handle.done:  # should not happen: the executor always ends a goal
            handle.cancel()
            loop.run(60.0)
        result = handle.result
        if result is None:
            return GoalOutcome("unfinished", "the goal did not end", loop.time_s - start_s,
                               self.current_positions())
        return GoalOutcome(result.status.value, result.error_string, loop.time_s - start_s,
                           self.current_positions())

    @property
    def trace_path(self) -> Path | None:
        return self.session.trace_path

    def close(self) -> None:
        self.session.close()

    def __enter__(self) -> InProcessGoalSender:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# -- client logic -----------------------------------------------------------------------------

class InputRefused(ValueError):
    """A prompter answer that cannot be used; the message is one line for the user."""


def format_angles(values: Sequence[float]) -> str:
    """``[0.0000, 1.0000, ...]`` (no negative zero)."""
    return "[" + ", ".join(f"{round(float(v), 4) + 0.0:.4f}" for v in values) + "]"


def describe(outcome: GoalOutcome) -> str:
    text = f"{outcome.status} in {outcome.duration_s:.2f} s"
    return f"{text} ({outcome.error})" if outcome.error else text


def parse_joint_number(text: str, n_joints: int) -> int | None:
    """The joint index typed at the prompt, or None for "quit" (a negative number)."""
    answer = text.strip()
    if not answer:
        raise InputRefused(f"enter a joint number 0 through {n_joints - 1} (negative to quit)")
    try:
        value = float(answer)
    except ValueError:
        raise InputRefused(f"not a number: {answer!r}; enter a joint number 0 through {n_joints - 1}") from None
    if value < 0:
        return None
    if not value.is_integer():
        raise InputRefused(f"joint number must be a whole number 0 through {n_joints - 1}, got {answer}")
    if value >= n_joints:
        raise InputRefused(f"no joint {answer}: enter a joint number 0 through {n_joints - 1}")
    return int(value)


def parse_angle(text: str, spec: JointSpec) -> float:
    """The angle typed at the prompt, checked against the joint's range."""
    answer = text.strip()
    try:
        value = float(answer)
    except ValueError:
        raise InputRefused(f"not a number: {answer!r}; enter an angle in rad") from None
    if not math.isfinite(value):
        raise InputRefused(f"angle must be a finite number, got {answer}")
    if not _within(value, spec):
        raise InputRefused(f"angle {answer} is beyond {spec.name}'s limits [{spec.lower:g}, {spec.upper:g}]; "
                             "nothing sent")
    return value


def _within(value: float, spec: JointSpec) -> bool:
    return ((spec.lower is None or value >= spec.lower) and (spec.upper is None or value <= spec.upper))


def move_to(sender: GoalSender, pose: Sequence[float], *, timing: str = "chapter") -> GoalOutcome:
    """A two-point trajectory from the current pose to ``pose`` (every joint), run to the end."""
    return sender.send(sender.plan([list(pose)], timing=timing))


def move_joint(sender: GoalSender, joint: int, angle: float) -> GoalOutcome:
    """A two-point trajectory of one joint (the others hold), timed by the chapter's rule."""
    name = sender.joint_names[joint]
    return sender.send(sender.plan([[angle]], timing="chapter", joint_names=[name]))


def run_prompter(sender: GoalSender, *, ask: Callable[[str], str] = input, out: TextIO | None = None,
                 pre_pose: Sequence[float] | None = PRE_POSE) -> int:
    """The prompter client: go to ``pre_pose``, then move one joint per answer until a
    negative joint number or the end of input. Bad answers get one line and a new prompt.
    Returns the exit status (0)."""
    out = out or sys.stdout

    def say(text: str) -> None:
        print(text, file=out, flush=True)

    n = len(sender.joint_names)
    if pre_pose is not None:
        say(f"moving to the pre-pose {format_angles(pre_pose)}")
        outcome = move_to(sender, pre_pose)
        say(f"pre-pose: {describe(outcome)}; reached {format_angles(outcome.positions)}")
    question = joint_prompt(n)
    while True:
        try:
            joint = parse_joint_number(ask(question), n)
            if joint is None:
                say("quitting")
                return 0
            angle = parse_angle(ask(ANGLE_PROMPT), sender.joint_specs[joint])
            start = sender.current_positions()[joint]
        except InputRefused as exc:
            say(str(exc))
            continue
        except EOFError:
            say("")
            say("end of input: quitting")
            return 0
        try:
            outcome = move_joint(sender, joint, angle)
        except JointCtlError as exc:  # refused by the executor: nothing moved
            say(f"refused: {exc}")
            continue
        say(f"joint {joint} to {angle:g}: {describe(outcome)}; reached {format_angles(outcome.positions)}")
        miss = outcome.positions[joint] - angle
        if abs(miss) > REACH_TOLERANCE:
            say(f"note: {sender.joint_names[joint]} stopped {abs(miss):.3f} rad "
                f"{'short of' if miss * (angle - start) < 0 else 'past'} {angle:g} (blocked or still settling?)")


def read_path_file(path: str | Path, specs: Sequence[JointSpec]) -> list[list[float]]:
    """The rows of a CSV path file: one pose a line, ``len(specs)`` comma-separated angles,
    no times; blank lines and lines starting with ``#`` are skipped. Every row is checked
    (count, number, finite, within the joint's range): a :class:`JointCtlError` names the
    file, the line number and the value."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise JointCtlError(f"cannot read the path file: {getattr(exc, 'strerror', None) or exc}",
                            source=source) from None
    n = len(specs)
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        where = f"line {number}"
        fields = [f.strip() for f in stripped.split(",")]
        if len(fields) != n:
            raise JointCtlError(f"needs {n} comma-separated joint angles, found {len(fields)}",
                                source=source, field=where, value=stripped)
        row = []
        for spec, item in zip(specs, fields):
            try:
                value = float(item)
            except ValueError:
                raise JointCtlError(f"{spec.name} angle is not a number", source=source, field=where,
                                    value=item) from None
            if not math.isfinite(value):
                raise JointCtlError(f"{spec.name} angle must be a finite number", source=source,
                                    field=where, value=item)
            if not _within(value, spec):
                raise JointCtlError(f"{spec.name} angle is beyond its limits [{spec.lower:g}, {spec.upper:g}]",
                                    source=source, field=where, value=value)
            row.append(value)
        rows.append(row)
    if not rows:
        raise JointCtlError("the path file has no poses (one line of joint angles per pose)", source=source)
    return rows


def play_path_file(sender: GoalSender, path: str | Path, *, timing: str = "chapter",
                   out: TextIO | None = None) -> GoalOutcome:
    """The playfile client: check every row of ``path`` (nothing moves on a bad one),
    prepend the current pose, time the path by ``timing`` and run it to the end."""
    if timing not in TIMINGS:
        raise JointCtlError(f"must be one of {', '.join(TIMINGS)}", field="timing", value=timing)
    rows = read_path_file(path, sender.joint_specs)
    if out is not None:
        print(f"{path}: {len(rows)} poses after the current pose, {timing} timing", file=out, flush=True)
    return sender.send(sender.plan(rows, timing=timing))


# -- command-line entry points (wired in jointctl.cli.arm_clients, which picks the sender) ---------

def prompt_command(sender: GoalSender) -> int:
    """``jointctl prompt arm7dof [--ros]`` on an opened ``sender`` (closed here)."""
    with sender:
        status = run_prompter(sender)
    _wrote(sender)
    return status


def play_command(sender: GoalSender, pathfile: Path, *, timing: str = "chapter") -> int:
    """``jointctl play PATHFILE [--ros]`` on an opened ``sender`` (closed here): 0 when the goal succeeds,
    1 otherwise."""
    with sender:
        outcome = play_path_file(sender, pathfile, timing=timing, out=sys.stdout)
        print(f"goal {describe(outcome)}")
        print(f"final joint angles {format_angles(outcome.positions)}")
    _wrote(sender)
    return 0 if outcome.succeeded else 1


def _wrote(sender: GoalSender) -> None:
    if sender.trace_path is not None:
        print(f"wrote {sender.trace_path}", file=sys.stderr)

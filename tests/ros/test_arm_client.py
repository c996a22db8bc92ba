"""RosGoalSender's reading of the action's end (jointctl.ros.arm_client), against a stand-in for
actionlib's SimpleActionClient that ends each goal in the state a test gives: a rejection is a refusal
(nothing moved), an abort is an outcome that is not a success, which play turns into exit status 1."""

from __future__ import annotations

import io
import threading

import pytest
from actionlib_msgs.msg import GoalStatus as RosStatus

from jointctl.clients.arm import play_command, play_path_file, run_prompter
from jointctl.errors import JointCtlError
from jointctl.ros.arm_client import RosGoalSender
from jointctl.trajectory.messages import JointSpec, JointTrajectory, JointTrajectoryPoint

JOINTS = tuple(f"joint{k}" for k in range(7))


class EndingClient:
    """A SimpleActionClient whose goals end at once in ``state`` with ``text``."""

    def __init__(self, state: int, text: str) -> None:
        self.state, self.text, self.goals = state, text, []

    def send_goal(self, goal) -> None:
        self.goals.append(goal)

    def wait_for_result(self, _timeout) -> bool:
        return True

    def cancel_goal(self) -> None:  # pragma: no cover - the goals end at once
        raise AssertionError("not expected")

    def get_state(self) -> int:
        return self.state

    def get_goal_status_text(self) -> str:
        return self.text


class FakeRospy:
    @staticmethod
    def Duration(seconds):  # noqa: N802 (rospy's name)
        return seconds

    @staticmethod
    def signal_shutdown(_reason) -> None:
        pass


class FakeSubscriber:
    def unregister(self) -> None:
        pass


def sender_ending(state: int, text: str, positions=(0.0,) * 7) -> RosGoalSender:
    """A RosGoalSender without a graph: its state ``positions``, its goals ending in ``state``."""
    sender = RosGoalSender.__new__(RosGoalSender)
    sender._rospy = FakeRospy
    sender._subscriber = FakeSubscriber()
    sender._client = EndingClient(state, text)
    sender.server = "/trajActionServer"
    sender.joint_names = JOINTS
    sender.joint_specs = tuple(JointSpec(j, -3.0, 3.0, 1.0) for j in JOINTS)
    sender.goal_time_s = 0.5
    sender._lock = threading.Lock()
    sender._latest = dict(zip(JOINTS, positions))
    sender.plan = lambda path, timing="chapter", joint_names=None: JointTrajectory(  # one point at 1 s
        tuple(joint_names or JOINTS), (JointTrajectoryPoint(positions=tuple(path[-1]), time_from_start_s=1.0),))
    return sender


def test_a_rejected_goal_is_a_refusal_naming_the_servers_reason() -> None:
    sender = sender_ending(RosStatus.REJECTED, "joint5 beyond its limits")
    with pytest.raises(JointCtlError, match="the action server rejected the goal: joint5 beyond its limits") as info:
        sender.send(sender.plan([[0.5]], joint_names=["joint5"]))
    assert info.value.source == "/trajActionServer"
    answers = iter(["5", "0.5", "-1"])
    out = io.StringIO()
    assert run_prompter(sender, ask=lambda _prompt: next(answers), out=out, pre_pose=None) == 0
    assert f"refused: {info.value}" in out.getvalue().splitlines()


@pytest.mark.parametrize("state, status", [(RosStatus.ABORTED, "aborted"), (RosStatus.PREEMPTED, "preempted")])
def test_a_goal_that_ends_short_is_an_outcome_that_did_not_succeed(tmp_path, capsys, state, status) -> None:
    sender = sender_ending(state, "stopped: path tolerance", positions=(0.1,) * 7)
    path = tmp_path / "path.csv"
    path.write_text("0, 1, 0, -2, 0, 1, 0\n")
    outcome = play_path_file(sender, path)
    assert not outcome.succeeded
    assert (outcome.status, outcome.error, outcome.positions) == (status, "stopped: path tolerance", (0.1,) * 7)
    assert play_command(sender_ending(state, "stopped: path tolerance"), path) == 1
    assert f"goal {status} in " in capsys.readouterr().out


def test_a_goal_that_succeeds_is_a_success() -> None:
    sender = sender_ending(RosStatus.SUCCEEDED, "")
    outcome = sender.send(sender.plan([[0.0] * 7]))
    assert outcome.succeeded and outcome.error == ""


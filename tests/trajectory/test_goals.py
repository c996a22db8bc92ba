"""Tests for jointctl.trajectory.goals: the goal lifecycle without a loop (one result per goal)."""

from __future__ import annotations

from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.goals import GoalQueue, GoalStatus
from jointctl.trajectory.messages import JointTrajectory


def _results(handle):
    results = []
    handle.on_done = results.append
    return results


def test_ids_count_up_and_a_rejection_is_final() -> None:
    goals = GoalQueue()
    first, second = goals.new(JointTrajectory(("j",), ())), goals.new(JointTrajectory(("j",), ()))
    assert (first.id, second.id) == (1, 2) and first.status is GoalStatus.PENDING
    results = _results(first)
    goals.reject(first, InvalidTrajectory(TrajectoryErrorCode.INVALID_JOINTS, "no such joint"), 0.5)
    goals.reject(first, InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL, "again"), 0.6)
    assert [r.status for r in results] == [GoalStatus.REJECTED]
    assert results[0].error_code is TrajectoryErrorCode.INVALID_JOINTS and results[0].time_s == 0.5
    assert first.done and goals.pending is None


def test_a_newer_goal_preempts_the_pending_one_then_the_active_one() -> None:
    goals = GoalQueue()
    a, b, c = (goals.new(JointTrajectory(("j",), ())) for _ in range(3))
    done_a, done_b = _results(a), _results(b)
    goals.queue(a, 1.0)
    goals.queue(b, 1.1)  # a never started
    assert [r.status for r in done_a] == [GoalStatus.PREEMPTED] and "before it started" in done_a[0].error_string
    assert goals.take_pending() is b and goals.take_pending() is None
    goals.activate(b, 1.2)
    assert goals.active is b and b.status is GoalStatus.ACTIVE and goals.served == 1
    goals.activate(c, 1.3)
    assert [r.status for r in done_b] == [GoalStatus.PREEMPTED] and done_b[0].error_string == f"replaced by goal {c.id}"
    assert goals.active is c and goals.served == 2


def test_end_finishes_the_active_goal_once_and_abort_all_reaches_both() -> None:
    goals = GoalQueue()
    a, b = goals.new(JointTrajectory(("j",), ())), goals.new(JointTrajectory(("j",), ()))
    done_a, done_b = _results(a), _results(b)
    goals.activate(a, 0.0)
    goals.end(GoalStatus.SUCCEEDED, TrajectoryErrorCode.SUCCESSFUL, "", 2.0)
    goals.end(GoalStatus.ABORTED, TrajectoryErrorCode.GOAL_TOLERANCE_VIOLATED, "late", 2.1)  # nothing active
    assert [r.status for r in done_a] == [GoalStatus.SUCCEEDED] and goals.active is None
    goals.activate(b, 3.0)
    c = goals.new(JointTrajectory(("j",), ()))
    done_c = _results(c)
    goals.queue(c, 3.1)
    goals.abort_all("the chain failed", 3.2)
    for done in (done_b, done_c):
        assert [(r.status, r.error_string) for r in done] == [(GoalStatus.ABORTED, "the chain failed")]
    assert goals.active is None and goals.pending is None


def test_cancel_is_a_request_the_loop_acts_on() -> None:
    goals = GoalQueue()
    a = goals.new(JointTrajectory(("j",), ()))
    goals.activate(a, 0.0)
    a.cancel()
    assert a.cancel_requested and not a.done  # the executor stops the joints, then ends it PREEMPTED

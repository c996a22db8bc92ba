"""A goal's own tolerances (control_msgs/FollowJointTrajectory's path_tolerance, goal_tolerance, goal_time_tolerance)
over the controller's: 0 keeps the controller's, -1 takes the check away, a positive value replaces it.

Theory: without feed-forward the chapter's P loop (Kp 400) droops 24.8 mm under the 1.01 kg piston, so a path
tolerance of 5 mm is violated at a goal's first cycle and one of 40 mm is not (a slow move lags far less than the
droop's margin); at the end the joint rests 24.8 mm short, so a goal tolerance of 1 mm fails GOAL_TOLERANCE_VIOLATED
after the goal time and one of 30 mm succeeds.
"""

from __future__ import annotations

import pytest

from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.executor import GoalStatus, GoalTolerances
from tests.trajectory.test_executor import FF_OFF, POS, TRAJ, Done, build, executor_of, goal

SLOW_MOVE = ((2.0, -0.45),)  # 5 cm in 2 s: its lag is far below the droop's margin


def run_goal(write_scenario, controller: dict, tolerances: GoalTolerances | None, run_s: float = 4.0):
    session = build(write_scenario, {POS: FF_OFF, TRAJ: controller})
    executor = executor_of(session)
    session.loop.run(duration_s=1.0)  # settled into the droop
    done = Done()
    t0 = session.loop.time_s
    executor.submit(goal(*SLOW_MOVE), now_s=t0, on_done=done, tolerances=tolerances)
    session.loop.run(duration_s=run_s)
    return done.only, t0


def test_the_goals_path_tolerance_replaces_the_controllers(write_scenario):
    result, t0 = run_goal(write_scenario, {"path_tolerance": 0.04, "goal_tolerance": 0.03},
                          GoalTolerances(path={"joint1": 0.005}))
    assert result.error_code is TrajectoryErrorCode.PATH_TOLERANCE_VIOLATED
    assert result.time_s == pytest.approx(t0)  # the droop alone violates 5 mm, at the first cycle
    kept, _ = run_goal(write_scenario, {"path_tolerance": 0.04, "goal_tolerance": 0.03}, GoalTolerances())
    assert kept.status is GoalStatus.SUCCEEDED  # 0 / absent: the controller's 40 mm


def test_a_negative_tolerance_takes_the_check_away(write_scenario):
    strict = {"path_tolerance": 0.005, "goal_tolerance": 0.03}
    aborted, _ = run_goal(write_scenario, strict, None)
    assert aborted.error_code is TrajectoryErrorCode.PATH_TOLERANCE_VIOLATED
    erased, _ = run_goal(write_scenario, strict, GoalTolerances(path={"joint1": -1.0}))
    assert erased.status is GoalStatus.SUCCEEDED


def test_the_goals_goal_tolerance_and_goal_time_decide_at_the_end(write_scenario):
    result, t0 = run_goal(write_scenario, {"goal_tolerance": 0.03, "goal_time_s": 0.3},
                          GoalTolerances(goal={"joint1": 0.001}, goal_time_s=0.7))
    assert result.error_code is TrajectoryErrorCode.GOAL_TOLERANCE_VIOLATED
    end_s = t0 + SLOW_MOVE[-1][0]
    assert end_s + 0.7 < result.time_s <= end_s + 0.7 + 0.002  # the goal's 0.7 s, not the controller's 0.3 s


@pytest.mark.parametrize("tolerances, code, said", [
    (GoalTolerances(path={"joint9": 0.01}), TrajectoryErrorCode.INVALID_JOINTS, "joint9"),
    (GoalTolerances(goal={"joint1": float("nan")}), TrajectoryErrorCode.INVALID_GOAL, "nan"),
    (GoalTolerances(goal_time_s=-1.0), TrajectoryErrorCode.INVALID_GOAL, "goal_time_tolerance"),
], ids=["unknown_joint", "nan", "negative_goal_time"])
def test_bad_tolerances_refuse_the_goal_and_nothing_moves(write_scenario, tolerances, code, said):
    session = build(write_scenario, {POS: FF_OFF})
    executor = executor_of(session)
    session.loop.run(duration_s=0.5)
    before = list(executor.desired)
    with pytest.raises(InvalidTrajectory) as refused:
        executor.submit(goal(*SLOW_MOVE), now_s=session.loop.time_s, tolerances=tolerances)
    assert refused.value.error_code is code and said in str(refused.value)
    session.loop.run(duration_s=0.5)
    assert executor.desired == before and executor.active_goal is None

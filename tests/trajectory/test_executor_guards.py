"""Guards found in review: stale stamps, stopped executors, stream limits, bad scenario goals."""

from __future__ import annotations

import pytest

from jointctl.errors import ConfigError, InvalidCommand
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.executor import GoalStatus
from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint

TRAJ = "joint1_trajectory_controller"


def session_of(write_scenario, **changes) -> Session:
    data = {"robot": "one_dof", "controller_file": "trajectory", "gravity": -9.81, "duration_s": 5.0,
            "initial_positions": {"joint1": -0.5},
            "start_controllers": ["joint_state_controller", "joint1_position_controller", TRAJ]}
    data.update(changes)
    return Session(load_scenario(write_scenario(data)))


def goal(*points, stamp=0.0) -> JointTrajectory:
    return JointTrajectory(("joint1",), tuple(JointTrajectoryPoint(positions=(q,), time_from_start_s=t)
                                              for t, q in points), stamp_s=stamp)


def test_a_stale_stamp_cannot_squeeze_a_segment_past_the_velocity_limit(write_scenario):
    session = session_of(write_scenario)
    executor = session.manager.controller(TRAJ)
    session.loop.run(2.0)
    now = session.loop.time_s
    # Alone the goal is fine (0.4 m in 1 s); stamped 1.999 s ago, only 1 ms is left for it.
    stale = goal((2.0, -0.1), stamp=now - 1.999)
    with pytest.raises(InvalidTrajectory) as err:
        executor.submit(stale, now_s=now)
    assert err.value.error_code is TrajectoryErrorCode.INVALID_GOAL
    assert "left before" in str(err.value)
    session.loop.run(0.2)
    assert session.hardware.position[0] == pytest.approx(-0.5, abs=1e-5)


def test_a_goal_for_a_stopped_executor_is_rejected_not_left_pending(write_scenario):
    session = session_of(write_scenario)
    executor = session.manager.controller(TRAJ)
    session.manager.stop([TRAJ])
    with pytest.raises(InvalidTrajectory, match="not running"):
        executor.submit(goal((1.0, -0.4)), now_s=0.0)


def test_streamed_velocity_above_the_limit_is_refused(write_scenario):
    session = session_of(write_scenario)
    executor = session.manager.controller(TRAJ)
    with pytest.raises(InvalidCommand, match="velocity limit"):
        executor.stream_reference([-0.5], [150.0])  # joint1's limit is 100 m/s


def test_stopping_a_controller_clears_its_acceleration_reference(write_scenario):
    session = session_of(write_scenario)
    position = session.manager.controller("joint1_position_controller")
    session.manager.stop([TRAJ])
    position.set_reference(-0.5, 0.0, 3.0)
    assert session.manager.context.reference_accelerations[0] == 3.0
    session.manager.stop(["joint1_position_controller"])
    assert session.manager.context.reference_accelerations[0] == 0.0


def test_the_executor_owns_its_position_controllers_reference(write_scenario):
    # Chained mode: the executor writes the reference interfaces; an edge's set_reference is refused
    # naming it, and the goal's references are what the position controller uses.
    session = session_of(write_scenario)
    executor = session.manager.controller(TRAJ)
    position = session.manager.controller("joint1_position_controller")
    assert position.upstream == TRAJ
    executor.submit(goal((1.0, -0.4)), now_s=0.0)
    session.loop.run(0.5)
    with pytest.raises(InvalidCommand, match=f"comes from controller '{TRAJ}'"):
        position.set_reference(-0.1)
    session.loop.run(0.001)
    q, v, _ = position.reference_input
    assert -0.5 < q < -0.4 and v > 0  # the goal's interpolated reference, not -0.1
    assert session.manager.references[0] == q
    session.manager.stop([TRAJ])  # the executor leaves its last position, without feed-forward
    assert position.upstream is None
    assert position.reference_input == (q, 0.0, 0.0)
    position.set_reference(-0.1)  # the edge works again
    assert position.reference_input == (-0.1, 0.0, 0.0)


def test_negative_durations_are_refused(write_scenario):
    session = session_of(write_scenario)
    with pytest.raises(ValueError, match="negative"):
        session.loop.run(-1.0)


def test_loop_time_advances_while_the_loop_runs(write_scenario):
    # Edges on other threads read loop.time_s while run() is going: it must follow the cycles.
    session = session_of(write_scenario)
    seen = []
    session.loop.add_observer(lambda t: seen.append((t, session.loop.time_s)))
    session.loop.run(cycles=3)
    assert [loop_time for _, loop_time in seen] == pytest.approx([t for t, _ in seen])
    assert seen[-1][0] == pytest.approx(0.002)


@pytest.mark.parametrize(("goal_spec", "text"), [
    ({"controller": "joint1_position_controller", "path": {"points": [[-0.4]]}}, "trajectory executor"),
    ({"controller": TRAJ, "path": {"points": [[-0.4, 0.0]]}}, "needs 1 values"),
    ({"controller": TRAJ, "path": "abc"}, "mapping"),
])
def test_bad_scenario_goals_are_refused_before_the_run(write_scenario, goal_spec, text):
    with pytest.raises(ConfigError, match=text):
        session_of(write_scenario, goals=[{"at_s": 0.5, **goal_spec}])


def test_goal_ids_count_per_executor(write_scenario):
    first = session_of(write_scenario).manager.controller(TRAJ)
    second = session_of(write_scenario).manager.controller(TRAJ)
    a = first.submit(goal((1.0, -0.45)), now_s=0.0)
    b = second.submit(goal((1.0, -0.45)), now_s=0.0)
    assert a.id == b.id == 1
    assert a.status is GoalStatus.PENDING

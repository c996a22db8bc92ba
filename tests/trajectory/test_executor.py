"""Closed-loop tests of the trajectory executor on the simulated robots.

Each test builds a :class:`Session` from a scenario dict (the 1-DOF robot, its
``trajectory`` controller file: a Kp 400 position controller with model
feed-forward, fed by ``joint1_trajectory_controller``), runs the 1 kHz loop and
submits goals between runs at the loop's time. A per-cycle trace of the
executor's references and the joint state (an observer of the loop) backs the
numbers: refusals leave the robot still, goals end with exactly one result,
splices and stops are continuous, streamed references obey the watchdog.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

import pytest

import jointctl.trajectory.goals as goals_module
from jointctl.errors import InvalidCommand
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.executor import GoalResult, GoalStatus, TrajectoryExecutor, TrajectoryFeedback
from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint
from jointctl.trajectory.timing import PATH_MAX_ACCELERATION, PATH_MAX_JERK, PATH_VELOCITY_FRACTION, time_path

TRAJ = "joint1_trajectory_controller"
POS = "joint1_position_controller"
DT = 0.001
FF_OFF = {"feedforward": {"gravity": False, "damping": False, "inertia": False}}
GRAVITY_DROOP_M = 0.0248  # (1 kg piston + 10 g disk) * 9.81 / Kp 400, without feed-forward


# ----------------------------------------------------------------------------- helpers


def trajectory_scenario(controllers: dict | None = None, **changes) -> dict:
    scenario = {
        "name": "test_trajectory",
        "robot": "one_dof",
        "controller_file": "trajectory",
        "start_controllers": ["joint_state_controller", POS, TRAJ],
        "gravity": -9.81,
        "initial_positions": {"joint1": -0.5},
        "duration_s": 1.0,
    }
    if controllers:
        scenario["controllers"] = controllers
    scenario.update(changes)
    return scenario


def build(write_scenario, controllers: dict | None = None, **changes) -> Session:
    return Session(load_scenario(write_scenario(trajectory_scenario(controllers, **changes))))


def goal(*points: tuple[float, float], joints: tuple[str, ...] = ("joint1",), stamp_s: float = 0.0,
         velocities: bool = False) -> JointTrajectory:
    """A trajectory from ``(time_from_start, position)`` pairs (positions: one float or a tuple a joint)."""
    rows = []
    for t, q in points:
        q = (q,) if isinstance(q, (int, float)) else tuple(q)
        rows.append(JointTrajectoryPoint(positions=q, velocities=(0.0,) * len(q) if velocities else (),
                                         time_from_start_s=t))
    return JointTrajectory(joints, tuple(rows), stamp_s=stamp_s)


class Done:
    """An ``on_done`` callback that records every call."""

    def __init__(self) -> None:
        self.results: list[GoalResult] = []

    def __call__(self, result: GoalResult) -> None:
        self.results.append(result)

    @property
    def only(self) -> GoalResult:
        assert len(self.results) == 1, f"on_done called {len(self.results)} times: {self.results}"
        return self.results[0]


@dataclass
class Trace:
    """Per-cycle samples of an executor's references and its joints' state (loop observer)."""

    t: list[float] = field(default_factory=list)
    q_ref: list[list[float]] = field(default_factory=list)
    v_ref: list[list[float]] = field(default_factory=list)
    a_ref: list[list[float]] = field(default_factory=list)
    reference_input: list[list[tuple[float, float, float]]] = field(default_factory=list)
    q: list[list[float]] = field(default_factory=list)
    v: list[list[float]] = field(default_factory=list)
    goal_id: list[int | None] = field(default_factory=list)

    @classmethod
    def attach(cls, session: Session, executor: TrajectoryExecutor) -> Trace:
        trace = cls()
        hw = session.hardware
        index = [hw.joint_index(j) for j in executor.joint_names]
        targets = executor.targets

        def observe(time_s: float) -> None:
            trace.t.append(time_s)
            trace.q_ref.append(list(executor.desired))
            trace.v_ref.append(list(executor.desired_velocity))
            trace.a_ref.append(list(executor.desired_acceleration))
            trace.reference_input.append([c.reference_input for c in targets])
            trace.q.append([hw.position[i] for i in index])
            trace.v.append([hw.velocity[i] for i in index])
            trace.goal_id.append(None if executor.active_goal is None else executor.active_goal.id)

        session.loop.add_observer(observe)
        return trace

    def at(self, time_s: float) -> int:
        """Index of the cycle at loop time ``time_s``."""
        k = min(range(len(self.t)), key=lambda i: abs(self.t[i] - time_s))
        assert abs(self.t[k] - time_s) < DT / 2, f"no cycle at {time_s} s"
        return k

    def first_active(self, goal_id: int) -> int:
        return self.goal_id.index(goal_id)


def executor_of(session: Session, name: str = TRAJ) -> TrajectoryExecutor:
    executor = session.manager.controller(name)
    assert isinstance(executor, TrajectoryExecutor)
    return executor


@pytest.fixture
def captured_handles(monkeypatch):
    """Every GoalHandle the executor creates (submit raises on a refusal, so the handle is
    otherwise out of reach)."""
    handles = []

    class RecordingHandle(goals_module.GoalHandle):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            handles.append(self)

    monkeypatch.setattr(goals_module, "GoalHandle", RecordingHandle)
    return handles


# ----------------------------------------------------------------------------- refusals


REFUSALS = {
    "unknown_joint": (goal((1.0, -0.4), joints=("joint7",)), TrajectoryErrorCode.INVALID_JOINTS, 0.2),
    "no_points": (JointTrajectory(("joint1",), ()), TrajectoryErrorCode.INVALID_GOAL, 0.2),
    "beyond_upper_limit": (goal((0.5, -0.3), (1.0, 0.01)), TrajectoryErrorCode.INVALID_GOAL, 0.2),
    # 0.4 m in 1 ms is 400 m/s, above the joint's 100 m/s.
    "faster_than_velocity_limit": (goal((0.001, -0.9)), TrajectoryErrorCode.INVALID_GOAL, 0.2),
    # Stamp 0.2 s + last point 0.1 s = 0.3 s, submitted at 1.0 s: already over.
    "old_header_stamp": (goal((0.1, -0.45), stamp_s=0.2), TrajectoryErrorCode.OLD_HEADER_TIMESTAMP, 1.0),
}


@pytest.mark.parametrize("case", list(REFUSALS))
def test_a_refused_goal_is_rejected_once_and_nothing_moves(write_scenario, captured_handles, case):
    trajectory, code, submit_at = REFUSALS[case]
    session = build(write_scenario)
    executor = executor_of(session)
    session.loop.run(duration_s=submit_at)
    assert session.loop.time_s == pytest.approx(submit_at)
    trace = Trace.attach(session, executor)
    q_before = session.hardware.position[0]
    desired_before = list(executor.desired)
    done = Done()

    with pytest.raises(InvalidTrajectory) as info:
        executor.submit(trajectory, now_s=session.loop.time_s, on_done=done)
    assert info.value.error_code is code
    result = done.only
    assert result.status is GoalStatus.REJECTED
    assert result.error_code is code
    assert result.error_string == str(info.value)
    assert result.time_s == pytest.approx(submit_at)
    (handle,) = captured_handles
    assert handle.status is GoalStatus.REJECTED and handle.done and handle.result is result

    session.loop.run(duration_s=0.3)
    assert len(done.results) == 1  # still once
    assert executor.active_goal is None and executor.goals_served == 0
    assert all(ref == desired_before for ref in trace.q_ref)
    assert all(v == [0.0] for v in trace.v_ref)
    drift = max(abs(q[0] - q_before) for q in trace.q)
    assert drift < 1e-5, f"joint1 moved {drift} m after a refusal"
    assert abs(q_before - (-0.5)) < 1e-5  # gravity feed-forward + Kp 400 hold the start pose


def test_a_refusal_during_a_goal_leaves_the_goal_untouched(write_scenario):
    """The same run with and without a refused submit mid-goal is identical, cycle for cycle."""
    traces = []
    for refuse in (False, True):
        session = build(write_scenario)
        executor = executor_of(session)
        trace = Trace.attach(session, executor)
        done = Done()
        executor.submit(goal((1.0, -0.2)), now_s=session.loop.time_s, on_done=done)
        session.loop.run(duration_s=0.4)
        if refuse:
            with pytest.raises(InvalidTrajectory):
                executor.submit(goal((0.5, 0.2)), now_s=session.loop.time_s)
        session.loop.run(duration_s=0.8)
        assert done.only.status is GoalStatus.SUCCEEDED
        traces.append(trace)
    assert traces[0].q_ref == traces[1].q_ref
    assert traces[0].q == traces[1].q


# ----------------------------------------------------------------------------- run-time aborts


def test_path_tolerance_violation_aborts_mid_move_and_the_robot_stops(write_scenario):
    # Without feed-forward the piston droops 24.8 mm at rest, so the tolerance sits above that:
    # only the lag of a fast move (-0.5 -> -0.1 m in 0.3 s, 2 m/s peak) can violate it.
    session = build(write_scenario, {POS: FF_OFF, TRAJ: {"path_tolerance": 0.04}})
    executor = executor_of(session)
    session.loop.run(duration_s=1.0)
    assert session.hardware.position[0] == pytest.approx(-0.5 - GRAVITY_DROOP_M, abs=1e-3)
    trace = Trace.attach(session, executor)
    done = Done()
    t0 = session.loop.time_s
    handle = executor.submit(goal((0.3, -0.1)), now_s=t0, on_done=done)
    session.loop.run(duration_s=2.5)

    result = done.only
    assert result.status is GoalStatus.ABORTED and handle.status is GoalStatus.ABORTED
    assert result.error_code is TrajectoryErrorCode.PATH_TOLERANCE_VIOLATED
    assert t0 + 0.005 < result.time_s < t0 + 0.3  # at run time, during the move
    k = trace.at(result.time_s)
    assert abs(trace.q_ref[k][0] - trace.q[k][0]) > 0.04
    assert all(abs(trace.q_ref[i][0] - trace.q[i][0]) <= 0.04 for i in range(k))
    assert executor.active_goal is None
    # The abort stops the robot: references decelerate to rest, the joint settles.
    assert trace.v_ref[-1] == [0.0]
    assert abs(trace.q_ref[-1][0] - trace.q_ref[trace.at(t0 + 1.0)][0]) < 1e-12
    assert abs(session.hardware.velocity[0]) < 1e-3
    assert trace.q_ref[-1][0] < -0.1 - 0.05  # it did not go on to the goal


def test_path_tolerance_below_the_gravity_droop_aborts_at_the_first_cycle(write_scenario):
    """The chapter's settings (no feed-forward) with path_tolerance 0.005: the 24.8 mm droop
    alone is a violation, found at the goal's first cycle."""
    session = build(write_scenario, {POS: FF_OFF, TRAJ: {"path_tolerance": 0.005}})
    executor = executor_of(session)
    session.loop.run(duration_s=1.0)
    trace = Trace.attach(session, executor)
    done = Done()
    t0 = session.loop.time_s
    executor.submit(goal((0.3, -0.1)), now_s=t0, on_done=done)
    session.loop.run(duration_s=2.0)
    assert done.only.error_code is TrajectoryErrorCode.PATH_TOLERANCE_VIOLATED
    assert done.only.status is GoalStatus.ABORTED
    assert done.only.time_s == pytest.approx(t0)
    assert abs(session.hardware.velocity[0]) < 1e-3
    assert abs(trace.q_ref[-1][0] - (-0.5)) < 1e-3  # stopped where it stood


@pytest.mark.parametrize("feedforward", [False, True], ids=["no_feedforward", "feedforward"])
def test_goal_tolerance_decides_at_the_end(write_scenario, feedforward):
    controllers = {TRAJ: {"goal_tolerance": 0.001, "goal_time_s": 0.3}}
    if not feedforward:
        controllers[POS] = FF_OFF
    session = build(write_scenario, controllers)
    executor = executor_of(session)
    session.loop.run(duration_s=0.5)
    done = Done()
    t0 = session.loop.time_s
    executor.submit(goal((1.0, -0.3)), now_s=t0, on_done=done)
    end = t0 + 1.0
    session.loop.run(duration_s=2.0)
    result = done.only
    if feedforward:
        assert result.status is GoalStatus.SUCCEEDED
        assert end - 1e-9 <= result.time_s <= end + 0.3
    else:  # 24.8 mm of droop never gets within 1 mm
        assert result.status is GoalStatus.ABORTED
        assert result.error_code is TrajectoryErrorCode.GOAL_TOLERANCE_VIOLATED
        assert result.time_s >= end + 0.3 - 1e-9
        assert result.time_s <= end + 0.3 + 2 * DT
        assert "joint1" in result.error_string


# ----------------------------------------------------------------------------- success and starting


def test_a_goal_succeeds_once_and_ends_at_its_last_point(write_scenario):
    session = build(write_scenario)
    executor = executor_of(session)
    session.loop.run(duration_s=0.2)
    done = Done()
    t0 = session.loop.time_s
    handle = executor.submit(goal((0.5, -0.35), (1.2, -0.2)), now_s=t0, on_done=done)
    assert handle.status is GoalStatus.PENDING and executor.goals_served == 0
    session.loop.run(cycles=1)
    assert handle.status is GoalStatus.ACTIVE and executor.goals_served == 1
    session.loop.run(duration_s=1.5)
    result = done.only
    assert result.status is GoalStatus.SUCCEEDED and result.error_code is TrajectoryErrorCode.SUCCESSFUL
    assert result.time_s == pytest.approx(t0 + 1.2)
    assert handle.wait(0) is result and handle.done
    assert abs(session.hardware.position[0] - (-0.2)) < 1e-3
    assert executor.desired == [-0.2] and executor.desired_velocity == [0.0]
    assert executor.active_goal is None
    # A second goal counts too.
    done2 = Done()
    executor.submit(goal((0.5, -0.3)), now_s=session.loop.time_s, on_done=done2)
    session.loop.run(duration_s=0.7)
    assert done2.only.status is GoalStatus.SUCCEEDED
    assert executor.goals_served == 2
    assert len(done.results) == 1


def test_a_goal_starts_from_the_desired_state_not_the_measured_one(write_scenario):
    # Without feed-forward the joint droops 24.8 mm below the desired -0.5 m.
    session = build(write_scenario, {POS: FF_OFF})
    executor = executor_of(session)
    session.loop.run(duration_s=1.0)
    assert executor.desired == [-0.5]
    assert session.hardware.position[0] < -0.52
    # A first point at t=0 must match the desired (not the measured) position.
    with pytest.raises(InvalidTrajectory) as info:
        executor.submit(goal((0.0, session.hardware.position[0]), (1.0, -0.4)), now_s=session.loop.time_s)
    assert info.value.error_code is TrajectoryErrorCode.INVALID_GOAL
    trace = Trace.attach(session, executor)
    previous = executor.desired[0]
    handle = executor.submit(goal((0.0, -0.5), (0.5, -0.3)), now_s=session.loop.time_s)
    session.loop.run(duration_s=0.05)
    k = trace.first_active(handle.id)
    assert k == 0
    max_step = 1.5 * 0.2 / 0.5 * DT  # the cubic's peak speed times one cycle
    assert abs(trace.q_ref[k][0] - previous) <= max_step
    steps = [abs(trace.q_ref[i][0] - trace.q_ref[i - 1][0]) for i in range(1, len(trace.t))]
    assert max(steps) <= max_step
    # The plan continues from last cycle's desired state (at rest): one cycle later its velocity is
    # at most the cubic's initial acceleration, 6·Δq/T², times dt.
    assert abs(trace.v_ref[0][0]) <= 6 * 0.2 / 0.5**2 * DT


# ----------------------------------------------------------------------------- splice, cancel


def test_a_new_goal_during_a_move_splices_continuously(write_scenario):
    session = build(write_scenario)
    executor = executor_of(session)
    trace = Trace.attach(session, executor)
    session.loop.run(duration_s=0.1)
    done_a, done_b = Done(), Done()
    a = executor.submit(goal((2.0, -0.1)), now_s=session.loop.time_s, on_done=done_a)
    session.loop.run(duration_s=0.7)
    moving = trace.v_ref[-1][0]
    assert moving > 0.2  # A is moving the joint up at speed
    b = executor.submit(goal((0.6, -0.25), (1.2, -0.6)), now_s=session.loop.time_s, on_done=done_b)
    session.loop.run(duration_s=2.0)

    s = trace.first_active(b.id)
    assert trace.goal_id[s - 1] == a.id
    result_a = done_a.only
    assert result_a.status is GoalStatus.PREEMPTED and a.status is GoalStatus.PREEMPTED
    assert result_a.time_s == pytest.approx(trace.t[s])
    assert done_b.only.status is GoalStatus.SUCCEEDED
    assert abs(session.hardware.position[0] - (-0.6)) < 1e-3
    # Continuity around the switch: position steps bounded by speed * dt, no velocity jump.
    for i in range(s - 5, s + 20):
        step = abs(trace.q_ref[i][0] - trace.q_ref[i - 1][0])
        bound = max(abs(trace.v_ref[i][0]), abs(trace.v_ref[i - 1][0])) * DT + 1e-6
        assert step <= bound, f"reference jumps {step} m at cycle {i} (switch at {s})"
    # No stall at the switch: the reference moves on from the last one at the last velocity.
    assert abs(trace.q_ref[s][0] - (trace.q_ref[s - 1][0] + trace.v_ref[s - 1][0] * DT)) <= 0.5 * 20 * DT**2
    dv = max(abs(trace.v_ref[i][0] - trace.v_ref[i - 1][0]) for i in range(s - 5, s + 20))
    assert dv < 0.02  # acceleration below 20 m/s² through the splice, no spike


def test_cancel_decelerates_within_stop_deceleration(write_scenario):
    session = build(write_scenario)
    executor = executor_of(session)
    trace = Trace.attach(session, executor)
    session.loop.run(duration_s=0.1)
    done = Done()
    handle = executor.submit(goal((2.0, -0.1)), now_s=session.loop.time_s, on_done=done)
    session.loop.run(duration_s=1.0)  # mid-move: the cubic's peak speed, 1.5 * 0.4 / 2 = 0.3 m/s
    v0 = trace.v_ref[-1][0]
    assert v0 == pytest.approx(0.3, abs=0.01)
    handle.cancel()
    c = len(trace.t)  # index of the cycle that sees the cancel
    session.loop.run(duration_s=2.0)

    result = done.only
    assert result.status is GoalStatus.PREEMPTED and result.error_code is TrajectoryErrorCode.SUCCESSFUL
    assert result.time_s == pytest.approx(trace.t[c])
    decel = executor.stop_deceleration[0]
    assert decel == 5.0
    stop_time = abs(v0) / decel
    for i in range(c, len(trace.t)):
        if trace.t[i] >= trace.t[c] + stop_time + DT:
            assert trace.v_ref[i] == [0.0], f"still moving at {trace.t[i] - trace.t[c]} s after the cancel"
    for i in range(c, len(trace.t)):
        rate = abs(trace.v_ref[i][0] - trace.v_ref[i - 1][0]) / DT
        assert rate <= decel + 1e-6, f"deceleration {rate} at cycle {i}"
        assert trace.q_ref[i][0] >= trace.q_ref[i - 1][0] - 1e-12  # no backing up
    # It stops in v0² / (2 decel), not instantly and not at the goal.
    travel = trace.q_ref[-1][0] - trace.q_ref[c - 1][0]
    assert travel == pytest.approx(v0 ** 2 / (2 * decel), abs=v0 * DT + 1e-6)
    assert abs(session.hardware.velocity[0]) < 1e-3
    assert abs(session.hardware.position[0] - trace.q_ref[-1][0]) < 1e-3


def test_cancel_before_a_goal_starts_preempts_it_without_motion(write_scenario):
    session = build(write_scenario)
    executor = executor_of(session)
    session.loop.run(duration_s=0.1)
    done = Done()
    handle = executor.submit(goal((1.0, -0.2)), now_s=session.loop.time_s, on_done=done)
    handle.cancel()
    session.loop.run(duration_s=0.5)
    assert done.only.status is GoalStatus.PREEMPTED
    assert abs(session.hardware.position[0] - (-0.5)) < 1e-5
    assert executor.desired == [-0.5] and executor.desired_velocity == [0.0]


def test_a_goal_replaced_before_it_starts_is_preempted_without_being_active(write_scenario):
    session = build(write_scenario)
    executor = executor_of(session)
    session.loop.run(duration_s=0.1)
    seen = []
    done_a, done_b = Done(), Done()
    now = session.loop.time_s
    a = executor.submit(goal((1.0, -0.2)), now_s=now, on_done=done_a, on_feedback=seen.append)
    b = executor.submit(goal((0.5, -0.4)), now_s=now, on_done=done_b)
    assert a.status is GoalStatus.PREEMPTED and done_a.only.status is GoalStatus.PREEMPTED
    assert b.status is GoalStatus.PENDING
    session.loop.run(duration_s=1.0)
    assert a.status is GoalStatus.PREEMPTED and len(done_a.results) == 1
    assert seen == []  # never active: never got feedback
    assert executor.goals_served == 1
    assert done_b.only.status is GoalStatus.SUCCEEDED
    assert abs(session.hardware.position[0] - (-0.4)) < 1e-3


def test_stopping_the_executor_aborts_the_active_goal_once(write_scenario):
    session = build(write_scenario)
    executor = executor_of(session)
    session.loop.run(duration_s=0.2)
    done = Done()
    handle = executor.submit(goal((1.0, -0.2)), now_s=session.loop.time_s, on_done=done)
    session.loop.run(duration_s=0.5)
    assert handle.status is GoalStatus.ACTIVE
    session.manager.stop([TRAJ], session.loop.time_s)
    result = done.only
    assert result.status is GoalStatus.ABORTED and handle.status is GoalStatus.ABORTED
    assert result.time_s == pytest.approx(0.7)
    assert executor.active_goal is None
    session.loop.run(duration_s=0.5)
    session.manager.stop([TRAJ], session.loop.time_s)  # not running: nothing more
    assert len(done.results) == 1


def test_stopping_the_executor_mid_move_leaves_the_joint_at_rest_on_its_reference(write_scenario):
    session = build(write_scenario)
    executor = executor_of(session)
    session.loop.run(duration_s=0.2)
    executor.submit(goal((1.0, -0.2)), now_s=session.loop.time_s)
    session.loop.run(duration_s=0.5)  # moving at about 0.45 m/s
    session.manager.stop([TRAJ], session.loop.time_s)
    session.loop.run(duration_s=2.0)
    target = session.manager.controller(POS)
    q_cmd, v_cmd, a_cmd = target.reference_input
    assert abs(session.hardware.velocity[0]) < 1e-3
    assert abs(session.hardware.position[0] - q_cmd) < 1e-3, (
        f"rests at {session.hardware.position[0]} m, reference {q_cmd} m (command velocity {v_cmd}, "
        f"acceleration {a_cmd})")
    assert v_cmd == 0.0 and a_cmd == 0.0


# ----------------------------------------------------------------------------- feedback, stream rate


def test_feedback_at_its_rate_matches_the_trace(write_scenario):
    session = build(write_scenario, {TRAJ: {"feedback_rate_hz": 20}})
    executor = executor_of(session)
    trace = Trace.attach(session, executor)
    session.loop.run(duration_s=0.1)
    feedback: list[TrajectoryFeedback] = []
    done = Done()
    t0 = session.loop.time_s
    executor.submit(goal((1.0, -0.3), (2.0, -0.45)), now_s=t0, on_feedback=feedback.append, on_done=done)
    session.loop.run(duration_s=2.5)
    assert done.only.status is GoalStatus.SUCCEEDED
    assert abs(len(feedback) - 40) <= 2, len(feedback)
    assert feedback[0].time_s == pytest.approx(t0)
    gaps = [b.time_s - a.time_s for a, b in zip(feedback, feedback[1:])]
    assert all(abs(g - 0.05) < 1e-6 for g in gaps)
    assert feedback[-1].time_s <= done.only.time_s + 1e-9
    for fb in feedback:
        k = trace.at(fb.time_s)
        assert fb.joint_names == ("joint1",)
        assert fb.desired_positions == tuple(trace.q_ref[k])
        assert fb.desired_velocities == tuple(trace.v_ref[k])
        assert fb.actual_positions == tuple(trace.q[k])
        assert fb.actual_velocities == tuple(trace.v[k])
        assert fb.errors[0] == pytest.approx(trace.q_ref[k][0] - trace.q[k][0])
    assert max(abs(fb.desired_velocities[0]) for fb in feedback) > 0.1  # it reported a move
    assert executor.latest_feedback is feedback[-1]


def test_chapter_mode_updates_references_at_the_stream_rate(write_scenario):
    session = build(write_scenario, {
        TRAJ: {"interpolation": "linear", "stream_rate_hz": 100, "velocity_feedforward": False},
        POS: FF_OFF,
    })
    executor = executor_of(session)
    trace = Trace.attach(session, executor)
    session.loop.run(duration_s=0.2)
    handle = executor.submit(goal((0.5, -0.4), (1.0, -0.3)), now_s=session.loop.time_s)
    session.loop.run(duration_s=1.2)
    start = trace.first_active(handle.id)
    end = trace.at(trace.t[start] + 1.0)
    changes = [i for i in range(start + 1, end) if trace.reference_input[i][0][0] != trace.reference_input[i - 1][0][0]]
    assert changes, "the reference never moved"
    assert all((i - start) % 10 == 0 for i in changes), changes[:10]
    assert len(changes) >= 95  # a new value every 10 ms over the 1 s goal
    for i in range(start, end):
        assert trace.reference_input[i][0][1:] == (0.0, 0.0)  # positions only
    # Linear between the points: every held value lies on the line from last cycle's desired
    # position (at trace.t[start] - DT, where the plan starts) through the goal's points.
    for i in range(start, end, 10):
        tau = trace.t[i] - trace.t[start] + DT
        first = 0.5 + DT
        line = -0.5 + 0.1 * tau / first if tau <= first else -0.4 + 0.2 * (tau - first)
        assert trace.reference_input[i][0][0] == pytest.approx(line, abs=1e-9)


# ----------------------------------------------------------------------------- streamed references


def test_streamed_references_are_held_with_zero_velocity_after_the_watchdog(write_scenario):
    timeout = 0.1
    session = build(write_scenario, {TRAJ: {"watchdog_timeout_s": timeout}})
    executor = executor_of(session)
    trace = Trace.attach(session, executor)
    session.loop.run(duration_s=0.1)
    t_start, t_stop, speed = 0.1, 0.5, 0.1
    last = {}

    def stream(time_s: float) -> None:
        if t_start - 1e-9 <= time_s <= t_stop + 1e-9:
            q = -0.5 + speed * (time_s - t_start)
            executor.stream_reference([q], [speed])
            last.update(t=time_s, q=q)

    session.loop.add_input(stream)
    session.loop.run(duration_s=2.4)  # the abrupt hold rings (Kp 400, no D) for a while
    assert last["t"] == pytest.approx(t_stop) and last["q"] == pytest.approx(-0.46)
    for i, t in enumerate(trace.t):
        if t < t_start - 1e-9:
            continue
        if t <= t_stop + 1e-9:
            assert trace.q_ref[i][0] == pytest.approx(-0.5 + speed * (t - t_start), abs=1e-12)
        else:
            assert trace.q_ref[i][0] == last["q"]  # held
        if t < t_stop + timeout - DT / 2:
            assert trace.v_ref[i] == [speed]
        elif t > t_stop + timeout + 1.5 * DT:
            assert trace.v_ref[i] == [0.0], f"velocity {trace.v_ref[i]} at {t} s, watchdog at {t_stop + timeout}"
    assert abs(session.hardware.velocity[0]) < 1e-3
    assert abs(session.hardware.position[0] - last["q"]) < 1e-4


@pytest.mark.parametrize("positions, velocities", [
    ([math.nan], None),
    ([-0.45], [math.inf]),
    ([0.1], None),
    ([-1.2], None),
    ([True], None),
    ([-0.45, -0.45], None),
], ids=["nan", "infinite_velocity", "above_range", "below_range", "bool", "too_many"])
def test_stream_reference_refuses_bad_values_and_nothing_changes(write_scenario, positions, velocities):
    session = build(write_scenario)
    executor = executor_of(session)
    session.loop.run(duration_s=0.1)
    executor.stream_reference([-0.45])
    session.loop.run(duration_s=2.5)  # the 5 cm step rings (Kp 400, no D) and settles
    trace = Trace.attach(session, executor)
    q_before = session.hardware.position[0]
    assert q_before == pytest.approx(-0.45, abs=1e-3)
    with pytest.raises(InvalidCommand):
        executor.stream_reference(positions, velocities)
    session.loop.run(duration_s=0.3)
    assert all(ref == [-0.45] for ref in trace.q_ref)
    assert all(v == [0.0] for v in trace.v_ref)
    assert max(abs(q[0] - q_before) for q in trace.q) < 1e-5


def test_a_stream_preempts_the_active_goal(write_scenario):
    session = build(write_scenario)
    executor = executor_of(session)
    session.loop.run(duration_s=0.1)
    done = Done()
    executor.submit(goal((1.0, -0.2)), now_s=session.loop.time_s, on_done=done)
    session.loop.run(duration_s=0.3)
    executor.stream_reference([executor.desired[0]])
    session.loop.run(duration_s=1.0)
    assert done.only.status is GoalStatus.PREEMPTED
    assert executor.active_goal is None


# ----------------------------------------------------------------------------- two joints


TWO_SLIDES_URDF = textwrap.dedent("""\
    <?xml version="1.0"?>
    <!-- Two vertical slides side by side on a fixed base: independent 1-kg pistons. -->
    <robot name="two_slides">
      <link name="world"/>
      <joint name="glue" type="fixed">
        <parent link="world"/>
        <child link="base"/>
      </joint>
      <link name="base">
        <inertial>
          <origin xyz="0 0 0.5"/>
          <mass value="1.0"/>
          <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/>
        </inertial>
      </link>
      {slides}
    </robot>
    """)

SLIDE = """
  <joint name="{joint}" type="prismatic">
    <parent link="base"/>
    <child link="{link}"/>
    <origin xyz="{x} 0 1.0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-1.0" upper="0.0" effort="1000.0" velocity="10.0"/>
    <dynamics damping="10.0"/>
  </joint>
  <link name="{link}">
    <inertial>
      <origin xyz="0 0 0.5"/>
      <mass value="1.0"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.005"/>
    </inertial>
  </link>
  <transmission name="{joint}_transmission">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="{joint}">
      <hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>
    </joint>
    <actuator name="{joint}_motor">
      <hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>
      <mechanicalReduction>1</mechanicalReduction>
    </actuator>
  </transmission>
"""

TWO_SLIDES_CONTROLLERS = textwrap.dedent("""\
    two_slides:
      joint_state_controller:
        type: joint_state_controller/JointStateController
        publish_rate: 50
      joint1_position_controller:
        type: effort_controllers/JointPositionController
        joint: joint1
        pid: {p: 400.0, i: 0.0, d: 0.0}
        feedforward: {gravity: true, damping: true, inertia: true}
      joint2_position_controller:
        type: effort_controllers/JointPositionController
        joint: joint2
        pid: {p: 400.0, i: 0.0, d: 0.0}
        feedforward: {gravity: true, damping: true, inertia: true}
      slides_trajectory_controller:
        type: trajectory_controllers/JointTrajectoryExecutor
        joints: [joint1, joint2]
        position_controllers: [joint1_position_controller, joint2_position_controller]
        interpolation: cubic
        stop_deceleration: 5.0
    """)


@pytest.fixture
def two_slides(tmp_path: Path, write_scenario):
    urdf = tmp_path / "two_slides.urdf"
    slides = "".join(SLIDE.format(joint=f"joint{k}", link=f"slide{k}", x=x) for k, x in ((1, -0.3), (2, 0.3)))
    urdf.write_text(TWO_SLIDES_URDF.format(slides=slides))
    controllers = tmp_path / "two_slides_controllers.yaml"
    controllers.write_text(TWO_SLIDES_CONTROLLERS)
    scenario = {
        "name": "two_slides",
        "robot": str(urdf),
        "controller_file": str(controllers),
        "start_controllers": ["joint_state_controller", "joint1_position_controller",
                              "joint2_position_controller", "slides_trajectory_controller"],
        "gravity": -9.81,
        "floor": False,
        "initial_positions": {"joint1": -0.5, "joint2": -0.6},
        "duration_s": 1.0,
    }
    session = Session(load_scenario(write_scenario(scenario, "two_slides.yaml")))
    return session, executor_of(session, "slides_trajectory_controller")


def test_a_partial_goal_moves_only_the_joints_it_names(two_slides):
    session, executor = two_slides
    trace = Trace.attach(session, executor)
    session.loop.run(duration_s=0.2)
    q1 = session.hardware.position[session.hardware.joint_index("joint1")]
    assert q1 == pytest.approx(-0.5, abs=1e-4)
    done = Done()
    executor.submit(goal((1.0, -0.2), joints=("joint2",)), now_s=session.loop.time_s, on_done=done)
    session.loop.run(duration_s=1.5)
    assert done.only.status is GoalStatus.SUCCEEDED
    assert all(ref[0] == -0.5 for ref in trace.q_ref)
    assert max(abs(q[0] - q1) for q in trace.q) < 1e-4, "joint1 moved"
    assert abs(trace.q[-1][1] - (-0.2)) < 1e-3
    assert max(v[1] for v in trace.v) > 0.2  # joint2 really moved


def test_cancel_stops_every_joint_together(two_slides):
    session, executor = two_slides
    trace = Trace.attach(session, executor)
    session.loop.run(duration_s=0.1)
    # joint1 -0.5 -> -0.1 and joint2 -0.6 -> -0.4 in 2 s: 0.3 and 0.15 m/s at mid-move.
    handle = executor.submit(goal((2.0, (-0.1, -0.4)), joints=("joint1", "joint2")),
                             now_s=session.loop.time_s)
    session.loop.run(duration_s=1.0)
    v0 = trace.v_ref[-1]
    assert v0[0] == pytest.approx(0.3, abs=0.01) and v0[1] == pytest.approx(0.15, abs=0.01)
    handle.cancel()
    c = len(trace.t)
    session.loop.run(duration_s=1.0)
    assert handle.status is GoalStatus.PREEMPTED
    stopped = [next(i for i in range(c, len(trace.t)) if trace.v_ref[i][j] == 0.0) for j in (0, 1)]
    assert stopped[0] == stopped[1], "the joints did not stop together"
    assert (trace.t[stopped[0]] - trace.t[c]) <= max(abs(v) for v in v0) / 5.0 + DT + 1e-9
    for i in range(c, len(trace.t)):
        for j in (0, 1):
            assert abs(trace.v_ref[i][j] - trace.v_ref[i - 1][j]) / DT <= 5.0 + 1e-6
    assert all(abs(v) < 1e-3 for v in session.hardware.velocity)


def test_a_partial_goal_during_a_move_does_not_freeze_the_omitted_joint(two_slides):
    session, executor = two_slides
    trace = Trace.attach(session, executor)
    session.loop.run(duration_s=0.1)
    executor.submit(goal((2.0, (-0.1, -0.4)), joints=("joint1", "joint2")), now_s=session.loop.time_s)
    session.loop.run(duration_s=1.0)
    assert trace.v_ref[-1][0] == pytest.approx(0.3, abs=0.01)
    b = executor.submit(goal((1.0, -0.5), joints=("joint2",)), now_s=session.loop.time_s)
    session.loop.run(duration_s=1.5)
    s = trace.first_active(b.id)
    jump = abs(trace.v_ref[s][0] - trace.v_ref[s - 1][0])
    rates = [abs(trace.v_ref[i][0] - trace.v_ref[i - 1][0]) / DT for i in range(s, len(trace.t))]
    assert jump < 1e-6 or max(rates) <= 5.0 + 1e-6, (
        f"joint1's desired velocity steps {trace.v_ref[s - 1][0]} -> {trace.v_ref[s][0]} m/s in one cycle")


# ----------------------------------------------------------------------------- path timing


def test_plan_path_times_a_path_from_the_desired_pose_with_the_default_limits(two_slides):
    session, executor = two_slides
    session.loop.run(duration_s=0.1)
    assert executor.path_velocity_fraction == PATH_VELOCITY_FRACTION
    assert executor.max_acceleration == (PATH_MAX_ACCELERATION,) * 2
    assert executor.max_jerk == (PATH_MAX_JERK,) * 2
    vmax = [spec.max_velocity for spec in executor.specs]
    for timing in ("ruckig", "chapter"):
        planned = executor.plan_path([[-0.2, -0.3], [-0.4, -0.1]], timing=timing)
        assert planned == time_path(("joint1", "joint2"), [-0.5, -0.6], [[-0.2, -0.3], [-0.4, -0.1]], vmax,
                                    timing=timing)
    one = executor.plan_path([[-0.2]], timing="chapter", joint_names=["joint2"])
    assert one.joint_names == ("joint2",) and one.points[0].positions == (-0.6,)
    done = Done()
    executor.submit(executor.plan_path([[-0.2, -0.3]]), now_s=session.loop.time_s, on_done=done)
    session.loop.run(duration_s=3.0)
    assert done.only.status is GoalStatus.SUCCEEDED


def test_plan_path_uses_the_executors_timing_parameters(write_scenario):
    session = build(write_scenario, {TRAJ: {"path_velocity_fraction": 0.25, "max_acceleration": 3.0,
                                            "max_jerk": {"joint1": 40.0}}})
    executor = executor_of(session)
    session.loop.run(cycles=1)
    planned = executor.plan_path([[-0.1]])
    assert planned == time_path(("joint1",), [-0.5], [[-0.1]], [executor.specs[0].max_velocity],
                                velocity_fraction=0.25, max_acceleration=3.0, max_jerk=40.0)


def test_every_goal_is_kept_in_the_history_refusals_too(write_scenario):
    """What a run's record lists: a goal that ran, one refused by submit, one refused on arrival by the queued
    servers' shape check, in the order they came, each with its end and the time it ended."""
    session = build(write_scenario)
    executor = executor_of(session)
    session.loop.run(duration_s=0.2)
    ran = executor.submit(goal((0.5, -0.3)), now_s=session.loop.time_s)
    session.loop.run(duration_s=0.7)
    with pytest.raises(InvalidTrajectory):
        executor.submit(goal((0.5, 5.0)), now_s=session.loop.time_s)
    with pytest.raises(InvalidTrajectory, match="upper limit"):
        executor.check_goal_shape(goal((0.5, 7.0)))
    history = list(executor.goals.history)
    assert [h.id for h in history] == [1, 2, 3] and history[0] is ran
    assert [h.status for h in history] == [GoalStatus.SUCCEEDED, GoalStatus.REJECTED, GoalStatus.REJECTED]
    assert "5.0" in history[1].result.error_string and "7.0" in history[2].result.error_string
    assert history[2].result.time_s == pytest.approx(0.9, abs=2e-3)  # the last cycle's loop time (0.2 + 0.7 s run)

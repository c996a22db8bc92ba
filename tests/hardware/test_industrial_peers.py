"""The arm's goals through IndustrialHardware against controllers of the kinds users own
(tests/hardware/controller_doubles.py): each goal succeeds at its target, a cancel stops the robot, and
the points on the wire are what ROS-I's client sends for the same goal (speed fraction and duration,
to float32), or, as JOINT_TRAJ_PT_FULL, the goal's own times, positions and velocities."""

from __future__ import annotations

import contextlib
import time

import numpy as np
import pytest

from jointctl.hardware.industrial import IndustrialHardware
from jointctl.model.loader import load_robot_model
from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot
from jointctl.trajectory.goals import GoalStatus
from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint
from jointctl.hardware.interface import POSITION
from jointctl.wire.simple_message import STOP_TRAJECTORY, VALID_POSITION, VALID_TIME, VALID_VELOCITY, JointTrajPtFull
from tests.hardware.controller_doubles import (
    ERROR_RANGE,
    ERROR_TOO_FAST,
    KINDS,
    LAG_S,
    ControllerDouble,
    asked_values,
    ros_i_fraction,
)
from tests.waiting import wait_until

SCENARIO = scenario_for_robot("arm7dof", "industrial")
ROBOT = load_robot_model(SCENARIO.robot.description)
JOINTS = tuple(j.name for j in ROBOT.movable_joints)
VMAX = tuple(j.range_and_speed()[2] for j in ROBOT.movable_joints)
RANGES = tuple(j.range_and_speed()[:2] for j in ROBOT.movable_joints)
PRE_POSE = (0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0)
GOAL_TOLERANCE = 0.01  # rad: the arm's industrial file
#: Loop time allowed for a goal beyond its end: the "speed" double runs the last segment (zero
#: velocity: ROS-I's 10 % default) at 0.02 rad/s, about a second more for this goal.
MARGIN_S = 4.0


def smooth_goal(delta: float, duration_s: float, points: int = 3) -> JointTrajectory:
    """Every joint from the pre-pose by ``delta`` [rad] along a smoothstep, ``points`` points with
    velocities (the last at rest)."""
    times = duration_s * np.arange(1, points + 1) / points
    tau = times / duration_s
    s, ds = 3 * tau**2 - 2 * tau**3, 6 * tau * (1 - tau) / duration_s
    rows = [JointTrajectoryPoint(positions=tuple(q + delta * si for q in PRE_POSE),
                                 velocities=tuple(delta * dsi for _ in PRE_POSE), time_from_start_s=float(t))
            for t, si, dsi in zip(times, s, ds)]
    return JointTrajectory(JOINTS, tuple(rows))


@contextlib.contextmanager
def arm_against(kind: str, double: dict | None = None, **options):
    """(double, session, executor): the arm's industrial session on IndustrialHardware connected to a
    controller double of ``kind`` (with the URDF's speed limits and ranges, unless ``double``, options
    of the double, says otherwise); ``options`` for the hardware (``message``...). State is stale after
    30 s, not 1: none of these tests is about stale state, and a loaded machine may hold a thread 1 s."""
    settings = {"ranges": RANGES, **(double or {})}
    limits = settings.pop("max_velocities", VMAX)
    controller = ControllerDouble(kind, PRE_POSE, limits, **settings)
    hardware = IndustrialHardware(JOINTS, robot_ip="127.0.0.1", motion_port=controller.motion_port,
                                  state_port=controller.state_port, max_velocities=VMAX,
                                  **{"stale_after_s": 30.0, **options})
    try:
        hardware.connect()
        session = Session(SCENARIO, hardware=hardware, realtime=True)
        yield controller, session, session.manager.controller("arm7dof_trajectory_controller")
    finally:
        hardware.close()
        controller.close()


@pytest.fixture(params=KINDS)
def arm(request):
    kind = request.param
    with arm_against(kind, message="full" if kind == "full" else "pt") as (double, session, executor):
        yield kind, double, session, executor


def run_until(session, condition, limit_s: float) -> None:
    """Run the loop until ``condition()`` holds at the start of a cycle (or ``limit_s`` of loop time)."""
    def check(_time_s: float) -> None:
        if condition():
            session.loop.request_stop()

    session.loop.add_input(check)
    try:
        session.run(limit_s)
    finally:
        session.loop.remove_input(check)


def run_until_done(session, handle, limit_s: float) -> None:
    """Run the loop until the goal ends (or ``limit_s`` of loop time)."""
    run_until(session, lambda: handle.done, limit_s)


def test_a_goal_succeeds_at_its_target_and_the_wire_carries_what_ros_is_client_sends(arm) -> None:
    kind, double, session, executor = arm
    goal = smooth_goal(0.08, 1.2)
    handle = executor.submit(goal, now_s=session.loop.time_s)
    run_until_done(session, handle, 1.2 + MARGIN_S)
    assert handle.status is GoalStatus.SUCCEEDED, handle.result
    target = np.array(goal.points[-1].positions)
    assert np.abs(np.array(double.positions) - target).max() < GOAL_TOLERANCE

    sent = double.trajectory_points()
    assert [m.sequence for m in sent] == [0, 1, 2]  # the goal's own points, a new trajectory
    times = [p.time_from_start_s for p in goal.points]
    for k, (message, point) in enumerate(zip(sent, goal.points)):
        assert message.positions[:7] == pytest.approx(np.float32(point.positions), abs=1e-6)
        assert message.positions[7:] == (0.0,) * 3
        if kind == "full":
            assert isinstance(message, JointTrajPtFull)
            assert message.valid_fields & (VALID_TIME | VALID_POSITION | VALID_VELOCITY) == 0x07
            assert message.time == pytest.approx(np.float32(times[k]))
            assert message.velocities[:7] == pytest.approx(np.float32(point.velocities), abs=1e-7)
        else:
            previous = times[k - 1] if k else 0.0
            assert message.duration == pytest.approx(np.float32(times[k] - previous), rel=1e-6)
            assert message.velocity == pytest.approx(np.float32(ros_i_fraction(point.velocities, VMAX)), rel=1e-6)
    if kind != "full":
        # the worked numbers: 0.08 rad x 6 tau (1 - tau) / 1.2 s at tau = 1/3 and 2/3 is 0.0889 rad/s, 0.444
        # of joint0's 0.2 rad/s; the last point at rest gets ROS-I's 10 % default, never 0
        assert [m.velocity for m in sent] == pytest.approx([0.4444444, 0.4444444, 0.1], rel=1e-6)


def test_a_cancel_stops_the_robot_short_of_the_goal(arm) -> None:
    kind, double, session, executor = arm
    goal = smooth_goal(0.3, 3.0, points=2)
    handle = executor.submit(goal, now_s=session.loop.time_s)
    session.run(1.5)
    assert double.moving
    handle.cancel()
    run_until_done(session, handle, 1.0)
    assert handle.status is GoalStatus.PREEMPTED, handle.result
    hardware = session.hardware
    run_until(session, lambda: double.stops >= 1 and not double.moving and hardware.fault is None, 3.0)
    assert double.stops >= 1 and not double.moving and hardware.fault is None
    rest = np.array(double.positions)
    # The STOP halted the interpolator; the joints, trailing it through the servo lag, came to rest on it,
    # beyond where they were measured then by their following error: at most v x lag_s for the fastest
    # segment any kind runs of this goal (0.15 rad/s: the "speed" kind at 0.75 of joint0's 0.2 rad/s).
    measured, halted = double.halts[0]
    assert rest == pytest.approx(halted, abs=ControllerDouble.SETTLED)
    coast = np.abs(rest - np.array(measured)).max()
    assert 0.0 < coast <= 0.15 * LAG_S
    holds_after(double, session, [0, 1, STOP_TRAJECTORY])
    travelled = np.abs(rest - np.array(PRE_POSE)).max()
    assert 0.0 < travelled < 0.3 - 0.05  # it moved, and stopped well short of the goal's 0.3 rad


def holds_after(double: ControllerDouble, session, sequences) -> None:
    """The robot, at rest, stays there: the hold is where it came to rest (the position command, to
    float32), nothing is sent after the points numbered ``sequences`` (a point put in the outbox while
    the loop ran has reached the double once the outbox is empty and no reply is awaited), and
    the joints have not moved after 0.3 s more of the loop."""
    hardware = session.hardware
    run_until(session, lambda: not double.moving and hardware.fault is None, 3.0)
    rest = np.array(double.positions)
    session.run(0.3)
    wait_until(lambda: hardware._outbox.qsize() == 0 and hardware._awaiting_reply_since is None,
               what="the hardware's outbox empty, no reply awaited")
    assert [m.sequence for m in double.points] == sequences  # nothing further sent
    assert np.array(double.positions) == pytest.approx(rest, abs=1e-9)  # it stays where it came to rest
    assert list(hardware.command_buffer(POSITION)) == pytest.approx(rest.tolist(), abs=1e-6)  # the hold is the rest


def ramp_goal(steps, times) -> JointTrajectory:
    """joint0 from the pre-pose by ``steps`` [rad] at ``times`` [s] (positions only), the others held."""
    return JointTrajectory(JOINTS, tuple(
        JointTrajectoryPoint(positions=(PRE_POSE[0] + d,) + PRE_POSE[1:], time_from_start_s=t)
        for d, t in zip(steps, times)))


def test_a_point_beyond_the_controllers_soft_limit_aborts_the_goal_naming_the_joint_and_the_robot_holds() -> None:
    # The controller's soft limit of joint3 (-1.93 rad) is narrower than the URDF's (2.7 rad): the executor
    # accepts the goal, and the controller refuses its point 2 (joint3 at -2 + 0.08 = -1.92 rad), which it takes
    # (room for one point) once point 0's segment has run, the robot moving. Its FAILURE reply leaves 50 ms
    # after the STATUS error (the request was sent 0.4 s before: held by the flow control). The goal is aborted
    # naming the point, the error code, the joint and its value; the robot comes to rest where the controller
    # halted and stays.
    ranges = list(RANGES)
    ranges[3] = (RANGES[3][0], -1.93)
    with arm_against("duration", {"ranges": ranges, "capacity": 1, "failure_reply_delay_s": 0.05}) as (
            double, session, executor):
        goal = smooth_goal(0.08, 1.2)
        handle = executor.submit(goal, now_s=session.loop.time_s)
        run_until_done(session, handle, 1.2 + MARGIN_S)
        assert handle.status is GoalStatus.ABORTED, handle.result
        message = handle.result.error_string
        assert f"the controller refused point 2 of the trajectory (FAILURE; STATUS error_code {ERROR_RANGE})" \
            in message
        asked = asked_values(message, JOINTS)
        assert asked["joint3"][0] == pytest.approx(-1.92, abs=1e-6)
        # at 0.08 x (1 - s(2/3)) / 0.4 s = 0.0519 rad/s from point 1 (s the smoothstep: s(2/3) = 20/27)
        assert asked["joint3"][1] == pytest.approx(0.08 * 7 / 27 / 0.4, rel=1e-5)
        measured, halted = double.halts[0]
        assert np.abs(np.array(halted) - np.array(PRE_POSE)).max() > 0.0  # it was on its way
        holds_after(double, session, [0, 1, 2])
        assert double.positions == pytest.approx(halted, abs=ControllerDouble.SETTLED)


def test_a_point_faster_than_the_controller_allows_aborts_the_goal_naming_the_joint_and_the_robot_holds() -> None:
    # A controller whose joint0 is limited to 0.1 rad/s (half the URDF's 0.2: a reduced-speed mode). The goal
    # (within the URDF's limit) moves joint0 0.02 rad in 0.4 s twice (0.05 rad/s), then 0.03 rad in 0.2 s:
    # 0.15 rad/s. The controller takes point 2 once point 0's segment has run (room for one point), the robot
    # moving, and refuses it; the goal is aborted naming the joint and the speed asked; the robot holds.
    limits = list(VMAX)
    limits[0] = 0.1
    with arm_against("duration", {"max_velocities": limits, "capacity": 1}) as (double, session, executor):
        handle = executor.submit(ramp_goal([0.02, 0.04, 0.07], [0.4, 0.8, 1.0]), now_s=session.loop.time_s)
        run_until_done(session, handle, 1.0 + MARGIN_S)
        assert handle.status is GoalStatus.ABORTED, handle.result
        message = handle.result.error_string
        assert f"the controller refused point 2 of the trajectory (FAILURE; STATUS error_code {ERROR_TOO_FAST})" \
            in message
        asked = asked_values(message, JOINTS)
        assert asked["joint0"] == pytest.approx((PRE_POSE[0] + 0.07, 0.15), rel=1e-5)
        assert asked["joint1"] == pytest.approx((PRE_POSE[1], 0.0), abs=1e-6)
        measured, halted = double.halts[0]
        assert halted[0] - PRE_POSE[0] > 0.0  # it was on its way
        holds_after(double, session, [0, 1, 2])
        assert double.positions == pytest.approx(halted, abs=ControllerDouble.SETTLED)


@pytest.mark.parametrize("failure_reply_delay_s, stale_status", [(0.0, False), (0.05, False), (0.0, True)])
def test_a_failure_reply_aborts_the_goal_at_once_naming_the_point_and_the_error_code(failure_reply_delay_s,
                                                                                     stale_status) -> None:
    # A controller that takes only JOINT_TRAJ_PT_FULL, sent JOINT_TRAJ_PT: it answers FAILURE (and
    # reports STATUS error_code 22); the goal ends long before its 3 s. With the reply 50 ms late (five of
    # its status periods: the error STATUS comes first), the fault still names the point. With a STATUS
    # without the error read after the reply (sent before the refusal), the code still comes from the next.
    with arm_against("full", {"failure_reply_delay_s": failure_reply_delay_s,
                              "stale_status_after_failure": stale_status}, message="pt") as (double, session, executor):
        handle = executor.submit(smooth_goal(0.1, 3.0), now_s=session.loop.time_s)
        run_until_done(session, handle, 3.0)
        assert handle.status is GoalStatus.ABORTED
        assert handle.result.time_s < 1.0  # before the goal's first point is even due (loop time)
        assert "the controller refused point 0 of the trajectory (FAILURE; STATUS error_code 22)" in \
            handle.result.error_string
        assert [m.sequence for m in double.points] == [0]  # the rest of the goal was not sent
        assert double.positions == pytest.approx(list(PRE_POSE))  # nothing moved


def test_a_streamed_command_as_full_points_carries_times_from_the_motions_start() -> None:
    with arm_against("full", message="full") as (double, session, _):
        hardware = session.hardware
        command = hardware.command_buffer(POSITION)
        for k in range(60):  # 60 ms of loop time, joint0 moving 0.1 rad/s
            command[0] = PRE_POSE[0] + 1e-4 * (k + 1)
            hardware.read()
            hardware.write()
            hardware.advance(0.001)
        wait_until(lambda: len(double.points) >= 3, what="three points at the controller", timeout_s=5.0)
        sent = list(double.points)
        assert [m.sequence for m in sent] == [0, 1, 2]  # one every 20 ms, from a new trajectory
        assert [m.time for m in sent] == pytest.approx([0.02, 0.04, 0.06], rel=1e-6)
        assert [m.positions[0] for m in sent] == pytest.approx([1e-4, 21e-4, 41e-4], abs=1e-7)


def test_a_failure_reply_without_an_error_status_aborts_the_goal_naming_the_point() -> None:
    # A controller that answers FAILURE but never sets STATUS in_error: the refusal is the reply alone,
    # reported once the error code has had its chance to arrive, without one.
    with arm_against("full", {"error_status": False}, message="pt") as (double, session, executor):
        handle = executor.submit(smooth_goal(0.1, 3.0), now_s=session.loop.time_s)
        run_until_done(session, handle, 3.0 + MARGIN_S)
        assert handle.status is GoalStatus.ABORTED
        assert "the controller refused point 0 of the trajectory (FAILURE; no error code reported)" in \
            handle.result.error_string
        assert [m.sequence for m in double.points] == [0]  # the rest of the goal was not sent
        assert double.positions == pytest.approx(list(PRE_POSE))  # nothing moved


def test_a_download_refused_by_the_status_alone_aborts_the_goal_with_the_error_code() -> None:
    # Download: every point is a topic, nothing is answered; the "full" controller refuses the
    # JOINT_TRAJ_PT points by its STATUS only (in_error, error_code 22). The goal aborts on that STATUS.
    with arm_against("full", message="pt", motion="download") as (double, session, executor):
        handle = executor.submit(smooth_goal(0.1, 3.0), now_s=session.loop.time_s)
        run_until_done(session, handle, 3.0 + MARGIN_S)
        assert handle.status is GoalStatus.ABORTED
        assert "the controller refused a point (STATUS error_code 22)" in handle.result.error_string
        assert [m.sequence for m in double.points] == [-1, 1, -3]  # the whole goal, as topics
        assert double.positions == pytest.approx(list(PRE_POSE))  # nothing moved


def test_a_download_runs_the_goal_after_its_last_point() -> None:
    # The success path of the same handshake, against the "duration" double: the positive control of the
    # test above (the download double executes a goal it accepts).
    with arm_against("duration", motion="download") as (double, session, executor):
        goal = smooth_goal(0.08, 1.2)
        handle = executor.submit(goal, now_s=session.loop.time_s)
        run_until_done(session, handle, 1.2 + MARGIN_S)
        assert handle.status is GoalStatus.SUCCEEDED, handle.result
        assert [m.sequence for m in double.trajectory_points()] == [-1, 1, -3]
        assert np.abs(np.array(double.positions) - np.array(goal.points[-1].positions)).max() < GOAL_TOLERANCE


def test_the_velocity_is_the_difference_of_the_last_two_reports_over_their_arrival_times() -> None:
    # The test decides when each report leaves: a report sent after t_sent arrives after it, and was read
    # by t_seen, so the hardware's interval between two reports lies within [t_sent2 - t_seen1,
    # t_seen2 - t_sent1], and its velocity Δq / interval within the bounds that follow, whatever the load.
    double = ControllerDouble("duration", PRE_POSE, VMAX, ranges=RANGES, state_period_s=None)
    hardware = IndustrialHardware(JOINTS, robot_ip="127.0.0.1", motion_port=double.motion_port,
                                  state_port=double.state_port, max_velocities=VMAX, stale_after_s=1e9)
    try:
        hardware.connect()  # the report sent on connect
        hardware.read()
        assert hardware.velocity == [0.0] * len(JOINTS)  # one report: nothing to difference

        def send(positions) -> tuple[float, float]:
            double.place(positions)
            reports = hardware.state_reports
            sent = time.monotonic()
            double.report()
            wait_until(lambda: hardware.state_reports != reports, what="the report read")
            return sent, time.monotonic()

        sent1, seen1 = send(PRE_POSE)
        hardware.read()
        assert hardware.velocity == [0.0] * len(JOINTS)  # the same positions again: at rest
        moved = [q + d for q, d in zip(PRE_POSE, (0.01, -0.02, 0.0, 0.005, 0.03, -0.001, 0.0))]
        sent2, seen2 = send(moved)
        hardware.read()
        dq = np.float32(moved) - np.float32(PRE_POSE)  # float32 on the wire
        shortest, longest = sent2 - seen1, seen2 - sent1
        assert 0 < shortest <= longest
        for v, d in zip(hardware.velocity, dq):
            low, high = sorted((d / longest, d / shortest))
            assert low * (1 - 1e-6) - 1e-12 <= v <= high * (1 + 1e-6) + 1e-12, (v, d, shortest, longest)
        # one interval for all joints: the velocities are in the ratio of the steps
        assert np.array(hardware.velocity) * float(dq[0]) == pytest.approx(dq * hardware.velocity[0], rel=1e-5)
    finally:
        hardware.close()
        double.close()


def test_resampled_points_are_the_goal_every_stream_period() -> None:
    # points="resampled" at 50 Hz: a 1.2 s goal goes as 60 points 20 ms apart, each the goal's smoothstep at its
    # time (a cubic: the executor's cubic interpolation between the goal's points with their velocities is the
    # smoothstep itself), with ROS-I's speed fraction of the goal's velocity then.
    delta, duration_s, period_s = 0.08, 1.2, 0.02
    with arm_against("duration", points="resampled", stream_rate_hz=1 / period_s) as (double, session, executor):
        goal = smooth_goal(delta, duration_s)
        handle = executor.submit(goal, now_s=session.loop.time_s)
        run_until_done(session, handle, duration_s + MARGIN_S)
        assert handle.status is GoalStatus.SUCCEEDED, handle.result
        sent = double.trajectory_points()
    count = round(duration_s / period_s)
    assert [m.sequence for m in sent] == list(range(count))
    assert [m.duration for m in sent] == pytest.approx([period_s] * count, abs=1e-6)
    times = period_s * np.arange(1, count + 1)
    tau = times / duration_s
    s, ds = 3 * tau**2 - 2 * tau**3, 6 * tau * (1 - tau) / duration_s
    # The goal is handed over at most one 1 ms loop cycle after its start: the samples may lead by that much.
    slack = delta * 1.5 / duration_s * 0.001 + 1e-6
    for message, si, dsi in zip(sent, s, ds):
        assert message.positions[:7] == pytest.approx([q + delta * si for q in PRE_POSE], abs=slack)
        assert message.velocity == pytest.approx(ros_i_fraction([delta * dsi] * 7, VMAX), abs=0.01)

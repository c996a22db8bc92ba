"""The simulated industrial controller's trajectory generator, against the arithmetic of linear
segments and constant-deceleration stops."""

from __future__ import annotations

import math

import pytest

from jointctl.industrial.interpolator import (
    ERROR_BAD_DURATION,
    ERROR_BAD_VELOCITY,
    ERROR_JOINT_COUNT,
    ERROR_NOT_FINITE,
    ERROR_POSITION_LIMIT,
    Interpolator,
    JointLimits,
    Point,
    QueueFull,
    RefusedPoint,
)
from jointctl.model import load_robot_model
from jointctl.paths import robots_dir

LIMITS = (JointLimits(-1.0, 1.0, 2.0, 10.0), JointLimits(-math.inf, math.inf, 1.0, 5.0))


def run(interp: Interpolator, seconds: float, dt: float = 0.001):
    for _ in range(round(seconds / dt)):
        q, v = interp.step(dt)
    return list(q), list(v)


def test_a_single_point_is_reached_linearly_in_its_duration() -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.4, -0.2), 0.0, 1.0))
    q, v = run(interp, 0.5)
    assert q == pytest.approx([0.2, -0.1], abs=1e-12)  # the midpoint at T/2
    assert v == pytest.approx([0.4, -0.2], abs=1e-12)  # Δq / T
    assert interp.in_motion
    q, v = run(interp, 0.5)
    assert q == [0.4, -0.2] and v == [0.0, 0.0]
    assert not interp.in_motion


def test_the_speed_fraction_and_the_limits_stretch_the_segment() -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((1.0, 0.0), 0.25, 0.1))  # 1 rad at 0.25 x 2 rad/s: 2 s, not 0.1 s
    q, _ = run(interp, 1.0)
    assert q[0] == pytest.approx(0.5, abs=1e-12)
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.0, 3.0), 0.0, 0.1))  # no fraction: joint 1's 1 rad/s limit, 3 s
    q, _ = run(interp, 1.5)
    assert q[1] == pytest.approx(1.5, abs=1e-12)


def test_short_segments_cross_within_a_step_without_drift() -> None:
    points = [Point((0.01 * k, -0.02 * k), 0.0, 0.02) for k in range(1, 51)]
    fine, coarse = Interpolator(LIMITS, [0.0, 0.0], capacity=64), Interpolator(LIMITS, [0.0, 0.0], capacity=64)
    for p in points:
        fine.push(p)
        coarse.push(p)
    q_fine, _ = run(fine, 1.0, 0.001)
    q_coarse, _ = run(coarse, 1.001, 0.007)  # 143 steps of 7 ms, crossing segment boundaries
    assert q_fine == pytest.approx([0.5, -1.0], abs=1e-12)
    assert q_coarse == pytest.approx([0.5, -1.0], abs=1e-12)
    # Mid-way, where a 7 ms step lands inside segment k: the line through its ends.
    interp = Interpolator(LIMITS, [0.0, 0.0], capacity=64)
    for p in points:
        interp.push(p)
    q, _ = run(interp, 0.035, 0.007)
    assert q == pytest.approx([0.0175, -0.035], abs=1e-12)


@pytest.mark.parametrize(("point", "field", "code"), [
    (Point((math.nan, 0.0), 0.0, 1.0), "positions[0]", ERROR_NOT_FINITE),
    (Point((0.0, math.inf), 0.0, 1.0), "positions[1]", ERROR_NOT_FINITE),
    (Point((1.5, 0.0), 0.0, 1.0), "positions[0]", ERROR_POSITION_LIMIT),
    (Point((0.1, 0.0), -0.1, 1.0), "velocity", ERROR_BAD_VELOCITY),
    (Point((0.1, 0.0), 1.5, 1.0), "velocity", ERROR_BAD_VELOCITY),
    (Point((0.1, 0.0), 0.0, -1.0), "duration", ERROR_BAD_DURATION),
    (Point((0.1, 0.0), 0.0, math.nan), "duration", ERROR_NOT_FINITE),
    (Point((0.1,), 0.0, 1.0), "positions", ERROR_JOINT_COUNT),
])
def test_refused_points_change_nothing(point, field, code) -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.2, 0.0), 0.0, 0.2))
    run(interp, 0.1)
    before = (list(interp.position), len(interp))
    with pytest.raises(RefusedPoint) as info:
        interp.push(point)
    assert (info.value.field, info.value.error_code) == (field, code)
    assert (list(interp.position), len(interp)) == before
    q, _ = run(interp, 0.1)  # it carries on to the good point
    assert q == pytest.approx([0.2, 0.0], abs=1e-12)


def test_the_queue_is_bounded_and_a_new_trajectory_drops_it() -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0], capacity=2)
    interp.push(Point((0.1, 0.0), 0.0, 1.0))
    interp.push(Point((0.2, 0.0), 0.0, 1.0))
    assert interp.full
    with pytest.raises(QueueFull):
        interp.push(Point((0.3, 0.0), 0.0, 1.0))
    run(interp, 0.5)  # half-way to 0.1
    interp.new_trajectory()
    interp.push(Point((-0.05, 0.0), 0.0, 1.0))
    q, _ = run(interp, 0.5)
    assert q[0] == pytest.approx(0.05 + (-0.05 - 0.05) / 2, abs=1e-12)  # from 0.05, not from 0.1
    q, _ = run(interp, 0.5)
    assert q[0] == pytest.approx(-0.05, abs=1e-12) and not interp.in_motion


def test_a_stop_from_full_speed_brakes_at_the_deceleration() -> None:
    interp = Interpolator(LIMITS, [-1.0, 0.0])
    interp.push(Point((1.0, 0.0), 1.0, 0.0))  # 2 m at the limit 2 /s: 1 s
    q0, v0 = run(interp, 0.3)
    assert v0[0] == pytest.approx(2.0)
    interp.stop()
    steps = 0
    while interp.in_motion:
        q, v = interp.step(0.001)
        steps += 1
    assert q[0] - q0[0] == pytest.approx(2.0**2 / (2 * 10.0), abs=1e-9)  # v²/2a
    assert abs(steps * 0.001 - 2.0 / 10.0) <= 0.001  # v/a, within a step
    assert v == [0.0, 0.0]


def test_a_stop_near_a_limit_stays_inside_it() -> None:
    interp = Interpolator(LIMITS, [0.9, 0.0])
    interp.push(Point((1.0, 0.0), 1.0, 0.0))
    run(interp, 0.045)  # 2 /s, 0.01 from the limit: braking needs 0.2
    interp.stop()
    while interp.in_motion:
        q, _ = interp.step(0.001)
        assert q[0] <= 1.0
    assert q[0] == pytest.approx(1.0)


def test_limits_from_the_arm_model() -> None:
    robot = load_robot_model(robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro")
    names = [j.name for j in robot.movable_joints]
    limits = JointLimits.from_model(robot, names, stop_time_s=0.5)
    for name, lim in zip(names, limits):
        urdf = robot.joint(name).limits
        assert (lim.lower, lim.upper, lim.velocity) == (urdf.lower, urdf.upper, urdf.velocity)
        assert lim.deceleration == pytest.approx(urdf.velocity / 0.5)

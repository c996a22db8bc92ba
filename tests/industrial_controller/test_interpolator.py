"""The simulated industrial controller's trajectory generator, against the arithmetic of linear
segments (T = max(duration, |Δq|/(v_frac·vmax), |Δq|/vmax)) and constant-deceleration stops
(distance v²/2a, time v/a)."""

from __future__ import annotations

import math
import struct

import pytest

from jointctl.errors import JointCtlError
from jointctl.industrial_controller.interpolator import (
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
from jointctl.model.robot_model import Joint, Link, RobotModel
from jointctl.model.robot_model import JointLimits as UrdfLimits
from jointctl.paths import robots_dir

# joint 0: range [-1, 1] rad, 2 rad/s, stops at 10 rad/s²; joint 1: no range, 1 rad/s, 4 rad/s².
LIMITS = (JointLimits(-1.0, 1.0, 2.0, 10.0), JointLimits(-math.inf, math.inf, 1.0, 4.0))
DT = 0.001


def run(interp: Interpolator, steps: int, dt: float = DT) -> tuple[list[float], list[float]]:
    q, v = interp.position, interp.velocity
    for _ in range(steps):
        q, v = interp.step(dt)
    return q, v


def float32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


# -- segments ------------------------------------------------------------------------------------
def test_a_single_point_is_reached_linearly_and_exactly_in_its_duration() -> None:
    # (-0.9, -3.0) -> (0.7, -0.9): in floats, start + (end - start) is not end for either joint.
    start, end = (-0.9, -3.0), (0.7, -0.9)
    assert [a + (b - a) for a, b in zip(start, end)] != list(end)
    interp = Interpolator(LIMITS, start)
    interp.push(Point(end, 1.0, 4.0))  # slowest joint: 2.1 rad at 1 rad/s = 2.1 s < 4 s
    q, v = run(interp, 2000)
    assert q == pytest.approx([-0.1, -1.95], abs=1e-12)  # the midpoint at T/2
    assert v == pytest.approx([1.6 / 4.0, 2.1 / 4.0], abs=1e-12)  # Δq / T
    q, v = run(interp, 1999)
    assert interp.in_motion and q[0] < 0.7
    q, v = run(interp, 1)  # t = T
    assert q == [0.7, -0.9] and v == [0.0, 0.0]  # the point itself, bit for bit
    assert not interp.in_motion and len(interp) == 0


def test_the_speed_fraction_stretches_the_segment() -> None:
    interp = Interpolator(LIMITS, [-0.5, 0.0])
    interp.push(Point((0.5, 0.0), 0.25, 0.1))  # 1 rad at 0.25 x 2 rad/s: T = 2 s, not 0.1 s
    q, v = run(interp, 1000)
    assert q[0] == pytest.approx(0.0, abs=1e-12) and v[0] == pytest.approx(0.5, abs=1e-12)
    run(interp, 999)
    assert interp.in_motion
    q, _ = run(interp, 1)
    assert q == [0.5, 0.0] and not interp.in_motion


def test_without_a_fraction_the_limits_stretch_the_segment_and_the_slowest_joint_sets_it() -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.0, 3.0), 1.0, 0.1))  # fraction 1: joint 1 at its 1 rad/s, T = 3 s
    q, v = run(interp, 1500)
    assert q[1] == pytest.approx(1.5, abs=1e-12) and v == pytest.approx([0.0, 1.0], abs=1e-12)
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((1.0, 1.0), 1.0, 0.0))  # joint 0 needs 0.5 s, joint 1 needs 1 s: both take 1 s
    q, v = run(interp, 500)
    assert q == pytest.approx([0.5, 0.5], abs=1e-12) and v == pytest.approx([1.0, 1.0], abs=1e-12)


def test_a_duration_longer_than_the_limits_need_is_kept() -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.2, 0.0), 1.0, 2.0))  # 0.1 s at full speed, but 2 s asked
    q, v = run(interp, 1000)
    assert q[0] == pytest.approx(0.1, abs=1e-12) and v[0] == pytest.approx(0.1, abs=1e-12)


def test_a_point_where_the_reference_is_completes_at_once_or_dwells_for_its_duration() -> None:
    interp = Interpolator(LIMITS, [0.3, 0.0])
    interp.push(Point((0.3, 0.0), 1.0, 0.0))
    q, v = interp.step(0.0)
    assert q == [0.3, 0.0] and v == [0.0, 0.0] and not interp.in_motion
    interp.push(Point((0.3, 0.0), 1.0, 0.0))  # takes no time: the next segment starts at t = 0
    interp.push(Point((0.5, 0.0), 1.0, 1.0))
    q, _ = run(interp, 500)
    assert q[0] == pytest.approx(0.4, abs=1e-12)
    interp = Interpolator(LIMITS, [0.3, 0.0])
    interp.push(Point((0.3, 0.0), 1.0, 0.3))  # a dwell of 0.3 s
    interp.push(Point((0.5, 0.0), 1.0, 1.0))
    q, v = run(interp, 299)
    assert q[0] == 0.3 and v[0] == 0.0 and interp.in_motion and len(interp) == 1
    q, _ = run(interp, 501)  # 0.3 s dwell + 0.5 s of the next segment
    assert q[0] == pytest.approx(0.4, abs=1e-12)


def test_short_segments_crossed_within_a_step_end_where_fine_steps_do() -> None:
    points = [Point((0.01 * k, -0.01 * k), 1.0, 0.02) for k in range(1, 51)]  # 0.5 rad/s, 1 s in all

    def loaded() -> Interpolator:
        interp = Interpolator(LIMITS, [0.0, 0.0], capacity=50)
        for p in points:
            interp.push(p)
        return interp

    fine, coarse = loaded(), loaded()
    q_fine, _ = run(fine, 1000, 0.001)
    q_coarse, _ = run(coarse, 143, 0.007)  # 1.001 s in 7 ms steps: most cross a boundary
    assert q_fine == pytest.approx(q_coarse, abs=1e-12)
    assert q_fine == list(points[-1].positions) == q_coarse
    assert not fine.in_motion and not coarse.in_motion
    # 35 ms: 15 ms into the second segment (0.01 -> 0.02 over 20 ms).
    q, v = run(loaded(), 5, 0.007)
    assert q == pytest.approx([0.0175, -0.0175], abs=1e-12) and v == pytest.approx([0.5, -0.5], abs=1e-12)
    # One 50 ms step crosses two boundaries.
    interp = loaded()
    q, _ = interp.step(0.05)
    assert q == pytest.approx([0.025, -0.025], abs=1e-12) and len(interp) == 47


def test_step_returns_fresh_lists_and_refuses_bad_time_steps() -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.2, 0.0), 1.0, 1.0))
    q, v = interp.step(0.5)
    q[0], v[0] = 99.0, 99.0
    assert interp.position == pytest.approx([0.1, 0.0]) and interp.velocity == pytest.approx([0.2, 0.0])
    for dt in (-0.001, math.nan, math.inf):
        with pytest.raises(JointCtlError) as info:
            interp.step(dt)
        assert info.value.field == "dt"
    assert interp.position == pytest.approx([0.1, 0.0])


# -- refusals ------------------------------------------------------------------------------------
@pytest.mark.parametrize(("point", "field", "value", "code"), [
    (Point((math.nan, 0.0), 1.0, 1.0), "positions[0]", math.nan, ERROR_NOT_FINITE),
    (Point((0.0, math.inf), 1.0, 1.0), "positions[1]", math.inf, ERROR_NOT_FINITE),
    (Point((0.0, -math.inf), 1.0, 1.0), "positions[1]", -math.inf, ERROR_NOT_FINITE),
    (Point((1.5, 0.0), 1.0, 1.0), "positions[0]", 1.5, ERROR_POSITION_LIMIT),
    (Point((-1.2, 0.0), 1.0, 1.0), "positions[0]", -1.2, ERROR_POSITION_LIMIT),
    (Point((0.1, 0.0), -0.1, 1.0), "velocity", -0.1, ERROR_BAD_VELOCITY),
    (Point((0.1, 0.0), 0.0, 1.0), "velocity", 0.0, ERROR_BAD_VELOCITY),  # a fraction of 0 never arrives
    (Point((0.1, 0.0), 1.5, 1.0), "velocity", 1.5, ERROR_BAD_VELOCITY),
    (Point((0.1, 0.0), math.nan, 1.0), "velocity", math.nan, ERROR_NOT_FINITE),
    (Point((0.1, 0.0), 1.0, -1.0), "duration", -1.0, ERROR_BAD_DURATION),
    (Point((0.1, 0.0), 1.0, math.nan), "duration", math.nan, ERROR_NOT_FINITE),
    (Point((0.1, 0.0), 1.0, math.inf), "duration", math.inf, ERROR_NOT_FINITE),
    (Point((0.1,), 1.0, 1.0), "positions", 1, ERROR_JOINT_COUNT),
    (Point((0.1, 0.0, 0.0), 1.0, 1.0), "positions", 3, ERROR_JOINT_COUNT),
])
def test_a_refused_point_names_field_value_and_code_and_changes_nothing(point, field, value, code) -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.2, 0.0), 1.0, 0.2))  # in progress
    interp.push(Point((0.4, 0.0), 1.0, 0.2))  # queued
    run(interp, 100)
    before = (interp.position, interp.velocity, len(interp), interp.in_motion)
    assert before[:3] == (pytest.approx([0.1, 0.0]), pytest.approx([1.0, 0.0]), 1)
    for call in (interp.check, interp.push):
        with pytest.raises(RefusedPoint) as info:
            call(point)
        error = info.value
        assert (error.field, error.error_code, error.code) == (field, code, "refused_point")
        assert error.value == value or (math.isnan(value) and math.isnan(error.value))
        assert field in str(error)
        assert (interp.position, interp.velocity, len(interp), interp.in_motion) == before
    q, _ = run(interp, 300)  # it carries on through both good points
    assert q == [0.4, 0.0] and not interp.in_motion


def test_a_limit_rounded_to_float32_is_accepted_at_the_limit_itself() -> None:
    # simple_message carries float32: 2.7 arrives as 2.700000047683716, above the limit 2.7.
    limits = (JointLimits(-3.1, 2.7, 0.3, 1.5),)
    interp = Interpolator(limits, [2.6])
    assert float32(2.7) > 2.7
    interp.push(Point((float32(2.7),), 1.0, 0.0))
    q, _ = run(interp, 1000)  # 0.1 rad at 0.3 rad/s: 1/3 s
    assert q == [2.7] and not interp.in_motion
    interp.check(Point((-3.1 - 3e-7,), 1.0, 0.0))  # within |limit|·2⁻²³ = 3.7e-7
    for beyond in (2.7 + 1e-6, -3.1 - 4e-7):
        with pytest.raises(RefusedPoint) as info:
            interp.push(Point((beyond,), 1.0, 0.0))
        assert (info.value.field, info.value.value, info.value.error_code) == ("positions[0]", beyond,
                                                                               ERROR_POSITION_LIMIT)


# -- queue and new trajectories ------------------------------------------------------------------
def test_the_queue_is_bounded() -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0], capacity=2)
    interp.push(Point((0.1, 0.0), 1.0, 1.0))
    interp.push(Point((0.2, 0.0), 1.0, 1.0))
    assert interp.full and len(interp) == 2
    with pytest.raises(QueueFull) as info:
        interp.push(Point((0.3, 0.0), 1.0, 1.0))
    assert isinstance(info.value, JointCtlError) and info.value.value == 2 and len(interp) == 2
    interp.step(DT)  # the first point becomes the segment in progress: room for one
    assert not interp.full and len(interp) == 1
    interp.push(Point((0.3, 0.0), 1.0, 1.0))
    q, _ = run(interp, 2999)
    assert q == [0.3, 0.0] and not interp.in_motion


def test_a_new_trajectory_drops_the_queue_and_starts_from_the_reference() -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.1, 0.0), 1.0, 1.0))
    interp.push(Point((0.2, 0.0), 1.0, 1.0))
    q, v = run(interp, 500)  # half-way to 0.1
    assert q[0] == pytest.approx(0.05, abs=1e-12)
    interp.new_trajectory()
    assert len(interp) == 0 and interp.position == q and interp.velocity == v  # the reference is kept
    interp.push(Point((-0.05, 0.0), 1.0, 1.0))
    q, v = run(interp, 500)
    assert q[0] == pytest.approx(0.0, abs=1e-12)  # from 0.05 (not 0.1) to -0.05, half-way
    assert v[0] == pytest.approx(-0.1, abs=1e-12)
    q, _ = run(interp, 500)
    assert q[0] == -0.05 and not interp.in_motion


def test_a_new_trajectory_with_no_point_brakes_instead_of_halting() -> None:
    interp = Interpolator(LIMITS, [-1.0, 0.0])
    interp.push(Point((1.0, 0.0), 1.0, 0.0))  # 2 rad at 2 rad/s
    q0, _ = run(interp, 300)
    interp.new_trajectory()
    q, v = run(interp, 100)
    assert v[0] == pytest.approx(2.0 - 10.0 * 0.1, abs=1e-9)  # ramping down at 10 rad/s²
    q, v = run(interp, 100)
    assert q[0] - q0[0] == pytest.approx(2.0**2 / (2 * 10.0), abs=1e-9) and v == [0.0, 0.0]
    assert not interp.in_motion
    # A point that comes while braking starts from the reference at once.
    interp = Interpolator(LIMITS, [-1.0, 0.0])
    interp.push(Point((1.0, 0.0), 1.0, 0.0))
    run(interp, 300)
    interp.new_trajectory()
    q1, _ = run(interp, 100)  # -0.4 + 0.15
    assert q1[0] == pytest.approx(-0.25, abs=1e-9)
    interp.push(Point((-0.75, 0.0), 1.0, 1.0))
    q, v = run(interp, 500)
    assert q[0] == pytest.approx(-0.5, abs=1e-9) and v[0] == pytest.approx(-0.5, abs=1e-9)


# -- stop ----------------------------------------------------------------------------------------
def test_a_stop_from_full_speed_brakes_each_joint_at_its_deceleration() -> None:
    interp = Interpolator(LIMITS, [-1.0, 0.0])
    interp.push(Point((1.0, -1.0), 1.0, 0.0))  # both at full speed: 2 rad at 2 rad/s, 1 rad at 1 rad/s
    interp.push(Point((0.0, 0.0), 1.0, 0.0))
    q0, v0 = run(interp, 300)
    assert v0 == pytest.approx([2.0, -1.0], abs=1e-12)
    interp.stop()
    assert len(interp) == 0 and interp.in_motion
    at_rest = [None, None]
    steps = 0
    while interp.in_motion:
        q, v = interp.step(DT)
        steps += 1
        for i in (0, 1):
            if at_rest[i] is None and v[i] == 0.0:
                at_rest[i] = steps
        if steps == 100:
            assert v == pytest.approx([2.0 - 10.0 * 0.1, -1.0 + 4.0 * 0.1], abs=1e-9)  # linear ramps
    assert q[0] - q0[0] == pytest.approx(2.0**2 / (2 * 10.0), abs=1e-9)  # v²/2a
    assert q[1] - q0[1] == pytest.approx(-(1.0**2) / (2 * 4.0), abs=1e-9)
    assert abs(at_rest[0] * DT - 2.0 / 10.0) <= DT  # v/a, within one step
    assert abs(at_rest[1] * DT - 1.0 / 4.0) <= DT
    assert abs(steps * DT - 1.0 / 4.0) <= DT and v == [0.0, 0.0]


def test_points_pushed_during_a_stop_start_from_the_rest_position() -> None:
    interp = Interpolator(LIMITS, [-1.0, 0.0])
    interp.push(Point((1.0, -1.0), 1.0, 0.0))
    run(interp, 300)  # at (-0.4, -0.3), velocities (2, -1)
    interp.stop()
    interp.push(Point((0.0, -0.425), 1.0, 1.0))
    q, _ = run(interp, 250)  # both at rest after max(0.2, 0.25) s: (-0.2, -0.425)
    assert q == pytest.approx([-0.2, -0.425], abs=1e-9)
    q, v = run(interp, 500)  # then half of the 1 s segment to the point
    assert q == pytest.approx([-0.1, -0.425], abs=1e-9) and v == pytest.approx([0.2, 0.0], abs=1e-9)
    q, _ = run(interp, 501)
    assert q == [0.0, -0.425] and not interp.in_motion


def test_a_stop_near_a_limit_stays_inside_it() -> None:
    for start, end in ((0.9, 1.0), (-0.9, -1.0)):
        interp = Interpolator(LIMITS, [start, 0.0])
        interp.push(Point((end, 0.0), 1.0, 0.0))
        q, v = run(interp, 45)  # 2 rad/s, 0.01 rad from the limit: braking needs 0.2 rad
        assert abs(v[0]) == pytest.approx(2.0)
        interp.stop()
        while interp.in_motion:
            q, _ = interp.step(DT)
            assert -1.0 <= q[0] <= 1.0
        assert q[0] == end


def test_a_stop_at_rest_only_clears_the_queue() -> None:
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.5, 0.0), 1.0, 1.0))
    interp.stop()
    assert not interp.in_motion and len(interp) == 0
    assert interp.step(DT) == ([0.0, 0.0], [0.0, 0.0])


# -- construction --------------------------------------------------------------------------------
def test_bad_construction_is_refused_with_the_field() -> None:
    cases = [
        (lambda: JointLimits(1.0, -1.0, 1.0, 1.0), "lower"),
        (lambda: JointLimits(-1.0, math.nan, 1.0, 1.0), "lower"),
        (lambda: JointLimits(-1.0, 1.0, 0.0, 1.0), "velocity"),
        (lambda: JointLimits(-1.0, 1.0, 1.0, -5.0), "deceleration"),
        (lambda: Interpolator(LIMITS, [0.0]), "start"),
        (lambda: Interpolator(LIMITS, [0.0, math.nan]), "start[1]"),
        (lambda: Interpolator(LIMITS, [0.0, 0.0], capacity=0), "capacity"),
        (lambda: Interpolator((), []), "limits"),
    ]
    for make, field in cases:
        with pytest.raises(JointCtlError) as info:
            make()
        assert info.value.field == field


def test_a_start_outside_the_range_is_clamped_into_it() -> None:
    assert Interpolator(LIMITS, [1.2, -7.0]).position == [1.0, -7.0]


def test_limits_from_the_arm_model_are_the_urdfs() -> None:
    robot = load_robot_model(robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro")
    # <limit lower upper velocity> of each joint in robots/arm7dof/urdf/arm7dof.xacro
    urdf = {"joint0": (-3, 3, 0.2), "joint1": (-3, 3, 0.2), "joint2": (-3.1, 2.8, 0.3),
            "joint3": (-3.1, 2.7, 0.3), "joint4": (-4.0, 1.5, 0.4), "joint5": (-3, 3, 0.5),
            "joint6": (-4.5, 1.2, 0.4)}
    names = list(urdf)
    limits = JointLimits.from_model(robot, names)  # stop_time_s 0.2: deceleration = 5 x velocity
    for name, lim in zip(names, limits):
        lower, upper, velocity = urdf[name]
        assert (lim.lower, lim.upper, lim.velocity) == (lower, upper, velocity), name
        assert lim.deceleration == pytest.approx(velocity / 0.2, rel=1e-15), name
    reordered = JointLimits.from_model(robot, ["joint6", "joint0"], stop_time_s=0.5)
    assert reordered == (JointLimits(-4.5, 1.2, 0.4, 0.8), JointLimits(-3.0, 3.0, 0.2, 0.4))
    for names, field in ((["joint0", "nope"], "joint_names[1]"), (["ft_sensor_joint"], "joint_names[0]")):
        with pytest.raises(JointCtlError) as info:
            JointLimits.from_model(robot, names)
        assert (info.value.field, info.value.value) == (field, names[-1])
    with pytest.raises(JointCtlError) as info:
        JointLimits.from_model(robot, ["joint0"], stop_time_s=0.0)
    assert info.value.field == "stop_time_s"


def test_continuous_joints_have_no_range_and_a_missing_velocity_is_unknown() -> None:
    robot = RobotModel(
        name="wheels",
        links=(Link("base"), Link("rim"), Link("tip")),
        joints=(Joint("wheel", "continuous", "base", "rim", limits=UrdfLimits(None, None, 10.0, 3.0)),
                Joint("free", "continuous", "rim", "tip")),
    )
    wheel, free = JointLimits.from_model(robot, ["wheel", "free"])
    assert wheel == JointLimits(-math.inf, math.inf, 3.0, 15.0)
    assert free == JointLimits(-math.inf, math.inf, math.inf, math.inf)
    interp = Interpolator((wheel, free), [0.0, 0.0])
    interp.push(Point((30.0, 100.0), 1.0, 0.0))  # the wheel's 3 rad/s sets T = 10 s
    q, _ = run(interp, 5000)
    assert q == pytest.approx([15.0, 50.0], abs=1e-9)


# -- points with velocities (JOINT_TRAJ_PT_FULL): cubic segments -------------------------------------------

def test_a_point_with_velocities_is_reached_along_the_hermite_cubic_with_its_velocity():
    from scipy.interpolate import CubicHermiteSpline

    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.4, 0.2), 1.0, 1.0, velocities=(0.3, 0.0)))
    interp.push(Point((0.6, 0.2), 1.0, 1.0, velocities=(0.0, 0.0)))
    first = CubicHermiteSpline([0.0, 1.0], [0.0, 0.4], [0.0, 0.3])  # joint 0, from rest
    second = CubicHermiteSpline([1.0, 2.0], [0.4, 0.6], [0.3, 0.0])
    for t, spline in ((0.25, first), (0.5, first), (1.5, second)):
        interp_t = Interpolator(LIMITS, [0.0, 0.0])
        interp_t.push(Point((0.4, 0.2), 1.0, 1.0, velocities=(0.3, 0.0)))
        interp_t.push(Point((0.6, 0.2), 1.0, 1.0, velocities=(0.0, 0.0)))
        q, v = run(interp_t, round(t / DT))
        assert q[0] == pytest.approx(float(spline(t)), abs=1e-9)
        assert v[0] == pytest.approx(float(spline(t, 1)), abs=1e-9)
        assert interp_t.acceleration[0] == pytest.approx(float(spline(t, 2)), abs=1e-6)
    q, v = run(interp, 1000)
    # the point, with its velocity, at 1 s
    assert q == pytest.approx([0.4, 0.2], abs=1e-12) and v == pytest.approx([0.3, 0.0])
    q, v = run(interp, 1000)
    assert q == [0.6, 0.2] and v == [0.0, 0.0] and not interp.in_motion


def test_a_cubic_that_ends_moving_with_nothing_after_it_brakes_at_the_deceleration():
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.2, 0.0), 1.0, 0.5, velocities=(1.0, 0.0)))
    run(interp, 500)
    assert interp.velocity[0] == pytest.approx(1.0)
    q, v = run(interp, 50)  # braking from 1 rad/s at 10 rad/s²: 0.05 m later at 0.5 rad/s
    assert v[0] == pytest.approx(0.5, abs=1e-9) and interp.acceleration[0] == pytest.approx(-10.0)
    q, v = run(interp, 100)
    assert v[0] == 0.0 and q[0] == pytest.approx(0.2 + 1.0**2 / (2 * 10.0), abs=1e-9)  # v²/2a beyond the point


def test_a_stop_feeds_the_braking_deceleration_forward():
    interp = Interpolator(LIMITS, [0.0, 0.0])
    interp.push(Point((0.0, 5.0), 1.0, 0.0))  # joint 1 at its 1 rad/s
    run(interp, 500)
    interp.stop()
    run(interp, 10)
    assert interp.acceleration == [0.0, pytest.approx(-4.0)]  # joint 1's deceleration, opposing its motion
    run(interp, 300)  # 1 rad/s at 4 rad/s²: at rest after 0.25 s
    assert interp.acceleration == [0.0, 0.0] and interp.velocity == [0.0, 0.0]


@pytest.mark.parametrize(("velocities", "field", "code"), [
    ((2.5, 0.0), "velocities[0]", ERROR_BAD_VELOCITY),  # above joint 0's 2 rad/s
    ((0.0, math.nan), "velocities[1]", ERROR_NOT_FINITE),
    ((0.0,), "velocities", ERROR_JOINT_COUNT),
])
def test_bad_point_velocities_are_refused_naming_the_joint(velocities, field, code):
    interp = Interpolator(LIMITS, [0.0, 0.0])
    with pytest.raises(RefusedPoint) as info:
        interp.push(Point((0.1, 0.0), 1.0, 1.0, velocities=velocities))
    assert (info.value.field, info.value.error_code) == (field, code) and len(interp) == 0

"""Tests of trajectory validation: every refusal code and rule, partial goals, start time,
and property-based checks (valid goals round-trip, garbage only ever raises InvalidTrajectory)."""

from __future__ import annotations

import dataclasses
import decimal
import fractions
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from jointctl.errors import JointCtlError, ModelError
from jointctl.model.robot_model import Joint, JointLimits, Link, RobotModel
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.messages import JointSpec, JointTrajectory, JointTrajectoryPoint
from jointctl.trajectory.validation import (
    ValidatedTrajectory,
    joint_specs_from_model,
    validate_trajectory,
)

INVALID_GOAL = TrajectoryErrorCode.INVALID_GOAL
INVALID_JOINTS = TrajectoryErrorCode.INVALID_JOINTS
OLD_HEADER_TIMESTAMP = TrajectoryErrorCode.OLD_HEADER_TIMESTAMP

# Controller order: shoulder, elbow, wrist (continuous). All start at 0.
JOINTS = (
    JointSpec("shoulder", -1.0, 1.0, max_velocity=2.0),
    JointSpec("elbow", -2.0, 2.0, max_velocity=1.0),
    JointSpec("wrist", None, None, max_velocity=3.0),
)
HOME = (0.0, 0.0, 0.0)
NOW = 100.0


def point(positions, velocities=(), accelerations=(), effort=(), t=1.0) -> JointTrajectoryPoint:
    return JointTrajectoryPoint(positions, velocities, accelerations, effort, t)


def traj(names, *points, stamp=0.0) -> JointTrajectory:
    return JointTrajectory(tuple(names), tuple(points), stamp_s=stamp)


def validate(trajectory, *, joints=JOINTS, now=NOW, current=HOME, **kwargs) -> ValidatedTrajectory:
    return validate_trajectory(trajectory, joints, now_s=now, current_positions=current, **kwargs)


def refused(trajectory, code, *, point=None, joint=None, contains=(), **kwargs) -> InvalidTrajectory:
    """Validate, expect InvalidTrajectory with ``code``; check the message names point/joint/values."""
    with pytest.raises(InvalidTrajectory) as info:
        validate(trajectory, **kwargs)
    exc = info.value
    text = str(exc)
    assert exc.error_code == code, text
    assert isinstance(exc, JointCtlError) and exc.code == "trajectory"
    assert text.startswith(f"{exc.field}: {code.name}: ") if exc.field else text.startswith(code.name)
    if point is not None:
        assert exc.point == point, text
        assert f"points[{point}]" in text, text
    if joint is not None:
        assert exc.joint == joint, text
        assert repr(joint) in text, text
    for piece in contains:
        assert piece in text, text
    return exc


ALL3 = ("shoulder", "elbow", "wrist")


def good(**changes) -> JointTrajectory:
    """A valid 3-point goal over all joints."""
    points = (point((0.1, 0.1, 0.1), t=0.5), point((0.2, 0.3, -1.0), t=1.0), point((0.5, 0.5, 0.0), t=2.0))
    base = traj(ALL3, *points)
    return dataclasses.replace(base, **changes)


# ----------------------------------------------------------------------------- acceptance


def test_valid_goal_becomes_arrays() -> None:
    v = validate(good())
    assert v.joint_names == ALL3 and v.joint_indices == (0, 1, 2)
    assert v.times_s.dtype == np.float64 and v.times_s.tolist() == [0.5, 1.0, 2.0]
    assert v.positions.dtype == np.float64 and v.positions.shape == (3, 3)
    assert v.positions.tolist() == [[0.1, 0.1, 0.1], [0.2, 0.3, -1.0], [0.5, 0.5, 0.0]]
    assert v.velocities is None and v.accelerations is None and v.effort is None
    assert v.start_time_s == NOW
    assert v.duration_s == 2.0 and v.end_time_s == NOW + 2.0


def test_result_arrays_are_read_only() -> None:
    v = validate(good())
    for array in (v.times_s, v.positions):
        with pytest.raises(ValueError):
            array[0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        v.start_time_s = 0.0  # type: ignore[misc]


def test_ints_and_numpy_numbers_are_accepted() -> None:
    v = validate(traj(("shoulder", "elbow"),
                      point((0, np.float32(0.5)), (np.int64(0), 0.25), (1, -1), (np.float64(2.0), 3), t=1),
                      point((np.float64(0.5), 1), (0, 0), (0, 0), (0, 0), t=np.float64(2.5)),
                      stamp=np.int32(0)))
    assert v.positions.tolist() == [[0.0, 0.5], [0.5, 1.0]]
    assert v.velocities.tolist() == [[0.0, 0.25], [0.0, 0.0]]
    assert v.accelerations.tolist() == [[1.0, -1.0], [0.0, 0.0]]
    assert v.effort.tolist() == [[2.0, 3.0], [0.0, 0.0]]
    assert v.times_s.tolist() == [1.0, 2.5]
    assert all(a.dtype == np.float64 for a in (v.times_s, v.positions, v.velocities, v.effort))


def test_partial_goal_reorders_columns_to_controller_order() -> None:
    goal = traj(("wrist", "shoulder"),
                point((5.0, 0.5), velocities=(1.0, 0.1), accelerations=(0.0, 0.2), effort=(7.0, 8.0), t=2.0),
                point((6.0, 0.6), velocities=(0.0, 0.0), accelerations=(0.3, 0.4), effort=(9.0, 10.0), t=3.0))
    v = validate(goal)
    assert v.joint_names == ("shoulder", "wrist")
    assert v.joint_indices == (0, 2)
    assert v.positions.tolist() == [[0.5, 5.0], [0.6, 6.0]]
    assert v.velocities.tolist() == [[0.1, 1.0], [0.0, 0.0]]
    assert v.accelerations.tolist() == [[0.2, 0.0], [0.4, 0.3]]
    assert v.effort.tolist() == [[8.0, 7.0], [10.0, 9.0]]


def test_partial_goal_compares_with_the_current_positions_of_its_own_joints() -> None:
    current = (0.9, -1.5, 10.0)
    # elbow alone, starting at time 0 at its current position: fine even though others are elsewhere.
    v = validate(traj(("elbow",), point((-1.5,), t=0.0), point((-1.0,), t=1.0)), current=current)
    assert v.joint_indices == (1,)
    refused(traj(("wrist",), point((0.0,), t=0.0)), INVALID_GOAL, point=0, joint="wrist",
            current=current, contains=("10.0",))


def test_start_time_is_now_when_the_stamp_is_zero() -> None:
    assert validate(good(stamp_s=0.0), now=3.25).start_time_s == 3.25
    assert validate(good(stamp_s=0), now=1e6).start_time_s == 1e6  # an old zero stamp is "now"


def test_start_time_is_the_stamp_when_given() -> None:
    assert validate(good(stamp_s=150.0)).start_time_s == 150.0  # in the future: starts later
    assert validate(good(stamp_s=99.0)).start_time_s == 99.0  # in the past, still running
    assert validate(good(stamp_s=98.0)).start_time_s == 98.0  # ends exactly now


def test_effort_is_not_limited_by_validation() -> None:
    v = validate(traj(("shoulder",), point((0.1,), effort=(1e9,), t=1.0)))
    assert v.effort.tolist() == [[1e9]]


def test_accelerations_without_velocities_are_passed_through() -> None:
    v = validate(traj(("shoulder",), point((0.1,), accelerations=(1.0,), t=1.0)))
    assert v.velocities is None and v.accelerations.tolist() == [[1.0]]


# ----------------------------------------------------------------------------- INVALID_JOINTS


def test_no_joint_names() -> None:
    refused(traj((), point(())), INVALID_JOINTS, contains=("joint_names", "no joints"))


def test_duplicate_joint_names() -> None:
    goal = traj(("shoulder", "elbow", "shoulder"), point((0.1, 0.1, 0.1)))
    refused(goal, INVALID_JOINTS, joint="shoulder", contains=("joint_names[2]", "twice", "joint_names[0]"))


def test_unknown_joint_name() -> None:
    goal = traj(("shoulder", "knee"), point((0.1, 0.1)))
    refused(goal, INVALID_JOINTS, joint="knee", contains=("joint_names[1]", "'knee'", "'elbow'"))


@pytest.mark.parametrize("name", ["", True, False, 0, 1.5, None, b"shoulder", ("shoulder",)])
def test_joint_names_must_be_non_empty_strings(name) -> None:
    goal = traj(("shoulder", name), point((0.1, 0.1)))
    refused(goal, INVALID_JOINTS, contains=("joint_names[1]", "non-empty string", repr(name)))


def test_numpy_string_names_are_plain_strings_in_the_result() -> None:
    v = validate(traj(np.array(["elbow", "shoulder"]), point((0.1, 0.2))))
    assert v.joint_names == ("shoulder", "elbow") and all(type(n) is str for n in v.joint_names)


def test_joint_errors_come_before_goal_errors() -> None:
    goal = traj(("shoulder", "knee"), point((math.nan,), t=-1.0), stamp=1.0)
    refused(goal, INVALID_JOINTS, joint="knee")
    refused(traj((), ), INVALID_JOINTS)


# ----------------------------------------------------------------------------- INVALID_GOAL: structure


def test_no_points() -> None:
    refused(traj(ALL3), INVALID_GOAL, contains=("points", "no points"))


def test_point_that_is_not_a_point() -> None:
    goal = traj(("shoulder",), point((0.1,)), {"positions": [0.2]})
    refused(goal, INVALID_GOAL, point=1, contains=("JointTrajectoryPoint", "'dict'"))


@pytest.mark.parametrize("positions", [(), (0.1,), (0.1, 0.1, 0.1, 0.1)])
def test_positions_must_have_one_value_per_joint(positions) -> None:
    goal = traj(ALL3, point((0.1, 0.1, 0.1), t=1.0), point(positions, t=2.0))
    refused(goal, INVALID_GOAL, point=1,
            contains=("positions", f"{len(positions)} values for 3 joints", f"(got {len(positions)})"))


@pytest.mark.parametrize("field", ["velocities", "accelerations", "effort"])
@pytest.mark.parametrize("n", [1, 4])
def test_optional_vectors_are_empty_or_one_value_per_joint(field, n) -> None:
    bad = {field: (0.0,) * n}
    goal = traj(ALL3, point((0.1, 0.1, 0.1), t=1.0), point((0.2, 0.2, 0.2), t=2.0, **bad))
    refused(goal, INVALID_GOAL, point=1, contains=(field, f"{n} values for 3 joints", f"(got {n})"))


@pytest.mark.parametrize("field", ["velocities", "accelerations", "effort"])
def test_optional_vectors_are_given_in_all_points_or_none(field) -> None:
    given_ = {field: (0.0, 0.0, 0.0)}
    goal = traj(ALL3, point((0.1, 0.1, 0.1), t=1.0, **given_), point((0.2, 0.2, 0.2), t=2.0, **given_),
                point((0.3, 0.3, 0.3), t=3.0))
    refused(goal, INVALID_GOAL, point=2, contains=(field, "all points or in none", "points[0]"))
    # and the other way round: missing first, given later
    goal = traj(ALL3, point((0.1, 0.1, 0.1), t=1.0), point((0.2, 0.2, 0.2), t=2.0, **given_))
    refused(goal, INVALID_GOAL, point=0, contains=(field, "points[1]"))


# ----------------------------------------------------------------------------- INVALID_GOAL: times


@pytest.mark.parametrize("t", [math.nan, math.inf, -math.inf, 10**400])
def test_time_from_start_must_be_finite(t) -> None:
    goal = traj(("shoulder",), point((0.1,), t=1.0), point((0.2,), t=t))
    refused(goal, INVALID_GOAL, point=1, contains=("time_from_start", "finite"))


def test_time_from_start_must_not_be_negative() -> None:
    goal = traj(("shoulder",), point((0.0,), t=-0.5), point((0.2,), t=1.0))
    refused(goal, INVALID_GOAL, point=0, contains=("time_from_start", "negative", "-0.5"))


@pytest.mark.parametrize("t2", [1.0, 0.5])
def test_times_must_increase_strictly(t2) -> None:
    goal = traj(("shoulder",), point((0.1,), t=0.5), point((0.2,), t=1.0), point((0.3,), t=t2))
    refused(goal, INVALID_GOAL, point=2, contains=("time_from_start", "increase strictly", repr(t2),
                                                   "points[1] is at 1.0"))


@pytest.mark.parametrize("t", [True, "1.0", None, 1 + 0j, decimal.Decimal("1.0"), np.array([1.0])])
def test_time_from_start_must_be_a_number(t) -> None:
    goal = traj(("shoulder",), point((0.1,), t=t))
    refused(goal, INVALID_GOAL, point=0, contains=("time_from_start", "number"))


@pytest.mark.parametrize("stamp", [True, "5", None, math.nan, math.inf])
def test_header_stamp_must_be_a_finite_number(stamp) -> None:
    refused(good(stamp_s=stamp), INVALID_GOAL, contains=("header.stamp",))


def test_fraction_times_are_numbers() -> None:
    v = validate(traj(("shoulder",), point((0.1,), t=fractions.Fraction(1, 2))))
    assert v.times_s.tolist() == [0.5]


# ----------------------------------------------------------------------------- INVALID_GOAL: values

FIELDS = ["positions", "velocities", "accelerations", "effort"]


def with_value(field: str, value, *, at_point: int = 1, at_joint: int = 1) -> JointTrajectory:
    """good() with every optional field given as zeros and one value replaced."""
    rows = {"positions": [[0.1, 0.1, 0.1], [0.2, 0.3, -1.0], [0.5, 0.5, 0.0]]}
    for f in FIELDS[1:]:
        rows[f] = [[0.0] * 3 for _ in range(3)]
    rows[field][at_point][at_joint] = value
    points = [JointTrajectoryPoint(*(tuple(rows[f][k]) for f in FIELDS), time_from_start_s=t)
              for k, t in enumerate((0.5, 1.0, 2.0))]
    return traj(ALL3, *points)


@pytest.mark.parametrize("field", FIELDS)
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, np.float64("nan"), -(10**400)])
def test_values_must_be_finite(field, value) -> None:
    refused(with_value(field, value), INVALID_GOAL, point=1, joint="elbow",
            contains=(field, "finite"))


def test_nan_message_shows_the_value() -> None:
    exc = refused(with_value("velocities", math.nan, at_point=2, at_joint=0), INVALID_GOAL,
                  point=2, joint="shoulder", contains=("velocities", "(got nan)"))
    assert math.isnan(exc.value)


@pytest.mark.parametrize("field", FIELDS)
@pytest.mark.parametrize("value", [True, False, np.bool_(True), "0.1", None, 1j, [0.1]])
def test_values_must_be_numbers_not_bools_or_strings(field, value) -> None:
    refused(with_value(field, value), INVALID_GOAL, point=1, joint="elbow",
            contains=(field, "numbers", repr(value)))


def test_a_wrong_type_is_reported_before_a_nan_in_an_earlier_point() -> None:
    goal = with_value("positions", math.nan, at_point=0, at_joint=0)
    goal = dataclasses.replace(goal, points=goal.points[:2] + (
        dataclasses.replace(goal.points[2], effort=(0.0, "x", 0.0)),))
    refused(goal, INVALID_GOAL, point=2, joint="elbow", contains=("effort", "'x'"))


# ----------------------------------------------------------------------------- INVALID_GOAL: limits


def test_position_below_lower_limit() -> None:
    refused(with_value("positions", -2.5), INVALID_GOAL, point=1, joint="elbow",
            contains=("positions", "lower limit -2.0", "(got -2.5)"))


def test_position_above_upper_limit() -> None:
    refused(with_value("positions", 1.25, at_point=2, at_joint=0), INVALID_GOAL, point=2,
            joint="shoulder", contains=("positions", "upper limit 1.0", "(got 1.25)"))


def test_positions_at_the_limits_are_allowed() -> None:
    goal = traj(("shoulder", "elbow"), point((-1.0, 2.0), t=2.0), point((1.0, -2.0), t=10.0))
    assert validate(goal).positions.tolist() == [[-1.0, 2.0], [1.0, -2.0]]


def test_continuous_joint_has_no_position_limit() -> None:
    goal = traj(("wrist",), point((1000.0,), t=400.0), point((-1000.0,), t=1100.0))
    assert validate(goal).positions.tolist() == [[1000.0], [-1000.0]]


def test_one_sided_limit_is_checked() -> None:
    joints = (JointSpec("slide", 0.0, None, max_velocity=math.inf),)
    assert validate(traj(("slide",), point((1e6,))), joints=joints, current=(0.0,))
    refused(traj(("slide",), point((-0.1,))), INVALID_GOAL, point=0, joint="slide",
            joints=joints, current=(0.0,), contains=("lower limit 0.0",))


@pytest.mark.parametrize("v", [2.5, -2.5])
def test_velocity_above_max_velocity(v) -> None:
    refused(with_value("velocities", v, at_joint=0), INVALID_GOAL, point=1, joint="shoulder",
            contains=("velocities", "max_velocity 2.0", f"(got {v})"))


def test_velocity_at_max_velocity_is_allowed() -> None:
    v = validate(with_value("velocities", -1.0))
    assert v.velocities[1, 1] == -1.0


def test_limits_are_checked_before_speeds() -> None:
    # point 1 is both out of range and too fast; the range is reported.
    goal = traj(("shoulder",), point((0.1,), t=1.0), point((5.0,), t=1.1))
    refused(goal, INVALID_GOAL, point=1, contains=("upper limit",))


# ----------------------------------------------------------------------------- INVALID_GOAL: feasibility


def test_segment_average_speed_above_max_velocity() -> None:
    # elbow: 0.3 -> -1.5 in 1.0 s is 1.8 per s, limit 1.0
    goal = traj(ALL3, point((0.1, 0.3, 0.0), t=1.0), point((0.2, -1.5, 0.0), t=2.0))
    exc = refused(goal, INVALID_GOAL, point=1, joint="elbow",
                  contains=("infeasible", "points[0]", "1.8", "max_velocity 1.0", "t=1.0", "t=2.0"))
    assert exc.value == pytest.approx(1.8)


def test_segment_from_the_current_position_counts() -> None:
    # shoulder from 0 (current) to 0.9 in 0.25 s needs 3.6 per s, limit 2.0
    goal = traj(("shoulder",), point((0.9,), t=0.25), point((0.9,), t=1.0))
    exc = refused(goal, INVALID_GOAL, point=0, joint="shoulder",
                  contains=("current position", "3.6", "max_velocity 2.0"))
    assert exc.value == pytest.approx(3.6)


def test_segment_from_the_current_position_uses_the_current_position() -> None:
    goal = traj(("shoulder",), point((0.9,), t=0.25))
    assert validate(goal, current=(0.8, 0.0, 0.0))  # 0.4 per s
    refused(goal, INVALID_GOAL, point=0, joint="shoulder", current=(-0.9, 0.0, 0.0))


def test_segment_at_exactly_max_velocity_is_allowed() -> None:
    goal = traj(("elbow",), point((0.1,), t=0.1), point((1.1,), t=1.1), point((-0.9,), t=3.1))
    assert validate(goal).positions[:, 0].tolist() == [0.1, 1.1, -0.9]


def test_infinite_max_velocity_is_not_checked() -> None:
    joints = (JointSpec("free", None, None, max_velocity=math.inf),)
    v = validate(traj(("free",), point((1e300,), t=1e-300)), joints=joints, current=(-1e300,))
    assert v.positions.tolist() == [[1e300]]


def test_check_velocity_false_skips_both_speed_checks() -> None:
    too_fast = traj(("shoulder",), point((0.9,), velocities=(50.0,), t=0.01))
    refused(too_fast, INVALID_GOAL, point=0, joint="shoulder")
    v = validate(too_fast, check_velocity=False)
    assert v.velocities.tolist() == [[50.0]]


# ----------------------------------------------------------------------------- INVALID_GOAL: start jump


def test_first_point_at_time_zero_must_be_at_the_current_position() -> None:
    goal = traj(ALL3, point((0.0, 0.5, 0.0), t=0.0), point((0.0, 0.5, 0.0), t=1.0))
    refused(goal, INVALID_GOAL, point=0, joint="elbow",
            contains=("time 0", "jump", "current position 0.0", "(got 0.5)"))


def test_first_point_at_time_zero_within_start_tolerance_is_allowed() -> None:
    goal = traj(("shoulder",), point((0.3 + 5e-4,), t=0.0), point((0.4,), t=1.0))
    v = validate(goal, current=(0.3, 0.0, 0.0))
    assert v.positions[0, 0] == 0.3 + 5e-4
    refused(goal, INVALID_GOAL, point=0, joint="shoulder", current=(0.3, 0.0, 0.0), start_tolerance=1e-4)
    assert validate(goal, current=(0.0, 0.0, 0.0), start_tolerance=0.5)


def test_start_jump_is_checked_even_without_speed_checks() -> None:
    goal = traj(("shoulder",), point((0.5,), t=0.0))
    refused(goal, INVALID_GOAL, point=0, joint="shoulder", check_velocity=False)


# ----------------------------------------------------------------------------- OLD_HEADER_TIMESTAMP


def test_goal_that_already_ended_is_old() -> None:
    exc = refused(good(stamp_s=97.5), OLD_HEADER_TIMESTAMP, contains=("header.stamp", "97.5", "before now"))
    assert exc.value == 97.5


def test_zero_stamp_is_never_old() -> None:
    assert validate(good(stamp_s=0.0), now=1e9).start_time_s == 1e9


def test_goal_errors_come_before_old_stamp() -> None:
    ended_and_out_of_range = dataclasses.replace(with_value("positions", 9.0), stamp_s=1.0)
    refused(ended_and_out_of_range, INVALID_GOAL, point=1, joint="elbow")
    refused(dataclasses.replace(ended_and_out_of_range, joint_names=("elbow", "knee", "wrist")),
            INVALID_JOINTS, joint="knee")


# ----------------------------------------------------------------------------- caller errors


def test_bad_caller_arguments_are_value_errors() -> None:
    with pytest.raises(ValueError):
        validate(good(), current=(0.0, 0.0))
    with pytest.raises(ValueError):
        validate(good(), current=(0.0, math.nan, 0.0))
    with pytest.raises(ValueError):
        validate(good(), now=math.nan)
    with pytest.raises(ValueError):
        validate(good(), joints=JOINTS + (JOINTS[0],), current=(0.0,) * 4)


def test_not_a_trajectory_is_an_invalid_goal() -> None:
    refused({"joint_names": ["shoulder"]}, INVALID_GOAL, contains=("JointTrajectory",))


# ----------------------------------------------------------------------------- joint_specs_from_model


def make_robot() -> RobotModel:
    links = tuple(Link(n) for n in ("world", "base", "a", "b", "c", "d", "e"))
    joints = (
        Joint("glue", "fixed", "world", "base"),
        Joint("ja", "revolute", "base", "a", limits=JointLimits(-1.0, 1.5, effort=5.0, velocity=2.0)),
        Joint("jb", "prismatic", "a", "b", limits=JointLimits(0.0, 0.3, effort=0.0, velocity=0.0)),
        Joint("jc", "continuous", "a", "c", limits=JointLimits(None, None, effort=3.0, velocity=4.0)),
        Joint("jd", "continuous", "a", "d"),
        Joint("je", "prismatic", "a", "e", limits=JointLimits(0.2, 0.2, effort=1.0, velocity=1.0)),
    )
    return RobotModel("r", links, joints, source="r.urdf")


def test_joint_specs_from_model() -> None:
    specs = joint_specs_from_model(make_robot(), ["jc", "ja", "jb", "jd"])
    assert [s.name for s in specs] == ["jc", "ja", "jb", "jd"]
    jc, ja, jb, jd = specs
    assert (ja.lower, ja.upper, ja.max_velocity, ja.max_effort) == (-1.0, 1.5, 2.0, 5.0)
    assert (jb.lower, jb.upper, jb.max_velocity, jb.max_effort) == (0.0, 0.3, math.inf, math.inf)
    assert (jc.lower, jc.upper, jc.max_velocity, jc.max_effort) == (None, None, 4.0, 3.0)
    assert (jd.lower, jd.upper, jd.max_velocity, jd.max_effort) == (None, None, math.inf, math.inf)
    assert all(s.max_acceleration == math.inf for s in specs)


@pytest.mark.parametrize("name", ["nope", "glue", "je"])
def test_joint_specs_from_model_refuses_unknown_or_unmovable_joints(name) -> None:
    with pytest.raises(ModelError) as info:
        joint_specs_from_model(make_robot(), ["ja", name])
    assert "joints[1]" in str(info.value) and repr(name) in str(info.value)


def test_joint_specs_of_the_built_in_robot_validate_a_goal() -> None:
    from jointctl.model import load_robot_model
    from jointctl.paths import robots_dir

    robot = load_robot_model(robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro")
    names = [j.name for j in robot.movable_joints]
    specs = joint_specs_from_model(robot, names)
    assert len(specs) == len(names) >= 1
    lower, upper = specs[0].lower, specs[0].upper
    mid = (lower + upper) / 2
    v = validate(traj(names[:1], point((mid,), t=1.0)), joints=specs, current=(mid,) * len(specs))
    assert v.positions.tolist() == [[mid]]
    refused(traj(names[:1], point((upper + 1.0,), t=1.0)), INVALID_GOAL, point=0, joint=names[0],
            joints=specs, current=(mid,) * len(specs))


# ----------------------------------------------------------------------------- properties


@st.composite
def joint_sets(draw) -> tuple[tuple[JointSpec, ...], tuple[float, ...]]:
    """1-7 joints with random limits (some continuous, some unlimited speed) and positions inside."""
    n = draw(st.integers(1, 7))
    specs, current = [], []
    for i in range(n):
        if draw(st.booleans()):
            lower = draw(st.floats(-10.0, 10.0))
            upper = lower + draw(st.floats(0.0, 10.0))
        else:
            lower = upper = None
        vmax = draw(st.one_of(st.floats(0.0, 20.0), st.just(math.inf)))
        specs.append(JointSpec(f"joint_{i}", lower, upper, max_velocity=vmax))
        current.append(draw(st.floats(lower, upper)) if lower is not None else draw(st.floats(-50.0, 50.0)))
    return tuple(specs), tuple(current)


def clip(q: float, spec: JointSpec) -> float:
    if spec.lower is not None:
        q = min(max(q, spec.lower), spec.upper)
    return q


@st.composite
def valid_goals(draw):
    joints, current = draw(joint_sets())
    # a non-empty subset, in random order
    order = draw(st.permutations(range(len(joints))))
    goal_idx = order[: draw(st.integers(1, len(joints)))]
    names = tuple(joints[i].name for i in goal_idx)
    n_points = draw(st.integers(1, 30))
    start_at_zero = draw(st.booleans())
    times, t = [], 0.0 if start_at_zero else draw(st.floats(0.001, 2.0))
    for _ in range(n_points):
        times.append(t)
        t += draw(st.floats(0.001, 2.0))
    rows = []
    prev = [current[i] for i in goal_idx]
    for k in range(n_points):
        dt = times[k] - (times[k - 1] if k else 0.0)
        row = []
        for c, i in enumerate(goal_idx):
            spec = joints[i]
            if k == 0 and start_at_zero:
                q = prev[c] + draw(st.floats(-1e-3, 1e-3))
                q = clip(q, spec)
            else:
                step = 10.0 if math.isinf(spec.max_velocity) else spec.max_velocity * dt
                q = clip(prev[c] + draw(st.floats(-1.0, 1.0)) * step, spec)
            row.append(q)
        rows.append(row)
        prev = row
    with_vel = draw(st.booleans())
    points = []
    for k in range(n_points):
        vel = ()
        if with_vel:
            vel = tuple(draw(st.floats(-1.0, 1.0)) * min(joints[i].max_velocity, 100.0) for i in goal_idx)
        points.append(JointTrajectoryPoint(tuple(rows[k]), vel, time_from_start_s=times[k]))
    stamp = draw(st.one_of(st.just(0.0), st.floats(NOW - times[-1] + 1e-6, NOW + 100.0)))
    return joints, current, goal_idx, JointTrajectory(names, tuple(points), stamp_s=stamp)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(valid_goals())
def test_valid_trajectories_are_accepted_and_round_trip_exactly(case) -> None:
    joints, current, goal_idx, goal = case
    # start within 1e-3 may land just over the tolerance through rounding: keep clear cases only
    if goal.points[0].time_from_start_s == 0.0:
        assume(all(abs(goal.points[0].positions[c] - current[i]) <= 1e-3 * (1 - 1e-9)
                   for c, i in enumerate(goal_idx)))
    v = validate(goal, joints=joints, current=current)
    order = sorted(range(len(goal_idx)), key=lambda c: goal_idx[c])
    assert v.joint_indices == tuple(sorted(goal_idx))
    assert v.joint_names == tuple(joints[i].name for i in sorted(goal_idx))
    assert v.times_s.tolist() == [p.time_from_start_s for p in goal.points]
    assert v.positions.tolist() == [[p.positions[c] for c in order] for p in goal.points]
    if goal.points[0].velocities:
        assert v.velocities.tolist() == [[p.velocities[c] for c in order] for p in goal.points]
    else:
        assert v.velocities is None
    assert v.accelerations is None and v.effort is None
    assert v.start_time_s == (goal.stamp_s if goal.stamp_s else NOW)


# garbage: anything in any place

NAMES = [s.name for s in JOINTS]
numberish = st.one_of(
    st.floats(-3.0, 3.0),
    st.floats(),
    st.integers(),
    st.integers(min_value=10**300, max_value=10**400),
    st.booleans(),
    st.text(max_size=3),
    st.none(),
    st.builds(np.float64, st.floats()),
    st.builds(np.float32, st.floats(width=32)),
    st.builds(np.int64, st.integers(-(2**63), 2**63 - 1)),
    st.fractions(),
    st.decimals(),
    st.complex_numbers(),
    st.just(np.array([1.0, 2.0])),
    st.just(object()),
)
anything = st.one_of(numberish, st.lists(numberish, max_size=3), st.dictionaries(st.text(max_size=2), numberish))
def rarely(draw) -> bool:
    """True about one time in twenty (hypothesis favours small integers, so test the top)."""
    return draw(st.integers(1, 20)) == 20


@st.composite
def garbage_vectors(draw, n: int, *, optional: bool):
    """Mostly the right length with plausible numbers; sometimes any length or any content."""
    length = draw(st.one_of(st.just(n), st.just(0) if optional else st.just(n), st.integers(0, n + 2)))
    element = st.one_of(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), numberish)
    return draw(st.lists(element, min_size=length, max_size=length))


@st.composite
def garbage_points(draw, n: int, t: float):
    if rarely(draw):
        return draw(anything)
    p = JointTrajectoryPoint(draw(garbage_vectors(n, optional=False)), draw(garbage_vectors(n, optional=True)),
                             draw(garbage_vectors(n, optional=True)), draw(garbage_vectors(n, optional=True)),
                             draw(st.one_of(st.just(t), st.just(t), st.floats(-1.0, 5.0), numberish)))
    if rarely(draw):  # bypass __post_init__: a field that is not a sequence
        object.__setattr__(p, draw(st.sampled_from(FIELDS)), draw(anything))
    return p


@st.composite
def garbage_trajectories(draw):
    names = draw(st.one_of(
        st.lists(st.sampled_from(NAMES), min_size=1, max_size=3, unique=True),
        st.lists(st.sampled_from(NAMES), min_size=1, max_size=3, unique=True),
        st.lists(st.one_of(st.sampled_from(NAMES), st.text(max_size=3), numberish), max_size=4),
    ))
    n_points = draw(st.integers(0, 5))
    times = sorted(draw(st.lists(st.floats(0.0, 5.0), min_size=n_points, max_size=n_points)))
    points = [draw(garbage_points(len(names), t)) for t in times]
    stamp = draw(st.one_of(st.just(0.0), st.floats(0.0, 200.0), numberish))
    goal = JointTrajectory(tuple(names), tuple(points), stamp_s=stamp)
    if rarely(draw):
        object.__setattr__(goal, "joint_names", draw(anything))
    if rarely(draw):
        object.__setattr__(goal, "points", draw(anything))
    return goal


@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(garbage_trajectories(), st.floats(0.0, 1.0), st.booleans())
def test_garbage_only_ever_raises_invalid_trajectory(goal, tol, check_velocity) -> None:
    try:
        v = validate(goal, start_tolerance=tol, check_velocity=check_velocity)
    except InvalidTrajectory as exc:
        assert isinstance(exc.error_code, TrajectoryErrorCode)
        assert exc.error_code in (INVALID_GOAL, INVALID_JOINTS, OLD_HEADER_TIMESTAMP)
        str(exc)  # the message renders
        return
    assert np.all(np.isfinite(v.positions)) and np.all(np.diff(v.times_s) > 0)
    assert set(v.joint_names) <= set(NAMES)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(NAMES), min_size=1, max_size=3, unique=True), st.data())
def test_shuffled_valid_names_with_random_lengths(names, data) -> None:
    """Right names, random vector lengths and times: accepted or INVALID_GOAL, never anything else."""
    n = len(names)
    points = data.draw(st.lists(st.builds(
        JointTrajectoryPoint,
        positions=st.lists(st.floats(-1.0, 1.0), min_size=max(0, n - 1), max_size=n + 1),
        velocities=st.lists(st.floats(-1.0, 1.0), max_size=n + 1),
        time_from_start_s=st.floats(-1.0, 5.0)), min_size=1, max_size=6))
    try:
        v = validate(JointTrajectory(tuple(names), tuple(points)))
    except InvalidTrajectory as exc:
        assert exc.error_code == INVALID_GOAL
    else:
        assert v.positions.shape == (len(points), n)

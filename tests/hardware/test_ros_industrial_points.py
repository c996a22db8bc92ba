"""Speed fraction and duration per point, as ROS-I's ``JointTrajectoryInterface::calc_velocity`` and
``calc_duration`` compute them (simple-message-facts.md §7), on worked numbers."""

from __future__ import annotations

import math

import pytest

from jointctl.hardware.ros_industrial_points import (
    DEFAULT_DURATION_S,
    DEFAULT_SPEED_FRACTION,
    speed_fraction,
    wire_points,
)

VMAX = (0.2, 0.2, 0.3, 0.3, 0.4, 0.5, 0.4)  # the arm's URDF speed limits [rad/s]


def test_the_fraction_is_the_critical_joints_ratio_to_its_limit():
    # joint 2 at 0.15 of 0.3 (0.5) beats joint 0 at 0.08 of 0.2 (0.4) and joint 5 at -0.2 of 0.5 (0.4)
    assert speed_fraction((0.08, 0, 0.15, 0, 0, -0.2, 0), VMAX) == pytest.approx(0.5)


def test_the_default_fraction_when_velocities_are_missing_zero_or_limits_unknown():
    assert speed_fraction(None, VMAX) == DEFAULT_SPEED_FRACTION == 0.1
    assert speed_fraction((), VMAX) == 0.1
    assert speed_fraction((0.0,) * 7, VMAX) == 0.1  # the last point of a planned path: 10 %, never 0
    assert speed_fraction((0.1, 0.1), (math.inf, math.nan)) == 0.1  # no joint has a known limit
    assert speed_fraction((0.0,) * 7, VMAX, default=0.25) == 0.25


def test_joints_without_a_known_limit_do_not_count_and_the_fraction_is_clipped_to_one():
    assert speed_fraction((5.0, 0.1), (math.inf, 0.2)) == pytest.approx(0.5)
    assert speed_fraction((0.0, 0.6), (math.inf, 0.2)) == 1.0  # 3x the limit: clipped


def test_durations_are_the_time_since_the_previous_point_from_the_goals_start():
    points = wire_points([0.5, 1.25, 3.0], [[0.1], [0.2], [0.3]], [[0.1], [0.04], [0.0]], None, (0.2,))
    assert [p.duration_s for p in points] == pytest.approx([0.5, 0.75, 1.75])
    assert [p.speed_fraction for p in points] == pytest.approx([0.5, 0.2, 0.1])
    assert [p.time_s for p in points] == [0.5, 1.25, 3.0]
    assert points[0].accelerations is None


def test_a_first_point_at_time_zero_is_where_the_robot_is_and_is_not_sent():
    points = wire_points([0.0, 2.0], [[0.0], [0.4]], None, None, (0.2,))
    assert len(points) == 1
    assert (points[0].positions, points[0].duration_s, points[0].speed_fraction) == ((0.4,), 2.0, 0.1)


def test_time_that_does_not_increase_gets_the_default_duration():
    points = wire_points([1.0, 1.0], [[0.0], [0.1]], None, None, (0.2,))
    assert [p.duration_s for p in points] == [1.0, DEFAULT_DURATION_S]

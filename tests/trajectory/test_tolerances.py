"""Tests for jointctl.trajectory.tolerances: the tolerance checks as functions of arrays."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.trajectory.tolerances import goal_reached, path_violation, worst_joint


@pytest.mark.parametrize("as_array", [False, True])
def test_path_violation_names_the_first_joint_past_its_tolerance(as_array) -> None:
    wrap = np.asarray if as_array else list
    desired = wrap([0.0, 1.0, 2.0])
    assert path_violation(desired, wrap([0.05, 0.95, 2.0]), wrap([0.1, 0.1, 0.1])) is None
    assert path_violation(desired, wrap([0.0, 1.2, 2.5]), wrap([0.1, 0.1, 0.1])) == 1
    # Exactly at the tolerance is still on the path.
    assert path_violation(wrap([0.0]), wrap([0.25]), wrap([0.25])) is None


def test_a_tolerance_of_zero_or_below_is_not_checked() -> None:
    assert path_violation([0.0, 0.0], [5.0, 0.2], [0.0, 0.1]) == 1
    assert path_violation([0.0, 0.0], [5.0, 0.0], [0.0, 0.1]) is None
    assert path_violation([0.0], [5.0], [-1.0]) is None


def test_without_goal_tolerances_a_goal_is_reached_at_its_end_wherever_the_joints_are() -> None:
    assert goal_reached([1.0, 2.0], [0.0, 0.0], [3.0, -3.0], [0.0, 0.0], 0.01)


def test_a_goal_is_reached_within_tolerance_and_at_rest() -> None:
    desired, tolerance = np.array([1.0, 2.0]), np.array([0.05, 0.05])
    assert goal_reached(desired, [1.04, 1.96], [0.0, 0.005], tolerance, 0.01)
    assert not goal_reached(desired, [1.06, 2.0], [0.0, 0.0], tolerance, 0.01)   # out of tolerance
    assert not goal_reached(desired, [1.0, 2.0], [0.0, 0.02], tolerance, 0.01)   # still moving
    # A joint without a tolerance may end anywhere; every joint must be at rest, though.
    assert goal_reached(desired, [1.0, 9.0], [0.0, 0.0], [0.05, 0.0], 0.01)
    assert not goal_reached(desired, [1.0, 9.0], [0.0, 0.5], [0.05, 0.0], 0.01)


def test_worst_joint_is_the_farthest_the_first_of_equals() -> None:
    assert worst_joint([0.0, 0.0, 0.0], [0.1, -0.3, 0.2]) == 1
    assert worst_joint(np.zeros(3), np.array([0.2, -0.2, 0.1])) == 0

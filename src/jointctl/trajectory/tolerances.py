"""Path and goal tolerances as pure functions of the joints' desired and actual states.

control_msgs/FollowJointTrajectory semantics: a goal whose joint strays farther than its path
tolerance from the desired position is aborted (PATH_TOLERANCE_VIOLATED); after the last point
it succeeds once every joint is within its goal tolerance and, if any goal tolerance is set, at
rest; otherwise it is aborted ``goal_time_s`` later (GOAL_TOLERANCE_VIOLATED). A tolerance of 0
(or below) means "not checked", per joint.

Arguments are sequences (lists, tuples or 1-D arrays) with one value per joint, in the same
order. The executor calls these every cycle a check is due, on at most a few joints: plain
loops over the joints cost less there than building arrays would.
"""

from __future__ import annotations

from collections.abc import Sequence


def path_violation(desired: Sequence[float], actual: Sequence[float], tolerance: Sequence[float]) -> int | None:
    """Index of the first joint farther than its (positive) tolerance from its desired position, or None."""
    for k, (d, a, tol) in enumerate(zip(desired, actual, tolerance)):
        if tol > 0 and abs(d - a) > tol:
            return k
    return None


def goal_reached(desired: Sequence[float], actual: Sequence[float], velocity: Sequence[float],
                 tolerance: Sequence[float], stopped_velocity: float, *, velocity_always: bool = False) -> bool:
    """Every joint within its (positive) goal tolerance, and, if any tolerance is set, every joint's
    speed at most ``stopped_velocity``. Without any tolerance a goal is reached at its end.

    ``velocity_always`` (ros2_controllers' JointTrajectoryController): the speeds are checked against a
    positive ``stopped_velocity`` whether or not a position tolerance is set."""
    if velocity_always:
        return (all(tol <= 0 or abs(d - a) <= tol for d, a, tol in zip(desired, actual, tolerance))
                and (stopped_velocity <= 0 or all(abs(v) <= stopped_velocity for v in velocity)))
    if not any(tol > 0 for tol in tolerance):
        return True
    return (all(tol <= 0 or abs(d - a) <= tol for d, a, tol in zip(desired, actual, tolerance))
            and all(abs(v) <= stopped_velocity for v in velocity))


def worst_joint(desired: Sequence[float], actual: Sequence[float]) -> int:
    """Index of the joint farthest from its desired position (the first of equals)."""
    errors = [abs(d - a) for d, a in zip(desired, actual)]
    return errors.index(max(errors))

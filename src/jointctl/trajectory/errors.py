"""Trajectory refusals with control_msgs/FollowJointTrajectory result codes."""

from __future__ import annotations

from enum import IntEnum
from typing import Any

from jointctl.errors import JointCtlError, _UNSET


class TrajectoryErrorCode(IntEnum):
    """``control_msgs/FollowJointTrajectoryResult`` error codes (same integers)."""

    SUCCESSFUL = 0
    INVALID_GOAL = -1
    INVALID_JOINTS = -2
    OLD_HEADER_TIMESTAMP = -3
    PATH_TOLERANCE_VIOLATED = -4
    GOAL_TOLERANCE_VIOLATED = -5


class InvalidTrajectory(JointCtlError):
    """A trajectory was refused. ``error_code`` is the FollowJointTrajectory code; the
    message names the point index, the joint and the value where they apply."""

    code = "trajectory"

    def __init__(self, error_code: TrajectoryErrorCode, message: str, *, point: int | None = None,
                 joint: str | None = None, value: Any = _UNSET, field: str | None = None) -> None:
        where = []
        if point is not None:
            where.append(f"points[{point}]")
        if field:
            where.append(field)
        if joint is not None:
            where.append(f"joint {joint!r}")
        super().__init__(f"{error_code.name}: {message}", field=" ".join(where) or None, value=value)
        self.error_code = error_code
        self.point = point
        self.joint = joint

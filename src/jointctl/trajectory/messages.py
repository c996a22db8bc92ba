"""``trajectory_msgs/JointTrajectory`` and ``JointTrajectoryPoint`` with ROS field names and meaning.

Times are float seconds: ``stamp_s`` is the header stamp (when the trajectory
starts; 0 means "start now", as in ROS) and ``time_from_start_s`` each point's
time after the start. Positions in m or rad, velocities per second,
accelerations per second squared, effort in N or N·m. Empty vectors mean "not
given". The ROS edge converts to and from the ROS messages field by field.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class JointTrajectoryPoint:
    """One waypoint: values per joint (in the trajectory's ``joint_names`` order) and its time."""

    positions: tuple[float, ...] = ()
    velocities: tuple[float, ...] = ()
    accelerations: tuple[float, ...] = ()
    effort: tuple[float, ...] = ()
    time_from_start_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("positions", "velocities", "accelerations", "effort"):
            object.__setattr__(self, name, _as_tuple(getattr(self, name)))


@dataclass(frozen=True)
class JointTrajectory:
    """A joint-space trajectory: ``joint_names`` and time-stamped ``points``."""

    joint_names: tuple[str, ...]
    points: tuple[JointTrajectoryPoint, ...]
    stamp_s: float = 0.0
    frame_id: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "joint_names", _as_tuple(self.joint_names))
        object.__setattr__(self, "points", _as_tuple(self.points))

    @classmethod
    def from_arrays(
        cls,
        joint_names: Sequence[str],
        times_s: Sequence[float],
        positions: Any,
        velocities: Any = None,
        accelerations: Any = None,
        *,
        stamp_s: float = 0.0,
    ) -> JointTrajectory:
        """Build from arrays shaped (points,) and (points, joints)."""
        positions = np.asarray(positions, dtype=float)
        rows = []
        for k, t in enumerate(times_s):
            rows.append(JointTrajectoryPoint(
                positions=tuple(positions[k].tolist()),
                velocities=() if velocities is None else tuple(np.asarray(velocities, float)[k].tolist()),
                accelerations=() if accelerations is None else tuple(np.asarray(accelerations, float)[k].tolist()),
                time_from_start_s=float(t),
            ))
        return cls(tuple(joint_names), tuple(rows), stamp_s=stamp_s)

    def to_dict(self) -> dict[str, Any]:
        """The ROS message as nested plain data (YAML/JSON), times in seconds."""
        return {
            "header": {"stamp": self.stamp_s, "frame_id": self.frame_id},
            "joint_names": list(self.joint_names),
            "points": [
                {"positions": list(p.positions), "velocities": list(p.velocities),
                 "accelerations": list(p.accelerations), "effort": list(p.effort),
                 "time_from_start": p.time_from_start_s}
                for p in self.points
            ],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> JointTrajectory:
        """Inverse of :meth:`to_dict`; values are checked later by validation. Data that
        cannot even be read as a trajectory is refused as INVALID_GOAL."""
        try:
            return cls._from_dict(data)
        except (TypeError, AttributeError, ValueError) as exc:
            from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode

            raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL,
                                    f"not a trajectory message: {exc}") from None

    @classmethod
    def _from_dict(cls, data: Mapping[str, Any]) -> JointTrajectory:
        header = data.get("header") or {}
        return cls(
            joint_names=tuple(data.get("joint_names") or ()),
            points=tuple(
                JointTrajectoryPoint(
                    positions=tuple(p.get("positions") or ()),
                    velocities=tuple(p.get("velocities") or ()),
                    accelerations=tuple(p.get("accelerations") or ()),
                    effort=tuple(p.get("effort") or ()),
                    time_from_start_s=p.get("time_from_start", 0.0),
                )
                for p in data.get("points") or ()
            ),
            stamp_s=header.get("stamp", 0.0),
            frame_id=header.get("frame_id", ""),
        )


def _as_tuple(value: Any) -> Any:
    """Lists and other sequences become tuples; a string or a non-sequence stays as it is,
    for validation to refuse (a string must not turn into its letters)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        return value
    return tuple(value.tolist() if isinstance(value, np.ndarray) else value)


@dataclass(frozen=True)
class JointSpec:
    """What validation and timing need to know about one controlled joint (SI units).

    ``lower``/``upper`` are None for a continuous joint; limits of
    ``math.inf`` mean "not limited".
    """

    name: str
    lower: float | None
    upper: float | None
    max_velocity: float
    max_acceleration: float = float("inf")
    max_jerk: float = float("inf")
    max_effort: float = float("inf")
    extra: Mapping[str, Any] = field(default_factory=dict)

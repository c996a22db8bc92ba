"""What ROS-Industrial's client sends for a trajectory: each point's speed fraction and duration.

ROS-I's ``industrial_robot_client`` (``JointTrajectoryInterface::calc_velocity`` and
``calc_duration``) turns every point of a ``trajectory_msgs/JointTrajectory`` into a JOINT_TRAJ_PT
whose ``velocity`` is a **fraction of the maximum speed** and whose ``duration`` is the **time of
the segment that ends at the point**. A controller program that scales its motion by the fraction
(most industrial ones) or that reaches each point over its duration moves as the goal says only
when both are what the reference client computes, so jointctl computes them the same way:

- ``speed_fraction``: over the joints whose speed limit is known, the largest ``|v_i| / v_max,i``
  of the point's velocities (rad/s or m/s against the URDF's ``<limit velocity>``), clipped to
  [0, 1]. The default fraction (ROS-I's ``default_vel_ratio``, 0.1) when the point has no
  velocities, when no joint's limit is known, or when that largest ratio is 0: a point whose
  velocities are all zero (the last point of a planned trajectory) moves at 10 %, never at 0.
- ``duration``: ``time_from_start`` of the point minus that of the previous point [s]; the default
  duration (ROS-I's ``default_duration``, 10 s) when time does not increase.

Where jointctl differs, on purpose (docs/industrial.md): ROS-I measures the first point's duration
from the previous *goal's* last point (a static variable shared by every trajectory of the node), so
every goal after the first starts with a 10 s segment; jointctl measures it from the goal's start.
A first point at time 0 is where the robot already is (the executor refuses one that is not), so
jointctl does not send it; ROS-I sends it with its 10 s default, which a controller that honours
durations spends standing still.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

#: ROS-I's ``default_vel_ratio_``: the speed fraction when a point has no usable velocities.
DEFAULT_SPEED_FRACTION = 0.1
#: ROS-I's ``default_duration_`` [s]: a point's duration when time does not increase.
DEFAULT_DURATION_S = 10.0


def speed_fraction(velocities: Sequence[float] | None, max_velocities: Sequence[float], *,
                   default: float = DEFAULT_SPEED_FRACTION) -> float:
    """The speed fraction ROS-I's client sends for a point with ``velocities`` (None: none given),
    one per joint in the order of ``max_velocities`` (the joints' speed limits; ``inf``, ``nan`` or
    <= 0 where unknown)."""
    if velocities is None or len(velocities) == 0:
        return default
    largest = -1.0
    for v, limit in zip(velocities, max_velocities):
        if math.isfinite(limit) and limit > 0:
            largest = max(largest, abs(v / limit))
    fraction = largest if largest > 0 else default
    return min(1.0, max(0.0, fraction))


@dataclass(frozen=True)
class WirePoint:
    """One point as it goes to the controller: ``time_s`` its time from the goal's start [s],
    ``positions`` (rad or m), ``velocities`` and ``accelerations`` (per s, per s²; None when the goal
    gave none), ``speed_fraction`` in [0, 1] and ``duration_s`` of the segment that ends here [s]."""

    time_s: float
    positions: tuple[float, ...]
    velocities: tuple[float, ...] | None
    accelerations: tuple[float, ...] | None
    speed_fraction: float
    duration_s: float


def wire_points(times_s: Sequence[float], positions: Sequence[Sequence[float]],
                velocities: Sequence[Sequence[float]] | None, accelerations: Sequence[Sequence[float]] | None,
                max_velocities: Sequence[float], *, default_speed: float = DEFAULT_SPEED_FRACTION,
                default_duration_s: float = DEFAULT_DURATION_S) -> list[WirePoint]:
    """The points of a trajectory (``times_s`` from its start, one row of joint values per point) as
    ROS-I's client sends them: speed fraction and duration per point (see the module docstring). A
    first point at time 0 (or before) is left out: it is where the robot already is."""
    out: list[WirePoint] = []
    previous = 0.0
    for k, t in enumerate(times_s):
        t = float(t)
        if k == 0 and t <= 0.0:
            continue
        v = tuple(map(float, velocities[k])) if velocities is not None else None
        a = tuple(map(float, accelerations[k])) if accelerations is not None else None
        duration = t - previous if t > previous else default_duration_s
        out.append(WirePoint(t, tuple(map(float, positions[k])), v, a,
                             speed_fraction(v, max_velocities, default=default_speed), duration))
        previous = t
    return out


__all__ = ["DEFAULT_DURATION_S", "DEFAULT_SPEED_FRACTION", "WirePoint", "speed_fraction", "wire_points"]

"""The trajectory generator of a simulated industrial controller: a queue of points, followed.

An industrial controller interpolates by itself (chapter 11.5): the PC sends joint positions,
each with the time its segment should take, and the controller moves there on its own clock.
:class:`Interpolator` is that program's motion part, pure (no sockets, threads or simulator):

- **Segments are linear in joint space** (the book's example server and ROS-Industrial's
  industrial_robot_simulator interpolate so), from the reference where the previous segment ended
  (or where the reference rests when idle) to the point, over
  ``T = max(duration, max_i |Δq_i| / (v_frac·vmax_i) if v_frac > 0, max_i |Δq_i| / vmax_i)``:
  never faster than the point's speed fraction of the joint limits, never faster than the limits.
  A fraction of 0 means "no fraction given" (ROS-I sends 0 when a point's velocities are zero,
  its last point for one): only the limits apply. The velocity reference is ``Δq / T`` during a
  segment and steps between segments; the joint controllers smooth it.
- **Time is exact**: :meth:`step` crosses as many segment boundaries as its ``dt`` covers,
  carrying the time left into the next segment, and evaluates positions from each segment's start
  and elapsed time, so the last point is reached exactly and nothing drifts.
- **Stop** decelerates every joint from its current velocity at its ``deceleration`` (a linear
  ramp of velocity to zero; the joints need not end together), clamped within the joint's range,
  and clears the queue.
- **Refusals**: a point with the wrong joint count, a non-finite number, a position outside the
  joint's range, a speed fraction outside [0, 1] or a negative duration is refused with
  :class:`RefusedPoint` (an ``error_code`` for the controller's STATUS) before anything changes.

Units: joint values in rad or m, velocities per second, durations in s.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from jointctl.errors import JointCtlError

ERROR_POSITION_LIMIT = 1
ERROR_NOT_FINITE = 2
ERROR_BAD_VELOCITY = 3
ERROR_BAD_DURATION = 4
ERROR_JOINT_COUNT = 5


class RefusedPoint(JointCtlError):
    """A point the controller will not move to; ``error_code`` is what STATUS reports."""

    code = "refused_point"

    def __init__(self, message: str, *, error_code: int, field: str, value) -> None:
        super().__init__(message, source="industrial controller", field=field, value=value)
        self.error_code = error_code


class QueueFull(JointCtlError):
    """The controller's point queue is full: the sender must wait (flow control)."""

    code = "queue_full"


@dataclass(frozen=True)
class JointLimits:
    """One joint's range [rad or m] (±inf when none), velocity limit [/s] and stopping
    deceleration [/s²]."""

    lower: float
    upper: float
    velocity: float
    deceleration: float

    @classmethod
    def from_model(cls, robot, joint_names: Sequence[str], *, stop_time_s: float = 0.2) -> tuple[JointLimits, ...]:
        """Limits of ``joint_names`` from the robot model; a joint at full speed stops within
        ``stop_time_s`` (joints without a velocity limit: 1 /s, stopping at 5 /s²)."""
        out = []
        for name in joint_names:
            limits = robot.joint(name).limits
            lower = limits.lower if limits is not None and limits.lower is not None else -math.inf
            upper = limits.upper if limits is not None and limits.upper is not None else math.inf
            if robot.joint(name).type == "continuous":
                lower, upper = -math.inf, math.inf
            velocity = limits.velocity if limits is not None and limits.velocity and limits.velocity > 0 else 1.0
            out.append(cls(lower, upper, velocity, velocity / stop_time_s))
        return tuple(out)


@dataclass(frozen=True)
class Point:
    """A trajectory point: ``positions`` [rad or m] per joint, ``velocity`` a fraction of each
    joint's maximum speed in [0, 1] (0: none given), ``duration`` [s] of the segment ending here."""

    positions: tuple[float, ...]
    velocity: float
    duration: float


class Interpolator:
    """The controller's trajectory generator (see the module docstring)."""

    def __init__(self, limits: Sequence[JointLimits], start: Sequence[float], *, capacity: int = 32) -> None:
        if len(start) != len(limits):
            raise ValueError("one start position per joint")
        if capacity < 1:
            raise ValueError("capacity must be at least 1")
        self.limits = tuple(limits)
        self.capacity = capacity
        self._queue: deque[Point] = deque()
        self.position = [float(q) for q in start]
        self.velocity = [0.0] * len(self.limits)
        # The segment in progress: its start, its change, its length and the time spent in it.
        self._segment: tuple[list[float], list[float], float] | None = None
        self._elapsed = 0.0
        self._stopping = False

    # -- points ------------------------------------------------------------------------------------
    def check(self, point: Point) -> None:
        """Raise :class:`RefusedPoint` if ``point`` cannot be executed; changes nothing."""
        positions = point.positions
        if len(positions) != len(self.limits):
            raise RefusedPoint(f"needs {len(self.limits)} joint positions", error_code=ERROR_JOINT_COUNT,
                               field="positions", value=len(positions))
        for i, (q, lim) in enumerate(zip(positions, self.limits)):
            if not isinstance(q, (int, float)) or not math.isfinite(q):
                raise RefusedPoint("must be a finite number", error_code=ERROR_NOT_FINITE,
                                   field=f"positions[{i}]", value=q)
            if not lim.lower <= q <= lim.upper:
                raise RefusedPoint(f"outside the joint's range [{lim.lower:g}, {lim.upper:g}]",
                                   error_code=ERROR_POSITION_LIMIT, field=f"positions[{i}]", value=q)
        v = point.velocity
        if not isinstance(v, (int, float)) or not math.isfinite(v):
            raise RefusedPoint("must be a finite number", error_code=ERROR_NOT_FINITE, field="velocity", value=v)
        if not 0.0 <= v <= 1.0:
            raise RefusedPoint("must be a fraction of the maximum speed in [0, 1]", error_code=ERROR_BAD_VELOCITY,
                               field="velocity", value=v)
        d = point.duration
        if not isinstance(d, (int, float)) or not math.isfinite(d):
            raise RefusedPoint("must be a finite number", error_code=ERROR_NOT_FINITE, field="duration", value=d)
        if d < 0:
            raise RefusedPoint("must not be negative", error_code=ERROR_BAD_DURATION, field="duration", value=d)

    def push(self, point: Point) -> None:
        """Check ``point`` and queue it (:class:`RefusedPoint`, or :class:`QueueFull` at capacity)."""
        self.check(point)
        if self.full:
            raise QueueFull(f"the queue holds {self.capacity} points", field="queue", value=len(self._queue))
        self._queue.append(Point(tuple(float(q) for q in point.positions), float(point.velocity),
                                 float(point.duration)))

    @property
    def full(self) -> bool:
        return len(self._queue) >= self.capacity

    def __len__(self) -> int:
        """Queued points (the segment in progress not counted)."""
        return len(self._queue)

    def new_trajectory(self) -> None:
        """Forget the queued points and the segment in progress: the next point starts from the
        current reference."""
        self._queue.clear()
        self._segment = None
        self._elapsed = 0.0

    def stop(self) -> None:
        """Decelerate to rest within each joint's deceleration and clear the queue."""
        self.new_trajectory()
        self._stopping = any(v != 0.0 for v in self.velocity)

    @property
    def in_motion(self) -> bool:
        """True while a segment, a stop or queued points are in progress."""
        return self._segment is not None or self._stopping or bool(self._queue)

    # -- time --------------------------------------------------------------------------------------
    def step(self, dt: float) -> tuple[list[float], list[float]]:
        """Advance ``dt`` seconds; the (positions, velocities) references per joint."""
        if self._stopping:
            self._brake(dt)
            return self.position, self.velocity
        left = dt
        while True:
            if self._segment is None:
                if not self._queue:
                    self.velocity = [0.0] * len(self.limits)
                    return self.position, self.velocity
                self._begin(self._queue.popleft())
            start, change, length = self._segment
            if self._elapsed + left < length:
                self._elapsed += left
                s = self._elapsed / length
                self.position = [a + s * d for a, d in zip(start, change)]
                self.velocity = [d / length for d in change]
                return self.position, self.velocity
            left -= length - self._elapsed  # the segment ends within this step
            self.position = [a + d for a, d in zip(start, change)]
            self._segment, self._elapsed = None, 0.0
            if not self._queue:
                self.velocity = [0.0] * len(self.limits)
                return self.position, self.velocity

    def _begin(self, point: Point) -> None:
        start = list(self.position)
        change = [q - a for q, a in zip(point.positions, start)]
        length = point.duration
        for d, lim in zip(change, self.limits):
            length = max(length, abs(d) / lim.velocity)
            if point.velocity > 0:
                length = max(length, abs(d) / (point.velocity * lim.velocity))
        if length <= 0.0:  # no motion and no time: done at once
            self.position = [float(q) for q in point.positions]
            return
        self._segment, self._elapsed = (start, change, length), 0.0

    def _brake(self, dt: float) -> None:
        moving = False
        for i, (v, lim) in enumerate(zip(self.velocity, self.limits)):
            if v == 0.0:
                continue
            a = lim.deceleration
            t = min(dt, abs(v) / a)  # time braking in this step
            sign = 1.0 if v > 0 else -1.0
            q = self.position[i] + v * t - 0.5 * sign * a * t * t
            v_new = v - sign * a * t
            if t < dt or abs(v_new) < 1e-12:
                v_new = 0.0
            if q <= lim.lower or q >= lim.upper:
                q, v_new = min(max(q, lim.lower), lim.upper), 0.0
            self.position[i], self.velocity[i] = q, v_new
            moving = moving or v_new != 0.0
        self._stopping = moving


__all__ = ["ERROR_BAD_DURATION", "ERROR_BAD_VELOCITY", "ERROR_JOINT_COUNT", "ERROR_NOT_FINITE",
           "ERROR_POSITION_LIMIT", "Interpolator", "JointLimits", "Point", "QueueFull", "RefusedPoint"]

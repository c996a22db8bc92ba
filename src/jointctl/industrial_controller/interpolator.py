"""The trajectory generator of a simulated industrial controller: a queue of points, followed.

An industrial controller interpolates by itself (chapter 11.5): the PC sends joint positions, each
with the time its segment should take and a fraction of the maximum speed (ROS-Industrial's
``JOINT_TRAJ_PT``), and the controller moves there on its own clock. :class:`Interpolator` is that
program's motion part, pure (no sockets, threads or simulator). Joint values are in rad (revolute)
or m (prismatic), velocities per second, decelerations per second², times in s; joint ``i`` is
joint ``i`` of the limits given.

Choices, as an industrial controller makes them:

- **Segments are linear in joint space** (the book's example server and ROS-Industrial's
  industrial_robot_simulator interpolate so), from the reference where the previous segment ended
  (or where the reference rests when idle) to the point, over
  ``T = max(duration, max_i |Δq_i| / (v_frac·vmax_i))``: no sooner than the point's duration and
  never faster than its speed fraction of the joint limits (a fraction of 1: the limits). All joints
  start and arrive together. A fraction of 0 is refused, as a controller that scales its speed by
  it must (the point would never be reached); ROS-I's client never sends one. A point where the
  reference already is, with a duration, is a dwell of that duration; with duration 0 it completes
  at once. The velocity reference is ``Δq / T`` during a segment and steps between segments (and
  to 0 at the last point, which is reached exactly): the joint servos smooth it.
- **Points with velocities** (a JOINT_TRAJ_PT_FULL's, reached by its time): the segment is the
  Hermite cubic from the reference's position and velocity to the point's, over its ``T``; the
  position, velocity and acceleration references follow the cubic. One that ends moving with no
  point after it brakes, as below.
- **Time is exact**: :meth:`step` crosses as many segment boundaries as its ``dt`` covers, carrying
  the time left into the next segment, and evaluates each position from its segment's start and
  the time spent in it, so nothing drifts and the last point's positions are reached bit for bit.
  A segment whose end is less than 1 ns away counts as ended (sums of ``dt`` round).
- **Stop** (:meth:`stop`, ROS-I's ``STOP_TRAJECTORY``) clears the queue and ramps each joint's
  velocity linearly from its current value to zero at the joint's ``deceleration`` (the joints need
  not end together; the distance is ``v²/(2a)``, integrated exactly); the acceleration reference is
  that deceleration, for the servos to feed forward. Points pushed while stopping
  wait until every joint is at rest, then motion resumes from the rest position.
- **New trajectory** (:meth:`new_trajectory`, a sequence number back to 0) forgets the queue and
  abandons the segment in progress; the reference keeps its position and velocity, and the next
  point's segment starts from the reference at the step that takes it. If a step finds nothing to
  move to while the reference still moves, the reference brakes as in a stop (never an instant
  halt from speed), until a point arrives or it is at rest.
- **Nothing leaves [lower, upper]**: points outside a joint's range are refused, braking is clamped
  at the range's ends (a joint that reaches one stops there), and positions are clamped against
  rounding. simple_message carries float32, so a point beyond a limit by no more than float32
  rounding (``|limit|·2⁻²³``) is accepted and queued at the limit itself; a start position outside
  the range is clamped into it.
- **Refusals**: a point with the wrong joint count, a non-finite number (positions, velocity or
  duration: :data:`ERROR_NOT_FINITE`), a position outside the joint's range, a speed fraction
  outside [0, 1] or a negative duration is refused with :class:`RefusedPoint`, which names the
  field and the value and carries the ``error_code`` for the controller's STATUS, before anything
  changes. A full queue raises :class:`QueueFull` (flow control: reply to the sender later).
- **Cost**: :meth:`step` uses plain floats and lists (a few list comprehensions over the joints).
  It returns fresh lists, which the caller may keep or change.
"""

from __future__ import annotations

import math
import numbers
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from jointctl.errors import JointCtlError

#: ``error_code`` values of :class:`RefusedPoint`, reported in the controller's STATUS.
ERROR_POSITION_LIMIT = 1
ERROR_NOT_FINITE = 2
ERROR_BAD_VELOCITY = 3
ERROR_BAD_DURATION = 4
ERROR_JOINT_COUNT = 5

#: A segment (or a joint's braking) whose end is nearer than this [s] is finished in the current step.
TIME_EPS_S = 1e-9
#: Relative tolerance on joint limits for positions that went through float32 (one float32 ulp).
FLOAT32_REL_TOL = 2.0**-23


class RefusedPoint(JointCtlError):
    """A point the controller will not move to. ``field`` is ``"positions"`` (joint count),
    ``"positions[i]"``, ``"velocity"`` or ``"duration"``; ``value`` the offending value;
    ``error_code`` one of the ``ERROR_*`` codes, for the controller's STATUS."""

    code = "refused_point"

    def __init__(self, message: str, *, error_code: int, field: str, value: object) -> None:
        super().__init__(message, field=field, value=value)
        self.error_code = error_code


class QueueFull(JointCtlError):
    """The point queue is at capacity: the sender must wait (the controller holds back its reply)."""

    code = "queue_full"


@dataclass(frozen=True)
class JointLimits:
    """One joint's limits for the controller.

    ``lower``/``upper``: range [rad or m], ``-inf``/``+inf`` when the joint has none.
    ``velocity``: maximum speed [rad/s or m/s], > 0, ``inf`` when unknown.
    ``deceleration``: [rad/s² or m/s²], > 0, used to stop; ``inf`` stops at once.
    """

    lower: float
    upper: float
    velocity: float
    deceleration: float

    def __post_init__(self) -> None:
        if math.isnan(self.lower) or math.isnan(self.upper) or self.lower > self.upper:
            raise JointCtlError(f"the range must be numbers with lower <= upper (upper is {self.upper!r})",
                                field="lower", value=self.lower)
        if not self.velocity > 0:
            raise JointCtlError("must be positive [rad/s or m/s] (inf if unknown)", field="velocity",
                                value=self.velocity)
        if not self.deceleration > 0:
            raise JointCtlError("must be positive [rad/s² or m/s²]", field="deceleration",
                                value=self.deceleration)

    @classmethod
    def from_model(cls, robot, joint_names: Sequence[str], *,
                   stop_time_s: float = 0.2) -> tuple[JointLimits, ...]:
        """The limits of ``joint_names`` (in that order) from a :class:`jointctl.model.RobotModel`.

        Range and velocity are the URDF's ``<limit>``: continuous joints have no range (±inf), a
        joint without a ``<limit>`` or with velocity 0 has an unknown velocity (inf). The
        deceleration is ``velocity / stop_time_s`` [s]: a joint at full speed stops within
        ``stop_time_s`` (at once when its velocity is unknown).
        """
        if not (isinstance(stop_time_s, numbers.Real) and 0 < stop_time_s < math.inf):
            raise JointCtlError("must be a positive number of seconds", field="stop_time_s", value=stop_time_s)
        out = []
        for i, name in enumerate(joint_names):
            if not robot.has_joint(name):
                raise JointCtlError(f"no such joint in robot {robot.name!r}", field=f"joint_names[{i}]",
                                    value=name)
            joint = robot.joint(name)
            if not joint.is_movable:
                raise JointCtlError(f"is a {joint.type} joint that does not move", field=f"joint_names[{i}]",
                                    value=name)
            lower, upper, velocity = joint.range_and_speed()
            out.append(cls(lower, upper, velocity, velocity / stop_time_s))
        return tuple(out)


@dataclass(frozen=True)
class Point:
    """A trajectory point: ``positions`` [rad or m], one per joint; ``velocity`` a fraction of each
    joint's maximum speed in (0, 1]; ``duration`` [s] of the segment that ends at this point, >= 0;
    ``velocities`` [per s], one per joint, when the point gives the joints' velocities there (a
    JOINT_TRAJ_PT_FULL point): the segment is then a cubic through both ends' positions and velocities."""

    positions: tuple[float, ...]
    velocity: float
    duration: float
    velocities: tuple[float, ...] | None = None


def _is_number(x: object) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


class Interpolator:
    """The controller's trajectory generator: a queue of points, followed from where the robot's
    reference is (see the module docstring for the choices).

    ``limits``: one :class:`JointLimits` per joint. ``start``: the reference's initial positions
    [rad or m] (clamped into the ranges). ``capacity``: how many points the queue holds (the segment
    in progress not counted).
    """

    def __init__(self, limits: Sequence[JointLimits], start: Sequence[float], *, capacity: int = 32) -> None:
        self.limits = tuple(limits)
        if not self.limits or not all(isinstance(lim, JointLimits) for lim in self.limits):
            raise JointCtlError("needs one JointLimits per joint, at least one", field="limits", value=limits)
        if len(start) != len(self.limits):
            raise JointCtlError(f"needs {len(self.limits)} positions, one per joint", field="start",
                                value=list(start))
        for i, q in enumerate(start):
            if not (_is_number(q) and math.isfinite(q)):
                raise JointCtlError("must be a finite number [rad or m]", field=f"start[{i}]", value=q)
        if not (isinstance(capacity, int) and not isinstance(capacity, bool) and capacity >= 1):
            raise JointCtlError("must be a whole number of points, at least 1", field="capacity", value=capacity)
        self.capacity = capacity
        self._lower = [lim.lower for lim in self.limits]
        self._upper = [lim.upper for lim in self.limits]
        self._vmax = [lim.velocity for lim in self.limits]
        self._decel = [lim.deceleration for lim in self.limits]
        self._zeros = [0.0] * len(self.limits)
        self._q = [min(max(float(q), lo), hi) for q, lo, hi in zip(start, self._lower, self._upper)]
        self._v = list(self._zeros)
        self._a = list(self._zeros)
        self._queue: deque[Point] = deque()
        # The segment in progress: start, change, end positions, velocity, length T [s]; and, for a
        # cubic segment, the start and end velocities (None for a linear one).
        self._seg: tuple[list[float], list[float], list[float], list[float], float] | None = None
        self._ends: tuple[list[float], list[float]] | None = None
        self._seg_t = 0.0
        self._stopping = False  # a stop(): brake to rest, queued points wait
        self._braking = False  # a segment abandoned by new_trajectory(): brake until a point comes

    # -- points ------------------------------------------------------------------------------------
    def check(self, point: Point) -> None:
        """Raise :class:`RefusedPoint` if ``point`` cannot be executed; changes nothing."""
        positions = point.positions
        try:
            count = len(positions)
        except TypeError:
            count = None
        if count != len(self.limits):
            raise RefusedPoint(f"needs {len(self.limits)} joint positions", error_code=ERROR_JOINT_COUNT,
                               field="positions", value=count)
        for i, q in enumerate(positions):
            if not (_is_number(q) and math.isfinite(q)):
                raise RefusedPoint("must be a finite number [rad or m]", error_code=ERROR_NOT_FINITE,
                                   field=f"positions[{i}]", value=q)
            lo, hi = self._lower[i], self._upper[i]
            if q < lo - abs(lo) * FLOAT32_REL_TOL or q > hi + abs(hi) * FLOAT32_REL_TOL:
                raise RefusedPoint(f"outside the joint's range [{lo:g}, {hi:g}]", error_code=ERROR_POSITION_LIMIT,
                                   field=f"positions[{i}]", value=q)
        v = point.velocity
        if not (_is_number(v) and math.isfinite(v)):
            raise RefusedPoint("must be a finite number", error_code=ERROR_NOT_FINITE, field="velocity", value=v)
        if not 0.0 < v <= 1.0:
            raise RefusedPoint("must be a fraction of the maximum speed in (0, 1] (at 0 the point is never "
                               "reached)", error_code=ERROR_BAD_VELOCITY, field="velocity", value=v)
        if point.velocities is not None:
            if len(point.velocities) != len(self.limits):
                raise RefusedPoint(f"needs {len(self.limits)} joint velocities", error_code=ERROR_JOINT_COUNT,
                                   field="velocities", value=len(point.velocities))
            for i, (vi, vmax) in enumerate(zip(point.velocities, self._vmax)):
                if not (_is_number(vi) and math.isfinite(vi)):
                    raise RefusedPoint("must be a finite number [per s]", error_code=ERROR_NOT_FINITE,
                                       field=f"velocities[{i}]", value=vi)
                if abs(vi) > vmax * (1.0 + FLOAT32_REL_TOL):
                    raise RefusedPoint(f"above the joint's speed limit {vmax:g}", error_code=ERROR_BAD_VELOCITY,
                                       field=f"velocities[{i}]", value=vi)
        d = point.duration
        if not (_is_number(d) and math.isfinite(d)):
            raise RefusedPoint("must be a finite number [s]", error_code=ERROR_NOT_FINITE, field="duration", value=d)
        if d < 0:
            raise RefusedPoint("must not be negative [s]", error_code=ERROR_BAD_DURATION, field="duration", value=d)

    def push(self, point: Point) -> None:
        """Check ``point`` (:class:`RefusedPoint`) and queue it (:class:`QueueFull` at capacity).

        Positions within float32 rounding beyond a limit are queued at the limit."""
        self.check(point)
        if self.full:
            raise QueueFull(f"the queue holds {self.capacity} points; wait for the robot to take one",
                            field="queue", value=len(self._queue))
        positions = tuple(min(max(float(q), lo), hi) for q, lo, hi in zip(point.positions, self._lower, self._upper))
        velocities = None if point.velocities is None else tuple(map(float, point.velocities))
        self._queue.append(Point(positions, float(point.velocity), float(point.duration), velocities))

    @property
    def full(self) -> bool:
        """True when :meth:`push` would raise :class:`QueueFull`."""
        return len(self._queue) >= self.capacity

    def __len__(self) -> int:
        """Queued points (the segment in progress not counted)."""
        return len(self._queue)

    def new_trajectory(self) -> None:
        """Forget the queued points and abandon the segment in progress. The reference keeps its
        position and velocity; the next point starts from it. With no point to go to, a moving
        reference brakes at each joint's deceleration (as in :meth:`stop`)."""
        self._queue.clear()
        self._ends = None
        if self._seg is not None:
            self._seg = None
            self._seg_t = 0.0
            self._braking = not self._stopping and any(v != 0.0 for v in self._v)

    def stop(self) -> None:
        """Clear the queue and decelerate every joint from its current velocity to rest at its
        ``deceleration``, inside its range. :attr:`in_motion` stays True until at rest; points pushed
        meanwhile start from the rest position."""
        self._queue.clear()
        self._seg = None
        self._ends = None
        self._seg_t = 0.0
        self._braking = False
        self._stopping = any(v != 0.0 for v in self._v)

    @property
    def in_motion(self) -> bool:
        """True while a segment or a stop is in progress or points are queued; False at rest with an
        empty queue."""
        return self._seg is not None or self._stopping or self._braking or bool(self._queue)

    @property
    def position(self) -> list[float]:
        """The current position references [rad or m] (a copy)."""
        return list(self._q)

    @property
    def velocity(self) -> list[float]:
        """The current velocity references [rad/s or m/s] (a copy)."""
        return list(self._v)

    @property
    def acceleration(self) -> list[float]:
        """The current acceleration references [rad/s² or m/s²] (a copy): 0 on linear segments and at
        rest, the braking deceleration while stopping, the cubic's on a segment with end velocities."""
        return list(self._a)

    # -- time --------------------------------------------------------------------------------------
    def step(self, dt: float) -> tuple[list[float], list[float]]:
        """Advance ``dt`` [s] (>= 0, finite); return the (positions, velocities) references per joint."""
        if not 0.0 <= dt < math.inf:
            raise JointCtlError("must be a finite time step >= 0 [s]", field="dt", value=dt)
        left = dt
        while True:
            if self._stopping or self._braking:
                if self._braking and self._queue:
                    self._braking = False  # a point came: its segment starts from here
                    continue
                left = self._brake(left)
                if left is None:  # still braking
                    return list(self._q), list(self._v)
                self._stopping = self._braking = False
            seg = self._seg
            if seg is None:
                if not self._queue:
                    if any(v != 0.0 for v in self._v):  # a cubic ended moving, nothing follows: brake
                        self._braking = True
                        continue
                    self._v = list(self._zeros)
                    self._a = list(self._zeros)
                    return list(self._q), list(self._v)
                self._begin(self._queue.popleft())
                continue
            start, change, end, vel, length = seg
            remaining = length - self._seg_t
            if left < remaining - TIME_EPS_S:
                self._seg_t += left
                s = self._seg_t / length
                if self._ends is None:
                    self._q = [min(max(a + s * d, lo), hi)
                               for a, d, lo, hi in zip(start, change, self._lower, self._upper)]
                    self._v = list(vel)
                    self._a = list(self._zeros)
                else:
                    self._cubic(s, length)
                return list(self._q), list(self._v)
            # The segment ends within this step: its point exactly, and the rest of dt goes on.
            left = max(left - remaining, 0.0)
            self._q = list(end)
            self._seg = None
            self._seg_t = 0.0
            self._v = list(self._zeros) if self._ends is None else list(self._ends[1])
            self._a = list(self._zeros)
            self._ends = None

    def _begin(self, point: Point) -> None:
        """Start the segment from the reference to ``point`` (or complete it at once if it takes no
        time): ``T = max(duration, max_i |Δq_i| / (fraction · vmax_i))``, linear, or a cubic from the
        reference's velocity to the point's when it gives velocities."""
        start = self._q
        end = list(point.positions)
        change = [q - a for q, a in zip(end, start)]
        length = point.duration
        frac = point.velocity
        for d, vmax in zip(change, self._vmax):
            if d != 0.0:
                length = max(length, abs(d) / (frac * vmax))
        if length <= 0.0:  # nothing to move and no time to take (or no velocity limit): there at once
            self._q = end
            self._v = list(self._zeros) if point.velocities is None else list(point.velocities)
            return
        self._seg = (list(start), change, end, [d / length for d in change], length)
        self._ends = None if point.velocities is None else (list(self._v), list(point.velocities))
        self._seg_t = 0.0

    def _cubic(self, s: float, length: float) -> None:
        """Position, velocity and acceleration at ``s`` (0..1) of the cubic segment in progress: the
        Hermite cubic through both ends' positions and velocities over ``length`` [s]."""
        start, change, _, _, _ = self._seg
        v0, v1 = self._ends
        s2, s3 = s * s, s * s * s
        h10, h11 = s3 - 2 * s2 + s, s3 - s2
        h01 = -2 * s3 + 3 * s2
        d01, d10, d11 = (-6 * s2 + 6 * s) / length, 3 * s2 - 4 * s + 1, 3 * s2 - 2 * s
        dd01, dd10, dd11 = (-12 * s + 6) / length**2, (6 * s - 4) / length, (6 * s - 2) / length
        self._q = [min(max(a + h01 * d + length * (h10 * va + h11 * vb), lo), hi)
                   for a, d, va, vb, lo, hi in zip(start, change, v0, v1, self._lower, self._upper)]
        self._v = [d01 * d + d10 * va + d11 * vb for d, va, vb in zip(change, v0, v1)]
        self._a = [dd01 * d + dd10 * va + dd11 * vb for d, va, vb in zip(change, v0, v1)]

    def _brake(self, dt: float) -> float | None:
        """Decelerate every moving joint for up to ``dt``; the time left once all are at rest, else None."""
        q, v, acc = list(self._q), list(self._v), list(self._zeros)
        rest_after = 0.0  # time [s] into dt at which the last joint came to rest
        moving = False
        for i, vi in enumerate(v):
            if vi == 0.0:
                continue
            a = self._decel[i]
            t_rest = abs(vi) / a
            if t_rest <= dt + TIME_EPS_S:  # at rest within this step: the ramp's remaining area
                dist, v_new, t = 0.5 * vi * t_rest, 0.0, min(t_rest, dt)
                acc[i] = 0.0
            else:
                v_new = vi - math.copysign(a * dt, vi)
                dist, t = 0.5 * (vi + v_new) * dt, dt
                acc[i] = -math.copysign(a, vi)
            qi = q[i] + dist
            if qi >= self._upper[i]:
                qi, v_new = self._upper[i], 0.0
            elif qi <= self._lower[i]:
                qi, v_new = self._lower[i], 0.0
            q[i], v[i] = qi, v_new
            if v_new != 0.0:
                moving = True
            else:
                rest_after = max(rest_after, t)
        self._q, self._v, self._a = q, v, acc
        return None if moving else max(dt - rest_after, 0.0)


__all__ = ["ERROR_BAD_DURATION", "ERROR_BAD_VELOCITY", "ERROR_JOINT_COUNT", "ERROR_NOT_FINITE",
           "ERROR_POSITION_LIMIT", "FLOAT32_REL_TOL", "TIME_EPS_S", "Interpolator", "JointLimits", "Point",
           "QueueFull", "RefusedPoint"]

"""Check a :class:`JointTrajectory` against the controlled joints before anything moves.

:func:`validate_trajectory` either returns a :class:`ValidatedTrajectory`
(plain float64 arrays, columns in the controller's joint order, start time
resolved) or raises :class:`InvalidTrajectory` carrying the
``control_msgs/FollowJointTrajectoryResult`` code. Checks run in a fixed order
of priority, so a goal with several faults always gets the same answer:

1. ``INVALID_JOINTS``: no names, a name that is not a non-empty string, a
   duplicate name, a name that is not a controlled joint. A partial goal (a
   subset of the joints) is allowed; the joints it omits hold.
2. ``INVALID_GOAL``, in this order: no points; a point that is not a
   ``JointTrajectoryPoint``; a vector of the wrong length (positions are
   required, velocities/accelerations/effort are empty or one value a joint);
   velocities, accelerations or effort given in some points but not others;
   the header stamp or a ``time_from_start`` that is not a finite number, a
   negative time, times not strictly increasing; a value that is not a number
   (bools and strings are refused), NaN or infinite; a position outside its
   joint's range; a velocity above ``max_velocity``; a segment whose average
   speed ``|Δq|/Δt`` exceeds ``max_velocity`` (the first segment starts at the
   current position when the first point's time is > 0); a first point at
   time 0 more than ``start_tolerance`` away from the current position.
3. ``OLD_HEADER_TIMESTAMP``: a non-zero stamp whose trajectory has already
   ended (``stamp + last time_from_start < now``).

Within one check, points are scanned in order and, within a point, joints in
the goal's ``joint_names`` order; the first fault is reported. The message (with
the exception's ``field``/``value``) names the point index, the joint and the
offending value.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from jointctl.errors import ModelError
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.messages import JointSpec, JointTrajectory, JointTrajectoryPoint

__all__ = [
    "SPEED_RTOL",
    "ValidatedTrajectory",
    "joint_specs_from_model",
    "validate_trajectory",
]

#: Relative slack on the velocity and average-speed limits, so that a segment
#: computed as exactly ``max_velocity * Δt`` is not refused for a rounding error.
#: Segments also get a few ulps of their positions' magnitude as slack.
SPEED_RTOL = 1e-9
_POSITION_ROUNDING = 4 * float(np.finfo(np.float64).eps)

_GOAL = TrajectoryErrorCode.INVALID_GOAL
_JOINTS = TrajectoryErrorCode.INVALID_JOINTS
_OPTIONAL_FIELDS = ("velocities", "accelerations", "effort")
_VECTOR_FIELDS = ("positions", *_OPTIONAL_FIELDS)


@dataclass(frozen=True, eq=False)
class ValidatedTrajectory:
    """A trajectory that passed :func:`validate_trajectory`, ready to interpolate.

    Arrays are float64 and read-only; columns follow ``joint_names``, which is
    the goal's joints in the controller's order (the order of ``joints``).
    ``joint_indices`` are those joints' indices into ``joints``. Times are
    ``time_from_start``; the loop time of a point is ``start_time_s + times_s[k]``.
    """

    joint_names: tuple[str, ...]
    joint_indices: tuple[int, ...]
    times_s: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None
    effort: np.ndarray | None
    start_time_s: float

    @property
    def duration_s(self) -> float:
        """``time_from_start`` of the last point."""
        return float(self.times_s[-1])

    @property
    def end_time_s(self) -> float:
        """Loop time of the last point."""
        return self.start_time_s + self.duration_s


def validate_trajectory(
    trajectory: JointTrajectory,
    joints: Sequence[JointSpec],
    *,
    now_s: float,
    current_positions: Sequence[float],
    start_tolerance: float = 1e-3,
    check_velocity: bool = True,
) -> ValidatedTrajectory:
    """Check ``trajectory`` for the controlled ``joints`` and return it as arrays.

    ``current_positions`` are the joints' current desired positions, in the
    order of ``joints``; ``now_s`` is the loop time. ``check_velocity=False``
    skips the two speed checks (given velocities and segment average speeds).
    Raises :class:`InvalidTrajectory` for a bad goal and :class:`ValueError` for
    bad arguments from the caller (``joints``, ``current_positions``, ``now_s``).
    """
    joints = tuple(joints)
    current = _check_caller_arguments(joints, now_s, current_positions, start_tolerance)
    if not isinstance(trajectory, JointTrajectory):
        raise InvalidTrajectory(_GOAL, "expected a JointTrajectory", value=type(trajectory).__name__)

    names, goal_to_controller = _check_joint_names(trajectory, joints)
    n_joints = len(names)
    points = _check_points(trajectory, n_joints)
    present = _check_all_or_none(points)
    stamp_s = _check_stamp(trajectory)
    times = _check_times(points)
    values = _check_values(points, names, present)

    # Columns in the controller's order: goal column c goes to sorted position.
    order = sorted(range(n_joints), key=lambda c: goal_to_controller[c])
    specs = [joints[goal_to_controller[c]] for c in range(n_joints)]
    start = np.array([current[goal_to_controller[c]] for c in range(n_joints)], dtype=np.float64)
    positions = values["positions"]

    _check_position_limits(positions, names, specs)
    if check_velocity:
        if values["velocities"] is not None:
            _check_velocity_limits(values["velocities"], names, specs)
        _check_segment_speeds(times, positions, start, names, specs)
    _check_start(times, positions, start, names, start_tolerance)

    last = float(times[-1])
    if stamp_s != 0.0 and stamp_s + last < now_s:
        raise InvalidTrajectory(
            TrajectoryErrorCode.OLD_HEADER_TIMESTAMP,
            f"the goal ended at stamp + {last!r} s = {stamp_s + last!r} s, before now ({float(now_s)!r} s)",
            field="header.stamp", value=stamp_s)
    start_time_s = stamp_s if stamp_s != 0.0 else float(now_s)

    def columns(array: np.ndarray | None) -> np.ndarray | None:
        if array is None:
            return None
        out = np.ascontiguousarray(array[:, order], dtype=np.float64)
        out.flags.writeable = False
        return out

    times.flags.writeable = False
    return ValidatedTrajectory(
        joint_names=tuple(names[c] for c in order),
        joint_indices=tuple(goal_to_controller[c] for c in order),
        times_s=times,
        positions=columns(positions),
        velocities=columns(values["velocities"]),
        accelerations=columns(values["accelerations"]),
        effort=columns(values["effort"]),
        start_time_s=start_time_s,
    )


def joint_specs_from_model(robot: Any, names: Sequence[str]) -> tuple[JointSpec, ...]:
    """The :class:`JointSpec` of each named joint of ``robot`` (a :class:`~jointctl.model.RobotModel`).

    Reads the URDF ``<limit>``: continuous joints (or joints without
    ``<limit>``) get ``lower``/``upper`` None; a velocity or effort limit of 0 or
    missing means "not limited" (``inf``), as in the joint controllers. Raises
    :class:`~jointctl.errors.ModelError` for a name the model does not have or a
    joint that does not move (fixed, locked, floating, planar).
    """
    specs = []
    for i, name in enumerate(names):
        if not isinstance(name, str) or not robot.has_joint(name):
            raise ModelError("the robot model has no joint of that name", source=robot.source,
                             field=f"joints[{i}]", value=name)
        joint = robot.joint(name)
        if not joint.is_movable:
            raise ModelError(f"joint is not movable (type {joint.type}"
                             f"{', locked' if joint.is_locked else ''})",
                             source=robot.source, field=f"joints[{i}]", value=name)
        lim = joint.limits
        lower = upper = None
        velocity = effort = math.inf
        if lim is not None:
            if joint.type != "continuous":
                lower, upper = lim.lower, lim.upper
            if lim.velocity and lim.velocity > 0:
                velocity = float(lim.velocity)
            if lim.effort and lim.effort > 0:
                effort = float(lim.effort)
        specs.append(JointSpec(name=name, lower=lower, upper=upper, max_velocity=velocity,
                               max_effort=effort))
    return tuple(specs)


# ----------------------------------------------------------------------------- helpers


def _check_caller_arguments(joints: tuple[JointSpec, ...], now_s: Any, current_positions: Any,
                            start_tolerance: Any) -> np.ndarray:
    seen = set()
    for spec in joints:
        if not isinstance(spec, JointSpec):
            raise ValueError(f"joints must be JointSpec, got {type(spec).__name__}")
        if spec.name in seen:
            raise ValueError(f"joints name {spec.name!r} twice")
        seen.add(spec.name)
    current = np.asarray(current_positions, dtype=np.float64).reshape(-1)
    if current.shape != (len(joints),):
        raise ValueError(f"current_positions has {current.size} values for {len(joints)} joints")
    if not np.all(np.isfinite(current)):
        raise ValueError(f"current_positions must be finite, got {current.tolist()}")
    if not math.isfinite(now_s):
        raise ValueError(f"now_s must be finite, got {now_s!r}")
    if not start_tolerance >= 0:
        raise ValueError(f"start_tolerance must be >= 0, got {start_tolerance!r}")
    return current


def _as_float(value: Any) -> float | None:
    """``value`` as a float when it is a real number (not a bool); None otherwise.

    Non-finite results (and ints too large for a float) come back as NaN/inf so
    the caller can report them as such.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        return None
    try:
        return float(value)
    except OverflowError:
        try:
            return math.inf if value > 0 else -math.inf
        except Exception:  # noqa: BLE001 - a number that cannot even compare is not usable
            return math.nan
    except (TypeError, ValueError, ArithmeticError):
        return None


def _check_joint_names(trajectory: JointTrajectory, joints: tuple[JointSpec, ...]) -> tuple[list[str], list[int]]:
    raw = trajectory.joint_names
    if isinstance(raw, (str, bytes)) or not isinstance(raw, (tuple, list)):
        raise InvalidTrajectory(_JOINTS, "joint_names must be a list of names",
                                field="joint_names", value=raw)
    if not raw:
        raise InvalidTrajectory(_JOINTS, "the goal names no joints", field="joint_names", value=raw)
    for i, name in enumerate(raw):
        if not isinstance(name, str) or not name:
            raise InvalidTrajectory(_JOINTS, "a joint name must be a non-empty string",
                                    field=f"joint_names[{i}]", value=name)
    seen: dict[str, int] = {}
    for i, name in enumerate(raw):
        if name in seen:
            raise InvalidTrajectory(_JOINTS, f"joint named twice (also joint_names[{seen[name]}])",
                                    field=f"joint_names[{i}]", joint=name, value=name)
        seen[name] = i
    index = {spec.name: k for k, spec in enumerate(joints)}
    known = ", ".join(repr(n) for n in index) or "none"
    mapping = []
    for i, name in enumerate(raw):
        if name not in index:
            raise InvalidTrajectory(_JOINTS, f"not a joint of this controller (joints: {known})",
                                    field=f"joint_names[{i}]", joint=name, value=name)
        mapping.append(index[name])
    return [str(n) for n in raw], mapping


def _check_points(trajectory: JointTrajectory, n_joints: int) -> list[JointTrajectoryPoint]:
    raw = trajectory.points
    if not isinstance(raw, (tuple, list)):
        raise InvalidTrajectory(_GOAL, "points must be a list of JointTrajectoryPoint",
                                field="points", value=raw)
    if not raw:
        raise InvalidTrajectory(_GOAL, "the goal has no points", field="points", value=len(raw))
    for k, point in enumerate(raw):
        if not isinstance(point, JointTrajectoryPoint):
            raise InvalidTrajectory(_GOAL, "not a JointTrajectoryPoint", point=k,
                                    value=type(point).__name__)
        for name in _VECTOR_FIELDS:
            vec = getattr(point, name)
            if not isinstance(vec, (tuple, list)):
                raise InvalidTrajectory(_GOAL, "must be a list of numbers", point=k, field=name,
                                        value=vec)
            n = len(vec)
            if name == "positions" and n != n_joints:
                raise InvalidTrajectory(
                    _GOAL, f"has {n} values for {n_joints} joints (positions are required in every point)",
                    point=k, field=name, value=n)
            if name != "positions" and n not in (0, n_joints):
                raise InvalidTrajectory(_GOAL, f"has {n} values for {n_joints} joints (give none or one a joint)",
                                        point=k, field=name, value=n)
    return list(raw)


def _check_all_or_none(points: list[JointTrajectoryPoint]) -> dict[str, bool]:
    present = {}
    for name in _OPTIONAL_FIELDS:
        given = [len(getattr(p, name)) > 0 for p in points]
        if any(given) and not all(given):
            first = given.index(True)
            missing = given.index(False)
            raise InvalidTrajectory(
                _GOAL, f"given in points[{first}] but missing here: give {name} in all points or in none",
                point=missing, field=name, value=())
        present[name] = all(given)
    return present


def _check_stamp(trajectory: JointTrajectory) -> float:
    stamp = _as_float(trajectory.stamp_s)
    if stamp is None:
        raise InvalidTrajectory(_GOAL, "the header stamp must be a number of seconds",
                                field="header.stamp", value=trajectory.stamp_s)
    if not math.isfinite(stamp):
        raise InvalidTrajectory(_GOAL, "the header stamp must be finite", field="header.stamp",
                                value=trajectory.stamp_s)
    return stamp


def _check_times(points: list[JointTrajectoryPoint]) -> np.ndarray:
    times = np.empty(len(points), dtype=np.float64)
    for k, point in enumerate(points):
        raw = point.time_from_start_s
        t = _as_float(raw)
        if t is None:
            raise InvalidTrajectory(_GOAL, "must be a number of seconds", point=k,
                                    field="time_from_start", value=raw)
        if not math.isfinite(t):
            raise InvalidTrajectory(_GOAL, "must be finite", point=k, field="time_from_start", value=raw)
        if t < 0:
            raise InvalidTrajectory(_GOAL, "must not be negative", point=k, field="time_from_start",
                                    value=raw)
        if k > 0 and not t > times[k - 1]:
            raise InvalidTrajectory(
                _GOAL, f"times must increase strictly (points[{k - 1}] is at {float(times[k - 1])!r} s)",
                point=k, field="time_from_start", value=raw)
        times[k] = t
    return times


def _check_values(points: list[JointTrajectoryPoint], names: list[str],
                  present: dict[str, bool]) -> dict[str, np.ndarray | None]:
    out: dict[str, np.ndarray | None] = {}
    for name in _VECTOR_FIELDS:
        if name != "positions" and not present[name]:
            out[name] = None
            continue
        array = np.empty((len(points), len(names)), dtype=np.float64)
        for k, point in enumerate(points):
            for c, raw in enumerate(getattr(point, name)):
                x = _as_float(raw)
                if x is None:
                    raise InvalidTrajectory(_GOAL, f"{name} must hold numbers", point=k, field=name,
                                            joint=names[c], value=raw)
                array[k, c] = x
        out[name] = array
    # NaN/inf after the type check of every field, so a string anywhere wins over a NaN.
    for name in _VECTOR_FIELDS:
        array = out[name]
        if array is None:
            continue
        bad = np.argwhere(~np.isfinite(array))
        if bad.size:
            k, c = (int(i) for i in bad[0])
            raise InvalidTrajectory(_GOAL, f"{name} must be finite", point=k, field=name,
                                    joint=names[c], value=getattr(points[k], name)[c])
    return out


def _check_position_limits(positions: np.ndarray, names: list[str], specs: list[JointSpec]) -> None:
    for k in range(positions.shape[0]):
        for c, spec in enumerate(specs):
            q = float(positions[k, c])
            if spec.lower is not None and q < spec.lower:
                raise InvalidTrajectory(_GOAL, f"position is below the joint's lower limit {spec.lower!r}",
                                        point=k, field="positions", joint=names[c], value=q)
            if spec.upper is not None and q > spec.upper:
                raise InvalidTrajectory(_GOAL, f"position is above the joint's upper limit {spec.upper!r}",
                                        point=k, field="positions", joint=names[c], value=q)


def _speed_limit(spec: JointSpec) -> float:
    return spec.max_velocity * (1.0 + SPEED_RTOL)


def _check_velocity_limits(velocities: np.ndarray, names: list[str], specs: list[JointSpec]) -> None:
    for k in range(velocities.shape[0]):
        for c, spec in enumerate(specs):
            v = float(velocities[k, c])
            if abs(v) > _speed_limit(spec):
                raise InvalidTrajectory(
                    _GOAL, f"velocity magnitude is above the joint's max_velocity {spec.max_velocity!r}",
                    point=k, field="velocities", joint=names[c], value=v)


def _check_segment_speeds(times: np.ndarray, positions: np.ndarray, start: np.ndarray,
                          names: list[str], specs: list[JointSpec]) -> None:
    for k in range(len(times)):
        if k == 0:
            if times[0] <= 0.0:
                continue  # the start check below covers a first point at t = 0
            q0, t0, origin = start, 0.0, "the current position"
        else:
            q0, t0, origin = positions[k - 1], float(times[k - 1]), f"points[{k - 1}]"
        dt = float(times[k]) - t0
        for c, spec in enumerate(specs):
            a, b = float(q0[c]), float(positions[k, c])
            dq = abs(b - a)
            # Allowed travel, with slack for the rounding of the positions themselves
            # (a step of max_velocity * Δt added to a large position is not exact).
            allowed = spec.max_velocity * dt * (1.0 + SPEED_RTOL) + _POSITION_ROUNDING * max(abs(a), abs(b))
            if dq > allowed:
                speed = dq / dt
                raise InvalidTrajectory(
                    _GOAL,
                    f"infeasible segment: moving {dq!r} from {origin} (t={t0!r} s) to here "
                    f"(t={float(times[k])!r} s) needs an average speed {speed!r} above the joint's "
                    f"max_velocity {spec.max_velocity!r}",
                    point=k, field="positions", joint=names[c], value=speed)


def _check_start(times: np.ndarray, positions: np.ndarray, start: np.ndarray, names: list[str],
                 start_tolerance: float) -> None:
    if times[0] != 0.0:
        return
    for c, name in enumerate(names):
        q = float(positions[0, c])
        jump = abs(q - float(start[c]))
        if jump > start_tolerance:
            raise InvalidTrajectory(
                _GOAL,
                f"the first point is at time 0 but {jump!r} away from the current position "
                f"{float(start[c])!r} (start_tolerance {start_tolerance!r}): it would jump",
                point=0, field="positions", joint=name, value=q)

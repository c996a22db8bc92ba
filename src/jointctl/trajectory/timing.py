"""Timing a path: turning positions without times (array (N, J)) into a trajectory.

:func:`time_path` is the one way jointctl times a path from the current pose
(the in-process executor's ``plan_path`` and the ROS client both call it); the
defaults of its limits are here, and the executor's parameters of the same
names default to them. Two rules:

* :func:`chapter_timing`: the chapter's "stuff trajectory" rule (a fraction of
  the velocity limit per segment, at least a minimum segment time). Cheap and
  predictable; the result is meant for linear or spline interpolation.
* :func:`ruckig_timing`: jerk-limited, time-optimal per segment (synchronised
  across joints) with the community ruckig library, densely sampled so a
  quintic :class:`~jointctl.trajectory.interpolation.Interpolant` built from
  the samples reproduces ruckig's profile.

Units: positions rad (or m), times s, limits per s, s², s³.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from jointctl.trajectory.interpolation import Interpolant, build_interpolant
from jointctl.trajectory.messages import JointTrajectory

FloatArray = NDArray[np.float64]

#: The path-timing rules :func:`time_path` knows.
PATH_TIMINGS = ("chapter", "ruckig")
#: Fraction of each joint's velocity limit a timed path may use.
PATH_VELOCITY_FRACTION = 0.5
#: Acceleration (per s²) and jerk (per s³) limits of ruckig timing, per joint.
PATH_MAX_ACCELERATION = 2.0
PATH_MAX_JERK = 20.0
#: The current pose is a timed path's first point, this long after sending (s), as the chapter's
#: clients prepend it.
PATH_START_S = 0.1

#: Shortest segment ruckig_timing produces (s); a repeated waypoint becomes a hold this long.
MIN_RUCKIG_SEGMENT_S = 1e-6
#: Fraction of the velocity limit used as the largest pass-through velocity when blending.
BLEND_VELOCITY_FRACTION = 0.8
#: Jerk switch times closer than this to a waypoint or another kept switch are not sampled (s).
SWITCH_MERGE_S = 1e-5


def _as_path(path: Any) -> FloatArray:
    try:
        array = np.array(path, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"path is not a numeric array: {exc}") from None
    if array.ndim != 2 or array.shape[0] < 1 or array.shape[1] < 1:
        raise ValueError(f"path must have shape (points >= 1, joints >= 1), got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError("path contains NaN or infinite values")
    return array


def _as_limits(value: Any, n_joints: int, name: str, *, allow_inf: bool) -> FloatArray:
    """Per-joint limits (J,) from a scalar or (J,); ValueError naming the first bad joint."""
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} is not numeric: {exc}") from None
    if array.ndim == 0:
        array = np.full(n_joints, float(array))
    if array.shape != (n_joints,):
        raise ValueError(f"{name} must be a scalar or have shape ({n_joints},), got {array.shape}")
    for j, limit in enumerate(array):
        if np.isnan(limit) or limit <= 0.0 or (np.isinf(limit) and not allow_inf):
            need = "positive" if allow_inf else "positive and finite"
            raise ValueError(f"{name}[{j}] (joint {j}) is {limit}; it must be {need}")
    return array


def _positive(value: Any, name: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} is not a number: {exc}") from None
    if not np.isfinite(number) or number <= 0.0:
        raise ValueError(f"{name} must be positive and finite, got {value!r}")
    return number


def time_path(joint_names: Sequence[str], current: Any, path: Any, max_velocity: Any, *,
              timing: str = "ruckig", path_joints: Sequence[str] | None = None,
              velocity_fraction: float = PATH_VELOCITY_FRACTION, max_acceleration: Any = PATH_MAX_ACCELERATION,
              max_jerk: Any = PATH_MAX_JERK, start_s: float = PATH_START_S) -> JointTrajectory:
    """A trajectory from the current pose through a path of poses without times.

    Args:
        joint_names: every joint of the robot part (J).
        current: their positions now (J,), the trajectory's first point, at ``start_s``.
        path: rows of positions of ``path_joints`` (default: every joint, in order); the
            trajectory names those joints only (the others hold).
        max_velocity: the joints' velocity limits (J,) or a scalar, per s; a path uses
            ``velocity_fraction`` of them.
        timing: ``"ruckig"``: jerk-limited and time-optimal per segment (:func:`ruckig_timing`)
            within those velocities, ``max_acceleration`` and ``max_jerk`` (scalars or (J,));
            ``"chapter"``: the chapter's rule (:func:`chapter_timing`: the slowest joint at those
            velocities, at least 20 ms a segment), positions only.
        start_s: time of the first point (the current pose) after sending, s.

    Raises:
        ValueError: an unknown rule or joint, a path that is not rows of ``path_joints``,
            NaN, or limits that are not positive.
    """
    all_names = tuple(joint_names)
    names = tuple(path_joints or all_names)
    try:
        columns = [all_names.index(n) for n in names]
    except ValueError:
        raise ValueError(f"path joints {list(names)} are not all among {list(all_names)}") from None

    def per_joint(value: Any, what: str) -> FloatArray:
        array = np.asarray(value, dtype=float)
        if array.ndim == 0:
            return np.full(len(columns), float(array))
        if array.shape != (len(all_names),):
            raise ValueError(f"{what} must be a scalar or have shape ({len(all_names)},), got {array.shape}")
        return array[columns]

    rows = np.asarray(path, dtype=float).reshape(-1, len(names))
    full = np.vstack((per_joint(current, "current"), rows))
    vmax = per_joint(max_velocity, "max_velocity") * velocity_fraction
    if timing == "chapter":
        return JointTrajectory.from_arrays(names, chapter_timing(full, vmax, velocity_fraction=1.0) + start_s, full)
    if timing != "ruckig":
        raise ValueError(f"timing must be one of {', '.join(PATH_TIMINGS)}, got {timing!r}")
    times, positions, velocities, accelerations = ruckig_timing(
        full, vmax, per_joint(max_acceleration, "max_acceleration"), per_joint(max_jerk, "max_jerk"))
    return JointTrajectory.from_arrays(names, times + start_s, positions, velocities, accelerations)


def chapter_timing(path: Any, max_velocity: Any, *, velocity_fraction: float = 0.5,
                   min_segment_s: float = 0.02) -> FloatArray:
    """Times (N,) s for a path (N, J) by the chapter's "stuff trajectory" rule.

    Point 0 is at t = 0; each next point follows after
    ``max_i |Δq_i| / (velocity_fraction * max_velocity_i)``, but at least
    ``min_segment_s``. ``max_velocity`` is per joint (J,) or a scalar, per s;
    ``inf`` means unlimited. With the chapter's client's 7-DOF limits
    ``[0.17, 0.17, 0.3, 0.3, 0.4, 0.4, 0.4]`` (the arm's URDF says 0.2, 0.2, 0.3, 0.3, 0.4, 0.5,
    0.4; joint 3 sets the pace either way) the move from zeros to ``[0, 1, 0, -2, 0, 1, 0]``
    takes 2 / (0.5 * 0.3) = 13.33 s.

    Raises:
        ValueError: bad shapes, no points, NaN, non-positive limits/fraction/minimum.
    """
    q = _as_path(path)
    vmax = _as_limits(max_velocity, q.shape[1], "max_velocity", allow_inf=True)
    fraction = _positive(velocity_fraction, "velocity_fraction")
    min_dt = _positive(min_segment_s, "min_segment_s")
    steps = np.abs(np.diff(q, axis=0)) / (fraction * vmax)        # (N-1, J)
    dt = np.maximum(steps.max(axis=1, initial=0.0), min_dt)
    return np.concatenate(([0.0], np.cumsum(dt)))


def ruckig_timing(path: Any, max_velocity: Any, max_acceleration: Any, max_jerk: Any, *,
                  sample_period_s: float = 0.01,
                  blend: bool = True) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Jerk-limited, time-optimal (per segment) trajectory through every path point.

    Each segment between consecutive waypoints is one offline ruckig
    trajectory (time-synchronised across joints, zero acceleration at the
    waypoints). With ``blend=False`` every waypoint is passed at rest. With
    ``blend=True`` interior waypoints get a pass-through velocity per joint:
    0 where that joint reverses direction or stands still on either side,
    otherwise the slope of a C2 cubic spline through the waypoints timed by
    the rest-to-rest durations (0 if the spline's slope has the wrong sign),
    clamped to ``BLEND_VELOCITY_FRACTION * max_velocity``. If ruckig fails on a
    segment, its end waypoint (and if needed its start waypoint) is passed at
    rest instead. A blended segment that would be slower than rest to rest (a
    short segment between long ones: the spline's velocity is too high for
    it) gets the offending joints' velocities zeroed at both its ends, so
    ``blend=True`` is never slower than ``blend=False``. Segments last at
    least ``MIN_RUCKIG_SEGMENT_S`` (a repeated waypoint becomes a hold that
    long).

    Args:
        path: (N, J) waypoints, N >= 1.
        max_velocity, max_acceleration, max_jerk: per joint (J,) or scalar,
            positive and finite (per s, s², s³).
        sample_period_s: spacing of the dense samples, s.
        blend: pass interior waypoints with non-zero velocity where sensible.

    Returns:
        ``(times_s, positions, velocities, accelerations)``: samples (T,),
        (T, J), strictly increasing from 0: every waypoint time exactly
        (positions there are the waypoints bit for bit, accelerations 0), the
        jerk switch times of ruckig's profiles (so the quintic through the
        samples reproduces ruckig's piecewise-cubic profile, except that a
        switch within ``SWITCH_MERGE_S`` of another is not sampled) and a grid
        every ``sample_period_s`` from 0 (grid points within a tenth of a
        period of those times are left out, so gaps are below
        1.2 ``sample_period_s``). The last sample is the last waypoint.

    Raises:
        ValueError: bad shapes, no points, NaN, a limit that is not positive
            and finite (the message names the joint index), or ruckig failing
            even rest to rest.
        ImportError: ruckig is not installed.
    """
    q = _as_path(path)
    n_points, n_joints = q.shape
    vmax = _as_limits(max_velocity, n_joints, "max_velocity", allow_inf=False)
    amax = _as_limits(max_acceleration, n_joints, "max_acceleration", allow_inf=False)
    jmax = _as_limits(max_jerk, n_joints, "max_jerk", allow_inf=False)
    period = _positive(sample_period_s, "sample_period_s")
    if n_points == 1:
        zeros = np.zeros_like(q)
        return np.zeros(1), q.copy(), zeros, zeros.copy()

    planner = _SegmentPlanner(n_joints, vmax, amax, jmax)
    v_wp = np.zeros_like(q)
    segments = _plan_segments(planner, q, v_wp)                    # rest to rest
    if blend and n_points >= 3:
        rest_durations = np.array([_duration(traj) for traj in segments])
        v_wp = _blend_velocities(q, rest_durations, vmax)
        if np.any(v_wp):
            segments = _plan_segments(planner, q, v_wp, rest_durations)
    durations = np.array([_duration(traj) for traj in segments])
    waypoint_times = np.concatenate(([0.0], np.cumsum(durations)))
    times = _sample_times(waypoint_times, segments, period)

    positions = np.empty((times.size, n_joints))
    velocities = np.empty_like(positions)
    accelerations = np.empty_like(positions)
    seg = np.clip(np.searchsorted(waypoint_times, times, side="right") - 1, 0, n_points - 2)
    bounds = np.searchsorted(seg, np.arange(n_points))              # seg is sorted
    for k, traj in enumerate(segments):
        rows = slice(bounds[k], bounds[k + 1])
        local = times[rows] - waypoint_times[k]
        states = np.array([traj.at_time(x) for x in local.tolist()])       # (n, 3, J)
        corr = _end_correction(traj, durations[k], q[k], q[k + 1], v_wp[k], v_wp[k + 1]).sample(local)
        positions[rows] = states[:, 0] + corr[0]
        velocities[rows] = states[:, 1] + corr[1]
        accelerations[rows] = states[:, 2] + corr[2]
    wp_index = np.searchsorted(times, waypoint_times)              # waypoints are in `times` exactly
    positions[wp_index] = q
    velocities[wp_index] = v_wp
    accelerations[wp_index] = 0.0
    return times, positions, velocities, accelerations


def _end_correction(traj: Any, duration: float, q0: FloatArray, q1: FloatArray,
                    v0: FloatArray, v1: FloatArray) -> Interpolant:
    """Quintic over the segment that removes ruckig's small boundary errors.

    Ruckig meets target positions only to about 1e-8; adding this quintic
    (zero where ruckig is exact) makes the samples continuous at the exact
    waypoints, so a quintic through the samples has no spurious
    acceleration spikes next to a waypoint. It stays a quintic within each
    ruckig phase, so the samples still determine it exactly.
    """
    start = [np.asarray(x, dtype=float) for x in traj.at_time(0.0)]
    end = [np.asarray(x, dtype=float) for x in traj.at_time(duration)]
    return build_interpolant(
        [0.0, duration],
        [q0 - start[0], q1 - end[0]],
        [v0 - start[1], v1 - end[1]],
        [-start[2], -end[2]],
    )


def _duration(traj: Any) -> float:
    return max(float(traj.duration), MIN_RUCKIG_SEGMENT_S)


class _SegmentPlanner:
    """One offline ruckig instance; plans a segment between two states (zero acceleration)."""

    def __init__(self, n_joints: int, vmax: FloatArray, amax: FloatArray, jmax: FloatArray) -> None:
        from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

        self._n = n_joints
        self._ok = (Result.Working, Result.Finished)
        self._error = RuckigError
        self._otg = Ruckig(n_joints)
        self._inp = InputParameter(n_joints)
        self._inp.max_velocity = vmax.tolist()
        self._inp.max_acceleration = amax.tolist()
        self._inp.max_jerk = jmax.tolist()
        self._inp.current_acceleration = [0.0] * n_joints
        self._inp.target_acceleration = [0.0] * n_joints
        self._trajectory_type = Trajectory

    def plan(self, q0: FloatArray, q1: FloatArray, v0: FloatArray, v1: FloatArray) -> Any:
        """A ruckig ``Trajectory`` from (q0, v0) to (q1, v1), or None if ruckig fails."""
        self._inp.current_position = q0.tolist()
        self._inp.current_velocity = v0.tolist()
        self._inp.target_position = q1.tolist()
        self._inp.target_velocity = v1.tolist()
        traj = self._trajectory_type(self._n)
        try:
            result = self._otg.calculate(self._inp, traj)
        except self._error:
            return None
        if result not in self._ok or not np.isfinite(traj.duration):
            return None
        return traj


def _blend_velocities(q: FloatArray, rest_durations: FloatArray, vmax: FloatArray) -> FloatArray:
    """Pass-through velocities (N, J) at the waypoints; zero at both ends."""
    knots = np.concatenate(([0.0], np.cumsum(rest_durations)))
    slope = CubicSpline(knots, q, axis=0, bc_type="clamped")(knots, 1)
    before = np.diff(q, axis=0)[:-1]                               # (N-2, J) into waypoint k
    after = np.diff(q, axis=0)[1:]                                 # out of waypoint k
    interior = slope[1:-1]
    keep = (np.sign(before) == np.sign(after)) & (before != 0.0) & (np.sign(interior) == np.sign(before))
    cap = BLEND_VELOCITY_FRACTION * vmax
    v = np.zeros_like(q)
    v[1:-1] = np.where(keep, np.clip(interior, -cap, cap), 0.0)
    return v


def _plan_segments(planner: _SegmentPlanner, q: FloatArray, v_wp: FloatArray,
                   rest_durations: FloatArray | None = None) -> list[Any]:
    """Plan every segment, zeroing waypoint velocities (``v_wp``, in place) where needed.

    If ruckig fails on a segment, its end waypoint is passed at rest (then its
    start waypoint). With ``rest_durations`` a segment slower than rest to rest
    has the velocities of the offending joints (those whose own minimum
    duration is too long, else all) zeroed at both ends, so no segment (and
    hence the whole trajectory) is slower than rest to rest. Each change zeroes
    at least one non-zero velocity, so this terminates.
    """
    n_segments = q.shape[0] - 1
    segments: list[Any] = [None] * n_segments
    pending = set(range(n_segments))

    def zero(waypoint: int, joints: Any) -> None:
        if np.any(v_wp[waypoint, joints]):
            v_wp[waypoint, joints] = 0.0
            pending.update(s for s in (waypoint - 1, waypoint) if 0 <= s < n_segments)

    while pending:
        k = min(pending)
        pending.discard(k)
        traj = planner.plan(q[k], q[k + 1], v_wp[k], v_wp[k + 1])
        if traj is None:
            if not (np.any(v_wp[k]) or np.any(v_wp[k + 1])):
                raise ValueError(f"ruckig could not time segment {k} even rest to rest; check the limits")
            zero(k + 1 if np.any(v_wp[k + 1]) else k, slice(None))
            pending.add(k)
            continue
        if rest_durations is not None and _duration(traj) > rest_durations[k]:
            joints = np.asarray(traj.independent_min_durations) > rest_durations[k]
            if not (np.any(v_wp[k, joints]) or np.any(v_wp[k + 1, joints])):
                joints = np.ones(q.shape[1], dtype=bool)
            zero(k, joints)
            zero(k + 1, joints)
            pending.add(k)
            continue
        segments[k] = traj
    return segments


def _switch_times(traj: Any) -> list[float]:
    """Local times (s) where any joint's jerk changes in a ruckig trajectory (best effort)."""
    times: list[float] = []
    try:
        for profile in traj.profiles[0]:
            offset = 0.0
            for pre in (profile.brake, profile.accel):
                times.extend((offset + np.cumsum(pre.t)).tolist())
                offset += float(pre.duration)
            times.extend((offset + np.cumsum(profile.t)).tolist())
    except (AttributeError, TypeError, IndexError):
        return []
    return times


def _merge(times: FloatArray, keep_first: FloatArray, eps: float) -> FloatArray:
    """``times`` without entries closer than ``eps`` to ``keep_first`` or to the previous kept entry."""
    times = np.sort(times)
    if times.size:
        times = times[np.concatenate(([True], np.diff(times) >= eps))]
        right = np.minimum(np.searchsorted(keep_first, times), keep_first.size - 1)
        left = np.maximum(right - 1, 0)
        gap = np.minimum(np.abs(keep_first[right] - times), np.abs(times - keep_first[left]))
        times = times[gap >= eps]
    return times


def _sample_times(waypoint_times: FloatArray, segments: list[Any], period: float) -> FloatArray:
    """Waypoint times, jerk switch times and a grid every ``period``, without very short gaps.

    Knots closer than a few microseconds make a quintic through rounded
    positions inaccurate (acceleration error ~ 1e-16 / gap²), so switch times
    closer than ``SWITCH_MERGE_S`` to a waypoint or another switch are dropped
    (acceleration error ~ jerk change × gap, rare) and grid points within
    ``period / 10`` of those times are dropped (no error; gaps stay below 1.2 ``period``).
    """
    total = waypoint_times[-1]
    switches = [start + np.asarray(_switch_times(traj), dtype=float)
                for start, traj in zip(waypoint_times[:-1], segments)]
    switch = np.concatenate(switches) if switches else np.zeros(0)
    switch = switch[np.isfinite(switch) & (switch > 0.0) & (switch < total)]
    essential = np.sort(np.concatenate((waypoint_times, _merge(switch, waypoint_times, SWITCH_MERGE_S))))
    grid = _merge(np.arange(0.0, total, period), essential, 0.1 * period)
    return np.sort(np.concatenate((essential, grid)))

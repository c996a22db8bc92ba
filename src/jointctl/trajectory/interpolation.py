"""Piecewise-polynomial joint trajectories, vectorised over joints and sample times.

Times are in seconds; positions in rad (or m), velocities per second,
accelerations per second squared. An :class:`Interpolant` stores one
polynomial per segment and joint as coefficients in powers of ``t - t_k``
(array ``(segments, joints, 6)``), so sampling any number of times is a
Horner evaluation over the coefficients its kind uses, vectorised over times
and joints, with no Python loop over either. Increasing times (a control
loop's) need no per-sample search: each segment's coefficients are repeated
over its run of samples. That samples position, velocity and acceleration
about twice as fast as scipy's ``CubicHermiteSpline`` evaluating the same
three (``make bench``). A control loop samples a block of cycles at once with
:func:`sample_block` rather than one call per cycle.

Validation of user trajectories (with proper error codes) happens upstream;
the ``ValueError`` raised here is a programming guard.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

Kind = Literal["linear", "cubic", "quintic"]
FloatArray = NDArray[np.float64]

_N_COEFFS = 6
_KINDS = ("auto", "linear", "cubic", "quintic", "spline")


def _as_float_array(value: Any, name: str) -> FloatArray:
    """``np.asarray(value, float)`` that only ever raises ``ValueError``."""
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} is not a numeric array: {exc}") from None
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return array


class Interpolant:
    """A piecewise-polynomial joint trajectory through knots.

    Attributes:
        kind: ``'linear'``, ``'cubic'`` or ``'quintic'``.
        times_s: knot times (K,), strictly increasing, s.
        positions: knot positions (K, J).
        velocities: knot velocities (K, J) per s. Always equal to what
            :meth:`sample` returns at the knot time: the outgoing segment's
            start value, and the last segment's end value at the last knot.
            For ``'linear'`` that is the segment slope (outgoing; the last
            knot reports the last segment's slope).
        accelerations: knot accelerations (K, J) per s², same convention
            (zeros for ``'linear'``; for ``'cubic'`` the one-sided value, which
            is continuous only for a spline fill).
        duration_s: ``times_s[-1]`` (s). A trajectory starting at t = 0 lasts this long.
        n_joints: J.
        coefficients: (K-1, J, 6) polynomial coefficients in powers of ``t - times_s[k]``.

    A single knot (K = 1) is a hold: zero velocity and acceleration everywhere.
    Instances are immutable (arrays are read-only); build them with
    :func:`build_interpolant`.
    """

    __slots__ = ("kind", "times_s", "positions", "velocities", "accelerations", "coefficients", "_table")

    def __init__(self, kind: Kind, times_s: FloatArray, positions: FloatArray,
                 velocities: FloatArray, accelerations: FloatArray,
                 coefficients: FloatArray) -> None:
        self.kind: Kind = kind
        self.times_s = times_s
        self.positions = positions
        self.velocities = velocities
        self.accelerations = accelerations
        self.coefficients = coefficients
        # The coefficients the kind uses, as rows (coefficient i of joint j at row i·J + j) and one
        # column per segment: a run of samples in one segment repeats a column (see _evaluate).
        order = _ORDER[kind]
        self._table = np.ascontiguousarray(
            coefficients[..., :order].transpose(2, 1, 0).reshape(order * positions.shape[1], -1))
        for array in (times_s, positions, velocities, accelerations, coefficients, self._table):
            array.flags.writeable = False

    @property
    def duration_s(self) -> float:
        """Time of the last knot, s."""
        return float(self.times_s[-1])

    @property
    def n_joints(self) -> int:
        """Number of joints J."""
        return int(self.positions.shape[1])

    def __repr__(self) -> str:
        return (f"Interpolant(kind={self.kind!r}, knots={len(self.times_s)}, "
                f"joints={self.n_joints}, t=[{self.times_s[0]:g}, {self.times_s[-1]:g}] s)")

    def sample(self, t: float | Any) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Positions, velocities and accelerations at time(s) ``t`` (s).

        A scalar ``t`` gives three arrays (J,); an array (T,) gives (T, J) (views
        of one (3, J, T) array). Before ``times_s[0]`` the result is the first
        knot's position with zero velocity and acceleration; after
        ``times_s[-1]`` the last knot's position with zero velocity and
        acceleration. At a knot time the position is the knot's exactly, and
        velocity and acceleration are the knot's ``velocities``/``accelerations``
        rows. Increasing times (a control loop's) are the fast case: each
        segment's coefficients are repeated over its run of samples instead of
        looked up sample by sample; any order gives the same values.
        """
        try:
            t_arr = np.asarray(t, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"t is not numeric: {exc}") from None
        if t_arr.ndim > 1:
            raise ValueError(f"t must be a scalar or a 1-D array, got shape {t_arr.shape}")
        if np.isnan(t_arr).any():
            raise ValueError("t contains NaN")
        if t_arr.ndim == 0:
            out = self._evaluate(t_arr.reshape(1))
            return out[0, :, 0].copy(), out[1, :, 0].copy(), out[2, :, 0].copy()
        out = self._evaluate(t_arr)
        return out[0].T, out[1].T, out[2].T

    def _evaluate(self, t: FloatArray, *, increasing: bool | None = None) -> FloatArray:
        """Positions, velocities, accelerations (3, J, T) at the times ``t`` (T,), none NaN;
        ``increasing``: whether ``t`` is known to be in order (None: check)."""
        times = self.times_s
        n_joints, n_t = self.positions.shape[1], t.size
        out = np.empty((3, n_joints, n_t))
        first, last = times[0], times[-1]
        if increasing is None:
            increasing = n_t > 1 and bool((t[1:] >= t[:-1]).all())
        if increasing and n_t > 1:
            lo = int(t.searchsorted(first))                 # t[:lo] before the first knot
            hi = int(t.searchsorted(last))                  # t[hi:] at or after the last knot
            if lo < hi:
                # Samples lo..hi-1 fall into segments s0..s1 in order, a run of samples each.
                s0 = int(times.searchsorted(t[lo], side="right")) - 1
                s1 = int(times.searchsorted(t[hi - 1], side="right")) - 1
                bounds = np.empty(s1 - s0 + 2, dtype=np.intp)  # segment s0 + i: bounds[i]..bounds[i+1]-1
                bounds[0], bounds[-1] = lo, hi
                bounds[1:-1] = t.searchsorted(times[s0 + 1:s1 + 1])
                _fill_runs(self._table, times, t, out, s0, bounds)
            if hi < n_t:
                end = int(t.searchsorted(last, side="right"))
                self._outside(out, slice(0, lo), slice(hi, n_t), slice(hi, end))
            elif lo:
                self._outside(out, slice(0, lo), slice(0, 0), slice(0, 0))
        else:
            before, after = t < first, t >= last
            if not (before | after).all():
                _fill_lookup(self._table, times, t, out)
            self._outside(out, before, after, t == last)
        return out

    def _outside(self, out: FloatArray, before: Any, after: Any, at_end: Any) -> None:
        """Holds before the first knot and after the last; the last knot's values at its time."""
        out[0][:, before] = self.positions[0][:, None]
        out[0][:, after] = self.positions[-1][:, None]
        out[1:, :, before] = 0.0
        out[1:, :, after] = 0.0
        out[1][:, at_end] = self.velocities[-1][:, None]
        out[2][:, at_end] = self.accelerations[-1][:, None]


#: Coefficients each kind uses (the others are zero).
_ORDER = {"linear": 2, "cubic": 4, "quintic": 6}
#: Samples evaluated at a time (the work arrays stay in the cache).
_CHUNK = 4096


def _fill_runs(table: FloatArray, times: FloatArray, t: FloatArray, out: FloatArray, s0: int,
               bounds: FloatArray) -> None:
    """Evaluate increasing times: segment ``s0 + i`` holds samples ``bounds[i]..bounds[i+1]-1``.
    Each segment's column of coefficients is repeated over its run (no per-sample look-up)."""
    lo, hi = int(bounds[0]), int(bounds[-1])
    work = _Work(table.shape[0], out.shape[1], min(_CHUNK, hi - lo))
    for a in range(lo, hi, _CHUNK):
        b = min(a + _CHUNK, hi)
        if a == lo and b == hi:
            i0, counts = 0, np.diff(bounds)
        else:
            i0 = int(bounds.searchsorted(a, side="right")) - 1
            i1 = int(bounds.searchsorted(b - 1, side="right")) - 1
            counts = np.minimum(bounds[i0 + 1:i1 + 2], b) - np.maximum(bounds[i0:i1 + 1], a)
        columns = slice(s0 + i0, s0 + i0 + counts.size)
        tau = work.tau[:b - a]
        tau[...] = times[columns].repeat(counts)
        np.subtract(t[a:b], tau, out=tau)
        work.evaluate(table[:, columns].repeat(counts, axis=1), tau, out[:, :, a:b])


def _fill_lookup(table: FloatArray, times: FloatArray, t: FloatArray, out: FloatArray) -> None:
    """Evaluate times in any order: each sample's segment is searched and its coefficients gathered.
    Samples outside ``[times[0], times[-1])`` get the first or last segment's polynomial (the
    caller overwrites them)."""
    n_t = t.size
    segments = times.searchsorted(t, side="right") - 1
    np.clip(segments, 0, times.size - 2, out=segments)
    work = _Work(table.shape[0], out.shape[1], min(_CHUNK, n_t))
    gathered = np.empty((table.shape[0], work.tau.size))
    for a in range(0, n_t, _CHUNK):
        b = min(a + _CHUNK, n_t)
        seg, tau, g = segments[a:b], work.tau[:b - a], gathered[:, :b - a]
        table.take(seg, axis=1, out=g)
        times.take(seg, out=tau)
        np.subtract(t[a:b], tau, out=tau)
        work.evaluate(g, tau, out[:, :, a:b])


class _Work:
    """Work arrays for evaluating chunks of up to ``size`` samples of ``n_joints`` joints."""

    def __init__(self, rows: int, n_joints: int, size: int) -> None:
        self.order = rows // n_joints
        self.n_joints = n_joints
        rows_d1 = max(self.order - 2, 0) * n_joints
        work = np.empty((1 + rows_d1 + max(self.order - 3, 0) * n_joints, size))
        self.tau = work[0]
        self.d1 = work[1:1 + rows_d1]   # velocity coefficients 2c2, 3c3, ...
        self.d2 = work[1 + rows_d1:]    # acceleration coefficients beyond 2c2

    def evaluate(self, g: FloatArray, tau: FloatArray, out: FloatArray) -> None:
        """``out`` (3, J, n): positions, velocities, accelerations from the coefficients ``g``
        (order·J, n: coefficient i of joint j at row i·J + j) at ``tau`` (n,) into their segments.

        Horner's scheme; the derivatives' coefficients are the position coefficients times their
        powers (``c[i+1]·(i+1)``, then that times ``i+1`` again)."""
        n, m, order = self.n_joints, tau.size, self.order
        c = [g[i * n:(i + 1) * n] for i in range(order)]
        p, v, a = out
        _horner(c, tau, p)
        if order == 2:  # linear: the slope, no acceleration
            v[...] = c[1]
            a[...] = 0.0
            return
        v_coeffs = [c[1]] + [self.d1[(i - 1) * n:i * n, :m] for i in range(1, order - 1)]
        for i in range(1, order - 1):
            np.multiply(c[i + 1], float(i + 1), out=v_coeffs[i])
        a_coeffs = [v_coeffs[1]] + [self.d2[(i - 1) * n:i * n, :m] for i in range(1, order - 2)]
        for i in range(1, order - 2):
            np.multiply(v_coeffs[i + 1], float(i + 1), out=a_coeffs[i])
        _horner(v_coeffs, tau, v)
        _horner(a_coeffs, tau, a)


def _horner(coefficients: list[FloatArray], tau: FloatArray, out: FloatArray) -> None:
    """``out = sum_i coefficients[i] * tau**i`` by Horner's scheme (each coefficient (J, n), tau (n,))."""
    np.multiply(coefficients[-1], tau, out=out)
    for c in coefficients[-2:0:-1]:
        out += c
        out *= tau
    out += coefficients[0]


def _segment_coefficients(kind: Kind, h: FloatArray, p0: FloatArray, p1: FloatArray,
                          v0: FloatArray, v1: FloatArray, a0: FloatArray, a1: FloatArray) -> FloatArray:
    """Coefficients (S, J, 6) for segments of length h (S, 1) between knot values (S, J)."""
    c = np.zeros(p0.shape + (_N_COEFFS,))
    dp = p1 - p0
    c[..., 0] = p0
    if kind == "linear":
        c[..., 1] = dp / h
    elif kind == "cubic":
        c[..., 1] = v0
        c[..., 2] = (3.0 * dp / h - 2.0 * v0 - v1) / h
        c[..., 3] = (-2.0 * dp / h + v0 + v1) / h**2
    else:
        c[..., 1] = v0
        c[..., 2] = 0.5 * a0
        c[..., 3] = (20.0 * dp - (8.0 * v1 + 12.0 * v0) * h - (3.0 * a0 - a1) * h**2) / (2.0 * h**3)
        c[..., 4] = (-30.0 * dp + (14.0 * v1 + 16.0 * v0) * h + (3.0 * a0 - 2.0 * a1) * h**2) / (2.0 * h**4)
        c[..., 5] = (12.0 * dp - 6.0 * (v1 + v0) * h + (a1 - a0) * h**2) / (2.0 * h**5)
    return c


def _boundary_velocity(value: Any, n_joints: int, name: str) -> FloatArray:
    if value is None:
        return np.zeros(n_joints)
    array = _as_float_array(value, name)
    if array.ndim == 0:
        return np.full(n_joints, float(array))
    if array.shape != (n_joints,):
        raise ValueError(f"{name} must be a scalar or have shape ({n_joints},), got {array.shape}")
    return array


def build_interpolant(times_s: Any, positions: Any, velocities: Any = None, accelerations: Any = None,
                      *, kind: str = "auto", start_velocity: Any = None,
                      end_velocity: Any = None) -> Interpolant:
    """Build an :class:`Interpolant` through knots.

    Args:
        times_s: knot times (K,), s, strictly increasing, K >= 1.
        positions: (K, J) knot positions.
        velocities: optional (K, J) knot velocities, per s.
        accelerations: optional (K, J) knot accelerations, per s² (needs velocities).
        kind: ``"auto"`` picks linear (positions only), cubic Hermite (with
            velocities) or quintic (with velocities and accelerations).
            ``"linear"``, ``"cubic"``, ``"quintic"`` force the order (ignoring
            fields the order does not use; cubic/quintic raise if theirs are
            missing). ``"spline"`` ignores given velocities/accelerations and
            fills the velocities from a C2 cubic spline through the positions
            (``scipy.interpolate.CubicSpline``, clamped to ``start_velocity`` /
            ``end_velocity``), giving a cubic Hermite equal to that spline.
        start_velocity, end_velocity: scalar or (J,), per s, default 0; only
            used by ``kind="spline"``.

    A single knot is a hold (velocities and accelerations zero).

    Raises:
        ValueError: unknown kind, missing fields, shape mismatch, non-finite
            values, or times that are not strictly increasing.
    """
    if kind not in _KINDS:
        raise ValueError(f"kind must be one of {_KINDS}, got {kind!r}")
    t = _as_float_array(times_s, "times_s")
    p = _as_float_array(positions, "positions")
    if t.ndim != 1 or t.size < 1:
        raise ValueError(f"times_s must be a non-empty 1-D array, got shape {t.shape}")
    if p.ndim != 2 or p.shape[0] != t.size or p.shape[1] < 1:
        raise ValueError(f"positions must have shape ({t.size}, joints >= 1), got {p.shape}")
    if np.any(np.diff(t) <= 0.0):
        raise ValueError("times_s must be strictly increasing")
    n_knots, n_joints = p.shape
    v = None if velocities is None else _as_float_array(velocities, "velocities")
    a = None if accelerations is None else _as_float_array(accelerations, "accelerations")
    for name, array in (("velocities", v), ("accelerations", a)):
        if array is not None and array.shape != p.shape:
            raise ValueError(f"{name} must have shape {p.shape}, got {array.shape}")

    resolved: Kind
    if kind == "auto":
        if a is not None and v is None:
            raise ValueError("accelerations given without velocities")
        resolved = "linear" if v is None else ("cubic" if a is None else "quintic")
    elif kind == "spline":
        resolved = "cubic"
        start = _boundary_velocity(start_velocity, n_joints, "start_velocity")
        end = _boundary_velocity(end_velocity, n_joints, "end_velocity")
        a = None
        if n_knots >= 2:
            spline = CubicSpline(t, p, axis=0, bc_type=((1, start), (1, end)))
            v = np.asarray(spline(t, 1), dtype=float)
        else:
            v = np.zeros_like(p)
    else:
        resolved = kind  # type: ignore[assignment]
        if resolved in ("cubic", "quintic") and v is None:
            raise ValueError(f"kind {kind!r} needs velocities")
        if resolved == "quintic" and a is None:
            raise ValueError("kind 'quintic' needs accelerations")

    if n_knots == 1:
        zeros = np.zeros_like(p)
        return Interpolant(resolved, t, p, zeros, zeros.copy(), np.zeros((0, n_joints, _N_COEFFS)))

    h = np.diff(t)[:, None]
    v_k = np.zeros_like(p) if v is None else v
    a_k = np.zeros_like(p) if a is None else a
    coeffs = _segment_coefficients(resolved, h, p[:-1], p[1:], v_k[:-1], v_k[1:], a_k[:-1], a_k[1:])
    if not np.all(np.isfinite(coeffs)):
        raise ValueError("time steps too small for the given values (non-finite coefficients)")

    if resolved == "quintic":
        assert v is not None and a is not None
        vel, acc = v.copy(), a.copy()
    elif resolved == "cubic":
        assert v is not None
        vel = v.copy()
        acc = np.empty_like(p)
        acc[:-1] = 2.0 * coeffs[:, :, 2]
        acc[-1] = 2.0 * coeffs[-1, :, 2] + 6.0 * coeffs[-1, :, 3] * h[-1]
    else:
        vel = np.empty_like(p)
        vel[:-1] = coeffs[:, :, 1]
        vel[-1] = coeffs[-1, :, 1]
        acc = np.zeros_like(p)
    return Interpolant(resolved, t, p, vel, acc, coeffs)


def sample_block(interpolant: Interpolant, t0: float | Sequence[float], period_s: float,
                 count: int, *, out: FloatArray | None = None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Sample ``count`` control cycles at ``t0 + k * period_s`` (s), k = 0..count-1.

    ``t0`` may also be several blocks' first times: each block is sampled on its own grid
    (``t0[b] + k * period_s``, the same values as sampling it alone) and the blocks follow
    one another in the result. Returns positions, velocities and accelerations, each
    (blocks·count, J). With ``out``, an array (blocks·count, J, 3), they are written there,
    a cycle's row holding each joint's position, velocity and acceleration in turn (a control
    loop reuses one buffer, block after block), and returned as views of it.
    """
    try:
        starts = [float(t0)] if np.ndim(t0) == 0 else [float(x) for x in t0]  # type: ignore[union-attr]
        period, n = float(period_s), int(count)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"bad sample_block arguments: {exc}") from None
    if not all(math.isfinite(x) for x in starts):
        raise ValueError(f"t0 must be finite, got {t0!r}")
    if not (math.isfinite(period) and period > 0.0):
        raise ValueError(f"period_s must be positive and finite, got {period_s!r}")
    if n != count or n < 0:
        raise ValueError(f"count must be a non-negative integer, got {count!r}")
    grid = period * np.arange(n, dtype=float)
    if len(starts) == 1:
        times, increasing = starts[0] + grid, True
    else:  # blocks may overlap; rounding may put one block's last time after the next one's first
        times, increasing = np.concatenate([x + grid for x in starts] or [grid[:0]]), None
    if out is not None and out.shape != (times.size, interpolant.n_joints, 3):
        raise ValueError(f"out must have shape ({times.size}, {interpolant.n_joints}, 3), got {out.shape}")
    values = interpolant._evaluate(times, increasing=increasing)
    if out is None:
        return values[0].T, values[1].T, values[2].T
    out[...] = values.transpose(2, 1, 0)  # evaluating into the strided rows directly is slower
    return out[:, :, 0], out[:, :, 1], out[:, :, 2]

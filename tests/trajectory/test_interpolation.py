"""Tests for jointctl.trajectory.interpolation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicSpline

from jointctl.trajectory.interpolation import Interpolant, build_interpolant, sample_block


def _random_knots(seed: int, n_knots: int = 6, n_joints: int = 3):
    rng = np.random.default_rng(seed)
    times = np.concatenate(([0.3], 0.3 + np.cumsum(rng.uniform(0.05, 1.5, n_knots - 1))))
    pos, vel, acc = rng.uniform(-2.0, 2.0, (3, n_knots, n_joints))
    return times, pos, vel, acc


def _left(t: float) -> float:
    """The float just before t: samples the previous segment at its very end."""
    return float(np.nextafter(t, -np.inf))


# --- exact knots and hand-computed midpoints -------------------------------------------------

def test_linear_knots_midpoints_and_slopes() -> None:
    it = build_interpolant([0.0, 1.0, 3.0], [[0.0, 0.0], [1.0, 2.0], [3.0, -2.0]])
    assert it.kind == "linear" and it.n_joints == 2 and it.duration_s == 3.0
    pos, vel, acc = it.sample(0.5)
    np.testing.assert_allclose(pos, [0.5, 1.0])
    np.testing.assert_allclose(vel, [1.0, 2.0])
    np.testing.assert_array_equal(acc, [0.0, 0.0])
    pos, vel, _ = it.sample(2.0)
    np.testing.assert_allclose(pos, [2.0, 0.0])
    np.testing.assert_allclose(vel, [1.0, -2.0])
    # velocities at knots: outgoing slope, the last knot the last slope; equal to sample()
    np.testing.assert_allclose(it.velocities, [[1.0, 2.0], [1.0, -2.0], [1.0, -2.0]])
    np.testing.assert_array_equal(it.accelerations, np.zeros((3, 2)))
    for k, t in enumerate(it.times_s):
        pos, vel, acc = it.sample(t)
        np.testing.assert_array_equal(pos, it.positions[k])
        np.testing.assert_array_equal(vel, it.velocities[k])


def test_cubic_hermite_midpoint_by_hand() -> None:
    # rest to rest over 1 s: p(0.5) = 0.5, v(0.5) = 1.5, a(0.5) = 0
    it = build_interpolant([0.0, 1.0], [[0.0], [1.0]], [[0.0], [0.0]])
    assert it.kind == "cubic"
    pos, vel, acc = it.sample(0.5)
    assert pos[0] == pytest.approx(0.5) and vel[0] == pytest.approx(1.5) and acc[0] == pytest.approx(0.0)
    np.testing.assert_allclose(it.accelerations, [[6.0], [-6.0]])
    # p(h/2) = (p0 + p1)/2 + h (v0 - v1)/8; v(h/2) = 1.5 (p1 - p0)/h - (v0 + v1)/4
    it = build_interpolant([1.0, 3.0], [[0.0], [0.0]], [[1.0], [-1.0]])
    pos, vel, _ = it.sample(2.0)
    assert pos[0] == pytest.approx(0.5) and vel[0] == pytest.approx(0.0)


def test_quintic_midpoint_by_hand() -> None:
    # rest to rest over 1 s (minimum jerk): p(0.5) = 0.5, v(0.5) = 30/16, a(0.5) = 0
    it = build_interpolant([0.0, 1.0], [[0.0], [1.0]], [[0.0], [0.0]], [[0.0], [0.0]])
    assert it.kind == "quintic"
    pos, vel, acc = it.sample(0.5)
    assert pos[0] == pytest.approx(0.5) and vel[0] == pytest.approx(1.875) and acc[0] == pytest.approx(0.0)
    # p(h/2) = (p0 + p1)/2 + 5 h (v0 - v1)/32 + h² (a0 + a1)/64
    h = 2.0
    it = build_interpolant([0.0, h], [[1.0], [2.0]], [[0.5], [-0.25]], [[1.0], [3.0]])
    expected = 1.5 + 5 * h * 0.75 / 32 + h**2 * 4.0 / 64
    assert it.sample(1.0)[0][0] == pytest.approx(expected)


def test_quintic_matches_linear_solve() -> None:
    times, pos, vel, acc = _random_knots(1, n_knots=4, n_joints=2)
    it = build_interpolant(times, pos, vel, acc)
    for k in range(len(times) - 1):
        h = times[k + 1] - times[k]
        rows = []
        for tau in (0.0, h):
            rows.append([tau**i for i in range(6)])
            rows.append([i * tau ** (i - 1) if i >= 1 else 0.0 for i in range(6)])
            rows.append([i * (i - 1) * tau ** (i - 2) if i >= 2 else 0.0 for i in range(6)])
        for j in range(2):
            rhs = [pos[k, j], vel[k, j], acc[k, j], pos[k + 1, j], vel[k + 1, j], acc[k + 1, j]]
            np.testing.assert_allclose(it.coefficients[k, j], np.linalg.solve(np.array(rows), rhs),
                                       rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("kind", ["linear", "cubic", "quintic", "spline"])
def test_passes_exactly_through_knots(kind: str) -> None:
    times, pos, vel, acc = _random_knots(2)
    it = build_interpolant(times, pos, vel, acc, kind=kind)
    p, v, a = it.sample(times)
    np.testing.assert_array_equal(p, pos)
    np.testing.assert_array_equal(v, it.velocities)
    np.testing.assert_array_equal(a, it.accelerations)
    if kind in ("cubic", "quintic"):
        np.testing.assert_array_equal(it.velocities, vel)
    if kind == "quintic":
        np.testing.assert_array_equal(it.accelerations, acc)
    # the left limit at every interior/last knot reaches the knot position too
    for k in range(1, len(times)):
        np.testing.assert_allclose(it.sample(_left(times[k]))[0], pos[k], atol=1e-9)


# --- continuity --------------------------------------------------------------------------------

def test_cubic_hermite_is_c1_but_not_c2() -> None:
    times, pos, vel, _ = _random_knots(3)
    it = build_interpolant(times, pos, vel)
    jumps = []
    for k in range(1, len(times) - 1):
        left, right = it.sample(_left(times[k])), it.sample(times[k])
        np.testing.assert_allclose(left[0], right[0], atol=1e-9)
        np.testing.assert_allclose(left[1], right[1], atol=1e-9)
        jumps.append(np.max(np.abs(left[2] - right[2])))
    assert max(jumps) > 1e-3          # arbitrary velocities: acceleration jumps


def test_spline_fill_is_c2_and_equals_scipy() -> None:
    times, pos, _, _ = _random_knots(4, n_knots=8)
    it = build_interpolant(times, pos, kind="spline", start_velocity=0.3, end_velocity=[0.0, -0.5, 1.0])
    assert it.kind == "cubic"
    for k in range(1, len(times) - 1):
        left, right = it.sample(_left(times[k])), it.sample(times[k])
        for d in range(3):
            np.testing.assert_allclose(left[d], right[d], rtol=1e-7, atol=1e-7)
    # second derivative continuous by finite differences of velocity across each knot too
    eps = 1e-6
    for k in range(1, len(times) - 1):
        before = (it.sample(times[k])[1] - it.sample(times[k] - eps)[1]) / eps
        after = (it.sample(times[k] + eps)[1] - it.sample(times[k])[1]) / eps
        np.testing.assert_allclose(before, after, atol=1e-3)
    spline = CubicSpline(times, pos, bc_type=((1, np.full(3, 0.3)), (1, np.array([0.0, -0.5, 1.0]))))
    t = np.linspace(times[0], times[-1], 501)
    p, v, a = it.sample(t)
    np.testing.assert_allclose(p, spline(t), atol=1e-9)
    np.testing.assert_allclose(v, spline(t, 1), atol=1e-8)
    np.testing.assert_allclose(a, spline(t, 2), atol=1e-6)
    np.testing.assert_allclose(it.velocities[0], 0.3)
    np.testing.assert_allclose(it.velocities[-1], [0.0, -0.5, 1.0])


def test_quintic_is_c2_at_knots() -> None:
    times, pos, vel, acc = _random_knots(5)
    it = build_interpolant(times, pos, vel, acc)
    for k in range(1, len(times) - 1):
        left, right = it.sample(_left(times[k])), it.sample(times[k])
        for d in range(3):
            np.testing.assert_allclose(left[d], right[d], rtol=1e-7, atol=1e-7)


# --- sampling ----------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["linear", "cubic", "quintic"])
def test_vectorised_equals_scalar(kind: str) -> None:
    times, pos, vel, acc = _random_knots(6)
    it = build_interpolant(times, pos, vel, acc, kind=kind)
    t = np.concatenate((np.linspace(times[0] - 1.0, times[-1] + 1.0, 97), times))
    p, v, a = it.sample(t)
    assert p.shape == v.shape == a.shape == (t.size, 3)
    for i, ti in enumerate(t):
        ps, vs, as_ = it.sample(float(ti))
        assert ps.shape == (3,)
        np.testing.assert_array_equal(ps, p[i])
        np.testing.assert_array_equal(vs, v[i])
        np.testing.assert_array_equal(as_, a[i])


@pytest.mark.parametrize("kind", ["linear", "cubic", "quintic"])
def test_holds_outside_range(kind: str) -> None:
    times, pos, vel, acc = _random_knots(7)
    it = build_interpolant(times, pos, vel, acc, kind=kind)
    before = np.array([times[0] - 10.0, _left(times[0])])
    after = np.array([times[-1] + 1e-9, times[-1] + 100.0])
    p, v, a = it.sample(before)
    np.testing.assert_array_equal(p, [pos[0], pos[0]])
    np.testing.assert_array_equal(v, np.zeros((2, 3)))
    np.testing.assert_array_equal(a, np.zeros((2, 3)))
    p, v, a = it.sample(after)
    np.testing.assert_array_equal(p, [pos[-1], pos[-1]])
    np.testing.assert_array_equal(v, np.zeros((2, 3)))
    np.testing.assert_array_equal(a, np.zeros((2, 3)))


def test_single_point_is_a_hold() -> None:
    it = build_interpolant([2.0], [[1.0, -1.0]], [[5.0, 5.0]])
    assert it.duration_s == 2.0 and it.coefficients.shape == (0, 2, 6)
    p, v, a = it.sample(np.array([0.0, 2.0, 5.0]))
    np.testing.assert_array_equal(p, [[1.0, -1.0]] * 3)
    np.testing.assert_array_equal(v, np.zeros((3, 2)))
    np.testing.assert_array_equal(a, np.zeros((3, 2)))
    assert build_interpolant([0.0], [[1.0]], kind="spline").sample(1.0)[0][0] == 1.0


def test_sample_block() -> None:
    times, pos, vel, acc = _random_knots(8)
    it = build_interpolant(times, pos, vel, acc)
    p, v, a = sample_block(it, 0.25, 0.001, 500)
    assert p.shape == (500, 3)
    ref = it.sample(0.25 + 0.001 * np.arange(500))
    for got, want in zip((p, v, a), ref):
        np.testing.assert_array_equal(got, want)
    assert sample_block(it, 0.0, 0.001, 0)[0].shape == (0, 3)
    for bad in ((0.0, 0.0, 3), (0.0, -1.0, 3), (0.0, 0.001, -1), (np.nan, 0.001, 3), (0.0, 0.001, 2.5)):
        with pytest.raises(ValueError):
            sample_block(it, *bad)


def test_sample_block_of_several_blocks_is_each_block_sampled_alone() -> None:
    times, pos, vel, acc = _random_knots(8)
    it = build_interpolant(times, pos, vel, acc)
    starts = [0.25, 0.25 + 0.001 * 300, 0.9, 0.5]  # in any order, even overlapping
    together = sample_block(it, starts, 0.001, 300)
    alone = [sample_block(it, t0, 0.001, 300) for t0 in starts]
    for got, want in zip(together, zip(*alone)):
        np.testing.assert_array_equal(got, np.vstack(want))
    assert sample_block(it, [], 0.001, 10)[0].shape == (0, 3)


def test_sample_block_into_rows_of_position_velocity_acceleration() -> None:
    times, pos, vel, acc = _random_knots(8)
    it = build_interpolant(times, pos, vel, acc)
    rows = np.empty((2 * 50, 3, 3))
    p, v, a = sample_block(it, [0.3, 0.7], 0.002, 50, out=rows)
    want = sample_block(it, [0.3, 0.7], 0.002, 50)
    for k, (got, expected) in enumerate(zip((p, v, a), want)):
        np.testing.assert_array_equal(rows[:, :, k], expected)
        assert np.shares_memory(got, rows)
    with pytest.raises(ValueError, match="out must have shape"):
        sample_block(it, 0.3, 0.002, 50, out=rows)


def test_arrays_are_read_only() -> None:
    it = build_interpolant([0.0, 1.0], [[0.0], [1.0]])
    with pytest.raises(ValueError):
        it.positions[0, 0] = 3.0


# --- programming guards ------------------------------------------------------------------------

@pytest.mark.parametrize("args, kwargs", [
    (([0.0, 1.0, 1.0], [[0.0], [1.0], [2.0]]), {}),                 # not strictly increasing
    (([1.0, 0.0], [[0.0], [1.0]]), {}),                             # decreasing
    (([0.0, 1.0], [[0.0], [1.0], [2.0]]), {}),                      # shape mismatch
    (([0.0, 1.0], [0.0, 1.0]), {}),                                 # 1-D positions
    (([0.0, 1.0], [[0.0], [1.0]], [[0.0]]), {}),                    # velocity shape
    (([0.0, 1.0], [[0.0], [1.0]]), {"kind": "cubic"}),              # cubic without velocities
    (([0.0, 1.0], [[0.0], [1.0]], [[0.0], [0.0]]), {"kind": "quintic"}),
    (([0.0, 1.0], [[0.0], [1.0]], None, [[0.0], [0.0]]), {}),       # accelerations only
    (([0.0, 1.0], [[0.0], [np.nan]]), {}),
    (([0.0, np.inf], [[0.0], [1.0]]), {}),
    (([], np.zeros((0, 1))), {}),
    (([0.0, 1.0], [[0.0], [1.0]]), {"kind": "bezier"}),
    (([0.0, 1.0], [[0.0], [1.0]]), {"kind": "spline", "start_velocity": [1.0, 2.0]}),
    (([0.0, 1.0], [["a"], [1.0]]), {}),
])
def test_value_errors(args, kwargs) -> None:
    with pytest.raises(ValueError):
        build_interpolant(*args, **kwargs)


def test_sample_rejects_bad_times() -> None:
    it = build_interpolant([0.0, 1.0], [[0.0], [1.0]])
    with pytest.raises(ValueError):
        it.sample(np.zeros((2, 2)))
    with pytest.raises(ValueError):
        it.sample(np.nan)


# --- property tests ----------------------------------------------------------------------------

@st.composite
def knot_sets(draw):
    n_knots = draw(st.integers(2, 30))
    n_joints = draw(st.integers(1, 7))
    steps = draw(st.lists(st.floats(0.01, 2.0), min_size=n_knots - 1, max_size=n_knots - 1))
    t0 = draw(st.floats(-5.0, 5.0))
    times = t0 + np.concatenate(([0.0], np.cumsum(steps)))
    values = st.floats(-10.0, 10.0, allow_nan=False)
    shape = (n_knots, n_joints)
    pos = np.array(draw(st.lists(values, min_size=pos_size(shape), max_size=pos_size(shape)))).reshape(shape)
    vel = np.array(draw(st.lists(values, min_size=pos_size(shape), max_size=pos_size(shape)))).reshape(shape)
    acc = 10.0 * np.array(draw(st.lists(values, min_size=pos_size(shape), max_size=pos_size(shape)))).reshape(shape)
    return times, pos, vel, acc


def pos_size(shape: tuple[int, int]) -> int:
    return shape[0] * shape[1]


@settings(max_examples=200, deadline=None)
@given(knot_sets(), st.sampled_from(["linear", "cubic", "quintic", "spline", "auto"]))
def test_property_passes_through_every_point(knots, kind) -> None:
    times, pos, vel, acc = knots
    it = build_interpolant(times, pos, vel, acc, kind=kind)
    p, v, a = it.sample(times)
    np.testing.assert_allclose(p, pos, rtol=0, atol=1e-9)
    if kind in ("cubic", "quintic", "auto"):
        np.testing.assert_allclose(v, vel, rtol=0, atol=1e-9)
    if kind in ("quintic", "auto"):
        np.testing.assert_allclose(a, acc, rtol=0, atol=1e-9)
    # each segment reaches the next knot from the left as well
    left = np.nextafter(times[1:], -np.inf)
    scale = 1.0 + np.abs(vel).max() + np.abs(acc).max()
    np.testing.assert_allclose(it.sample(left)[0], pos[1:], rtol=0, atol=1e-9 * scale)


@settings(max_examples=200, deadline=None)
@given(knot_sets(), st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20))
def test_property_linear_stays_within_segment_bounds(knots, fractions) -> None:
    times, pos, _, _ = knots
    it = build_interpolant(times, pos)
    seg = np.arange(len(times) - 1)
    for f in fractions:
        t = times[:-1] + f * np.diff(times)
        p, v, a = it.sample(t)
        lo = np.minimum(pos[seg], pos[seg + 1])
        hi = np.maximum(pos[seg], pos[seg + 1])
        assert np.all(p >= lo - 1e-12) and np.all(p <= hi + 1e-12)
        np.testing.assert_array_equal(a, 0.0)


def _anything():
    scalars = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 5),
                        st.just("x"), st.none())
    flat = st.lists(scalars, max_size=6)
    nested = st.lists(st.lists(scalars, max_size=4), max_size=6)
    return st.one_of(scalars, flat, nested, st.just([[0.0], [1.0]]), st.just({"a": 1}))


@settings(max_examples=300, deadline=None)
@given(_anything(), _anything(), st.one_of(st.none(), _anything()), st.one_of(st.none(), _anything()),
       st.sampled_from(["linear", "cubic", "quintic", "spline", "auto", "nope"]),
       st.one_of(st.none(), _anything()), st.one_of(st.floats(), st.lists(st.floats(), max_size=5)))
def test_property_only_value_errors(times, pos, vel, acc, kind, start_velocity, t) -> None:
    try:
        it = build_interpolant(times, pos, vel, acc, kind=kind, start_velocity=start_velocity)
    except ValueError:
        return
    assert isinstance(it, Interpolant)
    try:
        it.sample(t)
    except ValueError:
        pass


@settings(max_examples=100, deadline=None)
@given(knot_sets(), st.integers(0, 3))
def test_property_random_times_are_finite(knots, seed) -> None:
    times, pos, vel, acc = knots
    it = build_interpolant(times, pos, vel, acc)
    t = np.random.default_rng(seed).uniform(times[0] - 1.0, times[-1] + 1.0, 50)
    for arr in it.sample(t):
        assert np.all(np.isfinite(arr))

"""Tests for jointctl.trajectory.timing."""

from __future__ import annotations

import numpy as np
import pytest
import ruckig

from jointctl.trajectory.interpolation import build_interpolant
from jointctl.trajectory.timing import (BLEND_VELOCITY_FRACTION, PATH_MAX_ACCELERATION, PATH_MAX_JERK,
                                        PATH_START_S, PATH_VELOCITY_FRACTION, chapter_timing, ruckig_timing,
                                        time_path)

CHAPTER_VMAX = np.array([0.17, 0.17, 0.3, 0.3, 0.4, 0.4, 0.4])
AMAX = np.array([0.5, 0.5, 1.0, 1.0, 2.0, 2.0, 2.0])
JMAX = np.array([5.0, 5.0, 10.0, 10.0, 20.0, 20.0, 20.0])
HOME = [0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0]


# --- chapter_timing ------------------------------------------------------------------------------

def test_chapter_timing_example_13_33_s() -> None:
    times = chapter_timing([[0.0] * 7, HOME], CHAPTER_VMAX)
    np.testing.assert_allclose(times, [0.0, 2.0 / (0.5 * 0.3)])
    assert times[-1] == pytest.approx(13.333, abs=1e-3)


def test_chapter_timing_several_points_and_minimum_segment() -> None:
    path = [[0.0, 0.0], [0.1, -0.2], [0.1, -0.2], [0.1001, -0.2], [0.1001, 0.0]]
    times = chapter_timing(path, [0.5, 1.0])
    # 0.1/0.25 = 0.4 vs 0.2/0.5 = 0.4; repeat -> 0.02; tiny move -> 0.02; 0.2/0.5 = 0.4
    np.testing.assert_allclose(times, [0.0, 0.4, 0.42, 0.44, 0.84])
    times = chapter_timing(path, 1.0, velocity_fraction=1.0, min_segment_s=0.05)
    np.testing.assert_allclose(np.diff(times), [0.2, 0.05, 0.05, 0.2])


def test_chapter_timing_single_point_and_unlimited_joint() -> None:
    np.testing.assert_array_equal(chapter_timing([[1.0, 2.0]], [1.0, 1.0]), [0.0])
    times = chapter_timing([[0.0, 0.0], [5.0, 0.1]], [np.inf, 1.0])
    np.testing.assert_allclose(times, [0.0, 0.2])


@pytest.mark.parametrize("path, vmax, kwargs, match", [
    ([[0.0, 0.0], [1.0, 1.0]], [1.0, 0.0], {}, r"joint 1"),
    ([[0.0, 0.0], [1.0, 1.0]], [-1.0, 1.0], {}, r"joint 0"),
    ([[0.0, 0.0], [1.0, 1.0]], [1.0, np.nan], {}, r"joint 1"),
    ([[0.0, 0.0], [1.0, 1.0]], [1.0, 1.0, 1.0], {}, "shape"),
    ([[0.0, np.nan], [1.0, 1.0]], [1.0, 1.0], {}, "NaN"),
    ([0.0, 1.0], 1.0, {}, "shape"),
    (np.zeros((0, 2)), 1.0, {}, "shape"),
    ([[0.0], [1.0]], 1.0, {"velocity_fraction": 0.0}, "velocity_fraction"),
    ([[0.0], [1.0]], 1.0, {"min_segment_s": 0.0}, "min_segment_s"),
])
def test_chapter_timing_value_errors(path, vmax, kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        chapter_timing(path, vmax, **kwargs)


# --- ruckig_timing -------------------------------------------------------------------------------



def _path(seed: int = 0, n_points: int = 6) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.vstack([np.zeros(7), rng.uniform(-1.0, 1.0, (n_points - 1, 7))])


def _waypoint_indices(path: np.ndarray, positions: np.ndarray) -> list[int]:
    """Sample index of each waypoint, in order, where the positions equal it bit for bit."""
    indices, start = [], 0
    for row in path:
        hits = np.flatnonzero(np.all(positions[start:] == row, axis=1))
        assert hits.size, f"waypoint {row} not in the samples"
        indices.append(start + int(hits[0]))
        start = indices[-1] + 1
    return indices


@pytest.mark.parametrize("blend", [False, True])
def test_ruckig_passes_every_waypoint_exactly(blend: bool) -> None:
    path = _path(1)
    times, pos, vel, acc = ruckig_timing(path, CHAPTER_VMAX, AMAX, JMAX, blend=blend)
    assert times[0] == 0.0 and np.all(np.diff(times) > 0.0)
    assert np.max(np.diff(times)) < 1.2 * 0.01
    idx = _waypoint_indices(path, pos)
    assert idx[0] == 0 and idx[-1] == len(times) - 1
    np.testing.assert_array_equal(acc[idx], 0.0)
    np.testing.assert_array_equal(vel[[idx[0], idx[-1]]], 0.0)
    it = build_interpolant(times, pos, vel, acc)
    assert it.kind == "quintic"
    np.testing.assert_array_equal(it.sample(times[idx])[0], path)


@pytest.mark.parametrize("blend", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ruckig_respects_limits(blend: bool, seed: int) -> None:
    path = _path(seed, n_points=8)
    times, pos, vel, acc = ruckig_timing(path, CHAPTER_VMAX, AMAX, JMAX, blend=blend)
    assert np.all(np.abs(vel) <= CHAPTER_VMAX * (1 + 1e-9))
    assert np.all(np.abs(acc) <= AMAX * (1 + 1e-9))
    # the quintic through the samples, sampled densely at 1 ms
    it = build_interpolant(times, pos, vel, acc)
    t = np.arange(0.0, times[-1], 0.001)
    _, v, a = it.sample(t)
    assert np.all(np.abs(v) <= CHAPTER_VMAX * (1 + 1e-6))
    assert np.all(np.abs(a) <= AMAX * (1 + 1e-6))
    jerk = np.diff(a, axis=0) / 0.001
    assert np.all(np.abs(jerk) <= JMAX * 1.01)
    # the limits are actually used (time-optimal): some joint reaches its acceleration limit
    assert np.max(np.abs(a) / AMAX) > 0.99


def test_ruckig_interpolant_reproduces_profile_and_single_segment_duration() -> None:
    path = np.array([[0.0] * 7, HOME])
    times, pos, vel, acc = ruckig_timing(path, CHAPTER_VMAX, AMAX, JMAX)
    otg, inp, traj = ruckig.Ruckig(7), ruckig.InputParameter(7), ruckig.Trajectory(7)
    inp.current_position, inp.target_position = path[0].tolist(), path[1].tolist()
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = CHAPTER_VMAX.tolist(), AMAX.tolist(), JMAX.tolist()
    otg.calculate(inp, traj)
    assert times[-1] == traj.duration
    it = build_interpolant(times, pos, vel, acc)
    t = np.arange(0.0, traj.duration, 0.001)
    want = np.array([traj.at_time(x) for x in t])             # (T, 3, J)
    got = it.sample(t)
    for d, tol in enumerate((1e-9, 1e-8, 1e-6)):
        np.testing.assert_allclose(got[d], want[:, d], rtol=0, atol=tol)
    # joint 3 (the longest move) cruises at its velocity limit, not above
    assert np.max(np.abs(got[1][:, 3])) == pytest.approx(CHAPTER_VMAX[3], rel=1e-9)


def test_ruckig_rest_to_rest_without_blend() -> None:
    path = np.array([[0.0, 0.0], [0.5, 0.2], [1.0, 0.4], [1.5, 0.1]])
    vmax, amax, jmax = [1.0, 1.0], [2.0, 2.0], [10.0, 10.0]
    times, pos, vel, acc = ruckig_timing(path, vmax, amax, jmax, blend=False)
    idx = _waypoint_indices(path, pos)
    np.testing.assert_array_equal(vel[idx], 0.0)
    np.testing.assert_array_equal(acc[idx], 0.0)
    it = build_interpolant(times, pos, vel, acc)
    for i in idx[1:-1]:                          # at rest just before and just after the waypoint
        for t in (times[i] - 1e-6, times[i] + 1e-6):
            assert np.all(np.abs(it.sample(t)[1]) < 1e-6)


def test_ruckig_blend_velocities() -> None:
    # joint 0 monotone, joint 1 reverses at waypoint 1, joint 2 stands still after waypoint 2
    path = np.array([[0.0, 0.0, 0.0], [0.5, 0.3, 0.2], [1.0, 0.0, 0.4], [1.5, -0.2, 0.4], [2.0, -0.4, 0.4]])
    vmax, amax, jmax = np.array([1.0, 1.0, 1.0]), np.array([2.0] * 3), np.array([10.0] * 3)
    times, pos, vel, acc = ruckig_timing(path, vmax, amax, jmax, blend=True)
    v_wp = vel[_waypoint_indices(path, pos)]
    assert np.all(v_wp[1:-1, 0] > 0.0)
    assert v_wp[1, 1] == 0.0 and v_wp[2, 1] < 0.0 and v_wp[3, 1] < 0.0
    assert v_wp[1, 2] > 0.0 and v_wp[2, 2] == 0.0 and v_wp[3, 2] == 0.0
    assert np.all(np.abs(v_wp) <= BLEND_VELOCITY_FRACTION * vmax + 1e-12)
    np.testing.assert_array_equal(v_wp[[0, -1]], 0.0)


def test_ruckig_blend_is_faster_on_a_long_monotone_path() -> None:
    path = np.linspace(np.zeros(7), 2.0 * np.array(HOME) + 0.5, 21)
    rest = ruckig_timing(path, CHAPTER_VMAX, AMAX, JMAX, blend=False)[0][-1]
    blended = ruckig_timing(path, CHAPTER_VMAX, AMAX, JMAX, blend=True)[0][-1]
    # 23.5 s rest to rest, 16.7 s blended (the spline timed by rest-to-rest durations passes the
    # waypoints at about half the velocity limit); one straight segment would take 15.1 s
    assert blended < 0.75 * rest


@pytest.mark.parametrize("seed", range(10))
def test_ruckig_blend_never_slower_on_monotone_paths(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n_joints = int(rng.integers(1, 8))
    steps = rng.uniform(0.0, 0.5, (int(rng.integers(2, 12)), n_joints))
    steps *= rng.choice([0.0, 1.0], size=steps.shape, p=[0.2, 0.8])     # some joints pause
    steps *= rng.choice([-1.0, 1.0], size=n_joints)
    path = np.vstack([np.zeros(n_joints), np.cumsum(steps, axis=0)])
    limits = [rng.uniform(0.2, 2.0, n_joints), rng.uniform(0.5, 5.0, n_joints), rng.uniform(2.0, 50.0, n_joints)]
    rest = ruckig_timing(path, *limits, blend=False)[0][-1]
    blended = ruckig_timing(path, *limits, blend=True)[0][-1]
    assert blended <= rest


def test_ruckig_single_point_and_repeated_waypoint() -> None:
    times, pos, vel, acc = ruckig_timing([[0.3, 0.4]], 1.0, 1.0, 1.0)
    np.testing.assert_array_equal(times, [0.0])
    np.testing.assert_array_equal(pos, [[0.3, 0.4]])
    path = np.array([[0.0, 0.0], [0.0, 0.0], [0.5, 0.5], [0.5, 0.5]])
    times, pos, vel, acc = ruckig_timing(path, 1.0, 1.0, 1.0)
    assert np.all(np.diff(times) > 0.0)
    _waypoint_indices(path, pos)
    build_interpolant(times, pos, vel, acc)


@pytest.mark.parametrize("limits, match", [
    (([1.0, np.inf], [1.0, 1.0], [1.0, 1.0]), r"max_velocity\[1\] \(joint 1\)"),
    (([1.0, 1.0], [0.0, 1.0], [1.0, 1.0]), r"max_acceleration\[0\] \(joint 0\)"),
    (([1.0, 1.0], [1.0, 1.0], [1.0, -2.0]), r"max_jerk\[1\] \(joint 1\)"),
    (([1.0, 1.0], [1.0, 1.0], [np.nan, 1.0]), r"max_jerk\[0\] \(joint 0\)"),
    (([1.0, 1.0], [1.0, 1.0], [1.0]), "shape"),
])
def test_ruckig_bad_limits(limits, match) -> None:
    with pytest.raises(ValueError, match=match):
        ruckig_timing([[0.0, 0.0], [1.0, 1.0]], *limits)


@pytest.mark.parametrize("path, kwargs", [
    ([[0.0, np.nan], [1.0, 1.0]], {}),
    ([0.0, 1.0], {}),
    (np.zeros((0, 2)), {}),
    ([[0.0, 0.0], [1.0, 1.0]], {"sample_period_s": 0.0}),
    ("abc", {}),
])
def test_ruckig_bad_input(path, kwargs) -> None:
    with pytest.raises(ValueError):
        ruckig_timing(path, 1.0, 1.0, 1.0, **kwargs)


# --- time_path: the one way a path is timed from the current pose ---------------------------------

ARM = tuple(f"joint{k}" for k in range(7))
ARM_VMAX = [0.2, 0.2, 0.3, 0.3, 0.4, 0.5, 0.4]  # the arm's URDF


def test_time_path_chapter_rule_starts_at_the_current_pose_start_s_after_sending() -> None:
    current = [0.1] * 7
    traj = time_path(ARM, current, [HOME], ARM_VMAX, timing="chapter")
    assert traj.joint_names == ARM
    times = [p.time_from_start_s for p in traj.points]
    # Joint 3 sets the pace: 2.1 rad at PATH_VELOCITY_FRACTION of 0.3 rad/s.
    np.testing.assert_allclose(times, [PATH_START_S, PATH_START_S + 2.1 / (PATH_VELOCITY_FRACTION * 0.3)])
    assert traj.points[0].positions == tuple(current) and traj.points[-1].positions == tuple(HOME)
    assert traj.points[0].velocities == ()  # positions only


def test_time_path_of_some_joints_names_only_those() -> None:
    current = [0.0] * 7
    traj = time_path(ARM, current, [[0.5], [0.2]], ARM_VMAX, timing="chapter", path_joints=["joint5"],
                     start_s=0.0, velocity_fraction=1.0)
    assert traj.joint_names == ("joint5",)
    np.testing.assert_allclose([p.time_from_start_s for p in traj.points], [0.0, 1.0, 1.6])  # 0.5/0.5, 0.3/0.5
    assert [p.positions for p in traj.points] == [(0.0,), (0.5,), (0.2,)]


def test_time_path_ruckig_is_ruckig_timing_from_the_current_pose_with_the_default_limits() -> None:
    current = np.zeros(7)
    traj = time_path(ARM, current, [HOME], ARM_VMAX)
    times, positions, velocities, accelerations = ruckig_timing(
        np.vstack((current, HOME)), np.array(ARM_VMAX) * PATH_VELOCITY_FRACTION, PATH_MAX_ACCELERATION,
        PATH_MAX_JERK)
    np.testing.assert_array_equal([p.time_from_start_s for p in traj.points], times + PATH_START_S)
    np.testing.assert_array_equal([p.positions for p in traj.points], positions)
    np.testing.assert_array_equal([p.velocities for p in traj.points], velocities)
    np.testing.assert_array_equal([p.accelerations for p in traj.points], accelerations)


def test_time_path_per_joint_limits_are_those_of_the_named_columns() -> None:
    amax, jmax = np.linspace(0.5, 3.5, 7), np.linspace(5.0, 35.0, 7)
    traj = time_path(ARM, np.zeros(7), [[0.3, -0.2]], ARM_VMAX, path_joints=["joint6", "joint1"],
                     max_acceleration=amax, max_jerk=jmax, velocity_fraction=0.8, start_s=0.0)
    times, positions, _, _ = ruckig_timing([[0.0, 0.0], [0.3, -0.2]], np.array([0.4, 0.2]) * 0.8,
                                           amax[[6, 1]], jmax[[6, 1]])
    np.testing.assert_array_equal([p.time_from_start_s for p in traj.points], times)
    np.testing.assert_array_equal([p.positions for p in traj.points], positions)


@pytest.mark.parametrize("kwargs, match", [
    ({"timing": "fast"}, "timing must be one of chapter, ruckig"),
    ({"path_joints": ["joint9"]}, "not all among"),
    ({"max_acceleration": [1.0, 2.0]}, "max_acceleration must be a scalar or have shape"),
])
def test_time_path_refuses_unknown_rules_joints_and_shapes(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        time_path(ARM, np.zeros(7), [HOME], ARM_VMAX, **kwargs)

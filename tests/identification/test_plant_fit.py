"""The joint model fit against data made from known parameters (exact, then with noise), and its refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jointctl.identification.plant_fit import IdentificationError, fit_plant, resample_uniform, stamp_period, stretches
from tests.identification.joint_state_stream import Timing, joint_state_stream

DT = 0.001


def motion(seconds: float = 6.0):
    """A joint swinging with changing amplitude and frequency: position, velocity, acceleration."""
    t = np.arange(0.0, seconds, DT)
    q = 0.3 * np.sin(2 * np.pi * 0.7 * t) + 0.1 * np.sin(2 * np.pi * 2.3 * t + 0.4)
    qd = np.gradient(q, DT)
    return t, q, qd


def forward_difference(qd):
    return np.append((qd[1:] - qd[:-1]) / DT, 0.0)


@pytest.mark.parametrize("joint_type", ["prismatic", "revolute"])
def test_known_parameters_are_recovered_exactly_from_exact_data(joint_type) -> None:
    t, q, qd = motion()
    qdd = forward_difference(qd)
    gravity = 9.9 if joint_type == "prismatic" else 4.0 * np.sin(q) - 2.5 * np.cos(q)
    effort = 2.5 * qdd + 7.0 * qd + 1.5 * np.sign(qd) + gravity
    fit = fit_plant(t, q, qd, effort, joint_type=joint_type)
    assert fit.inertia == pytest.approx(2.5, rel=1e-9) and fit.damping == pytest.approx(7.0, rel=1e-9)
    assert fit.friction == pytest.approx(1.5, rel=1e-9)
    if joint_type == "prismatic":
        assert fit.gravity_load == pytest.approx(9.9, rel=1e-9)
    else:
        assert (fit.gravity_sin, fit.gravity_cos) == pytest.approx((4.0, -2.5), rel=1e-9)
    assert fit.effort_shift_cycles == 0 and fit.r_squared == pytest.approx(1.0)


def test_an_effort_logged_a_cycle_late_is_aligned() -> None:
    t, q, qd = motion()
    effort = 1.0 * forward_difference(qd) + 10.0 * qd + 9.81
    late = np.concatenate(([effort[0]], effort[:-1]))  # row k holds the effort of cycle k-1
    fit = fit_plant(t, q, qd, late, joint_type="prismatic")
    assert fit.effort_shift_cycles == 1 and fit.inertia == pytest.approx(1.0, rel=1e-6)


def test_noise_widens_the_confidence_intervals_which_then_hold_the_truth() -> None:
    rng = np.random.default_rng(7)
    t, q, qd = motion(10.0)
    effort = 1.0 * forward_difference(qd) + 10.0 * qd + 0.5 * np.sign(qd) + 9.81 + rng.normal(0, 0.2, t.size)
    fit = fit_plant(t, q, qd, effort, joint_type="prismatic", max_shift_cycles=0)
    for value, ci, truth in ((fit.inertia, fit.inertia_ci95, 1.0), (fit.damping, fit.damping_ci95, 10.0),
                             (fit.friction, fit.friction_ci95, 0.5), (fit.gravity_load, fit.gravity_load_ci95, 9.81)):
        assert 0 < ci < 0.1 * truth + 0.05
        assert abs(value - truth) < 3 * ci  # the interval is honest (3 x the 95 % half-width: very safe)
    assert fit.residual_rms == pytest.approx(0.2, rel=0.05)  # the noise we added


def test_a_trace_without_excitation_is_refused_with_the_reason() -> None:
    t = np.arange(0.0, 2.0, DT)
    q = np.full_like(t, -0.5)
    with pytest.raises(IdentificationError, match="does not move") as info:
        fit_plant(t, q, np.zeros_like(t), np.full_like(t, 9.9), joint_type="prismatic")
    assert info.value.field == "velocity"


def test_a_constant_speed_cannot_separate_inertia_from_the_rest() -> None:
    t = np.arange(0.0, 2.0, DT)
    qd = np.full_like(t, 0.1)
    with pytest.raises(IdentificationError, match="does not separate"):
        fit_plant(t, -0.5 + 0.1 * t, qd, 10.0 * qd + 9.81, joint_type="prismatic")


@pytest.mark.parametrize("change, field", [
    (dict(joint_type="planar"), "joint_type"),
    (dict(time_s=np.arange(0.0, 0.01, DT)), "samples"),
    (dict(time_s=np.cumsum(np.r_[0.0, np.full(5999, DT)]) ** 1.01), "time_s"),
    (dict(effort=np.full(6000, math.nan)), "samples"),
])
def test_bad_input_is_refused_naming_the_field(change, field) -> None:
    t, q, qd = motion()
    args = dict(time_s=t, position=q, velocity=qd, effort=qd, joint_type="prismatic") | change
    if args["time_s"].size != t.size and field == "samples":
        args.update(position=q[:args["time_s"].size], velocity=qd[:args["time_s"].size],
                    effort=args["effort"][:args["time_s"].size])
    with pytest.raises(IdentificationError) as info:
        fit_plant(**args)
    assert info.value.field == field


def sampled_sine(rate_hz: float, frequency_hz: float, seconds: float = 8.0):
    """Exact samples at ``rate_hz`` of q = 0.2·sin(ωt) + 0.05·sin(3.1ωt) and the effort of the model
    2.5·q̈ + 7·q̇ + 1.5·sign(q̇) + 9.9 (its true acceleration, not a difference)."""
    t = np.arange(0.0, seconds, 1.0 / rate_hz)
    w = 2 * np.pi * frequency_hz
    q = 0.2 * np.sin(w * t) + 0.05 * np.sin(3.1 * w * t)
    qd = 0.2 * w * np.cos(w * t) + 0.05 * 3.1 * w * np.cos(3.1 * w * t)
    qdd = -0.2 * w**2 * np.sin(w * t) - 0.05 * (3.1 * w) ** 2 * np.sin(3.1 * w * t)
    return t, q, qd, 2.5 * qdd + 7.0 * qd + 1.5 * np.sign(qd) + 9.9


def test_sparse_states_take_central_differences_within_their_truncation_error() -> None:
    # Joint states at 50 Hz: a central difference of a sine of ω reads its acceleration sin(ωh)/(ωh) low,
    # (ωh)²/6 = 2.5 % at 3.1 Hz; a forward one sits half a sample late, which turns inertia into damping.
    t, q, qd, u = sampled_sine(50.0, 1.0)
    central = fit_plant(t, q, qd, u, joint_type="prismatic", acceleration="central")
    bound = (2 * np.pi * 3.1 * 0.02) ** 2 / 6
    assert central.inertia == pytest.approx(2.5, rel=bound) and central.damping == pytest.approx(7.0, rel=bound)
    assert central.acceleration == "central"
    forward = fit_plant(t, q, qd, u, joint_type="prismatic", max_shift_cycles=0)
    assert abs(forward.damping - 7.0) > 10 * abs(central.damping - 7.0)


def test_states_a_little_off_their_period_are_put_on_the_grid_and_lost_ones_cut_out() -> None:
    t, q, qd, u = sampled_sine(1000.0, 1.0, seconds=4.0)
    keep = np.ones(t.size, dtype=bool)
    keep[[500, 1700, 1701]] = False  # three states lost on the way: two gaps, of 2 and 3 periods
    jitter = np.where(np.arange(t.size) % 7 == 0, 2e-5, 0.0)  # and stamps a little off the grid
    grid, *columns = resample_uniform((t + jitter)[keep], q[keep], qd[keep], u[keep])
    steps = np.diff(grid)
    assert np.allclose(np.sort(steps)[:-2], 0.001, rtol=1e-9)  # one period inside each stretch
    assert np.sort(steps)[-2:] == pytest.approx([0.002, 0.003], abs=3e-5)  # the gaps: not interpolated
    fit = fit_plant(grid, *columns, joint_type="prismatic", acceleration="central")
    assert [at for at, _ in fit.gaps] == pytest.approx([0.499, 1.699], abs=3e-5)
    assert fit.inertia == pytest.approx(2.5, rel=0.01) and fit.damping == pytest.approx(7.0, rel=0.01)


def test_gaps_are_cut_out_of_the_fit_which_reports_them_and_identifies_the_same_plant() -> None:
    # Every cycle recorded, with noise on the effort, then 10 ms and 50 ms of it lost. Each gap costs the
    # lost time and the row whose forward difference would span it; the fit is the same within its
    # intervals, and the truth is inside them.
    rng = np.random.default_rng(11)
    t, q, qd = motion(10.0)
    truth = {"inertia": 1.0, "damping": 10.0, "friction": 0.5, "gravity_load": 9.81}
    effort = (forward_difference(qd) + 10.0 * qd + 0.5 * np.sign(qd) + 9.81) + rng.normal(0, 0.2, t.size)
    whole = fit_plant(t, q, qd, effort, joint_type="prismatic", max_shift_cycles=0)
    lost = ((t >= 2.0) & (t < 2.01)) | ((t >= 6.7) & (t < 6.75))
    keep = ~lost
    cut = fit_plant(t[keep], q[keep], qd[keep], effort[keep], joint_type="prismatic", max_shift_cycles=0)
    assert np.ravel(cut.gaps) == pytest.approx([1.999, 0.011, 6.699, 0.051], abs=1e-9)
    assert cut.samples_given == t.size - lost.sum() == 9940
    assert cut.span_s == pytest.approx(10.0) and cut.usable_s == pytest.approx(9.94)
    assert cut.share_used == pytest.approx(0.994)
    for name, value in truth.items():
        ci = getattr(cut, f"{name}_ci95")
        assert abs(getattr(cut, name) - value) < ci  # the truth inside the interval
        assert abs(getattr(cut, name) - getattr(whole, name)) < ci  # and the whole recording's fit
    assert whole.gaps == () and whole.share_used == 1.0


def test_a_recording_that_is_mostly_gaps_is_refused_saying_how_much_was_left() -> None:
    # Joint states at 50 Hz over 10 s, of which six stretches of 0.2 s arrived: 60 states, 1.2 s; central
    # differences leave 8 rows in each stretch of 10 (its ends have no neighbour), 48 rows < 50.
    t, q, qd, u = sampled_sine(50.0, 1.0, seconds=10.0)
    keep = np.zeros(t.size, dtype=bool)
    for start in (0.0, 2.0, 4.0, 6.0, 8.0, 9.8):
        keep |= (t >= start - 1e-9) & (t < start + 0.2 - 1e-9)
    assert keep.sum() == 60
    grid, *columns = resample_uniform(t[keep], q[keep], qd[keep], u[keep])
    with pytest.raises(IdentificationError, match=r"only 1\.2 s of 10 s usable after cutting 5 gaps: need at "
                                                  r"least 50 samples inside unbroken stretches, 48 left") as info:
        fit_plant(grid, *columns, joint_type="prismatic", acceleration="central")
    assert info.value.field == "samples" and info.value.value == 48


def test_a_differencing_rule_other_than_forward_or_central_is_refused() -> None:
    t, q, qd, u = sampled_sine(1000.0, 1.0, seconds=2.0)
    with pytest.raises(IdentificationError, match="forward or central"):
        fit_plant(t, q, qd, u, joint_type="prismatic", acceleration="backward")


def test_a_50_hz_sample_holding_a_one_cycle_kick_is_left_out_with_its_neighbours() -> None:
    # A tenth of the samples hold a derivative kick of ±5 N (one cycle's effort, which the 20 ms between
    # samples does not show). Least squares would bend to them; they are left out (and the rows whose
    # difference takes their velocity), and the fit is within the central difference's bound again.
    t, q, qd, u = sampled_sine(50.0, 1.0)
    rng = np.random.default_rng(5)
    kicked = rng.random(t.size) < 0.1
    u = u + np.where(kicked, rng.choice([-5.0, 5.0], t.size), 0.0)
    fit = fit_plant(t, q, qd, u, joint_type="prismatic", acceleration="central", max_shift_cycles=0)
    moving = np.abs(qd) > 0.1 * np.abs(qd).max()
    assert fit.outliers == np.sum(kicked & moving)
    assert fit.left_out > fit.outliers and fit.r_squared > 0.999
    bound = (2 * np.pi * 3.1 * 0.02) ** 2 / 6
    assert fit.inertia == pytest.approx(2.5, rel=bound) and fit.damping == pytest.approx(7.0, rel=bound)


def test_a_loops_jittered_stamps_give_its_period_and_each_state_its_cycle() -> None:
    # A 1 kHz ros_control loop's joint states (tests/identification/joint_state_stream.py): stamps late by
    # 0.33 ms on average, the cycle after a late one skipped when the publishing thread has not woken yet,
    # and the thread stalled for 20 ms at 4 s. The steps left are longer than the period (a skipped
    # cycle is one whose step would have been short); the stamps' phases are not.
    published, stamps = joint_state_stream(13000, 0.001, 1000.0, Timing(stalls=((4.0, 0.020),)),
                                           np.random.default_rng(3))
    assert np.median(np.diff(stamps)) > 1.02e-3
    assert stamp_period(stamps) == pytest.approx(0.001, rel=1e-5)
    # Every state on its cycle's grid point (its values are the cycle's: not interpolated), the grid
    # following the stamps, a lost cycle a gap. Whether a late stamp next to a lost cycle is the cycle
    # before the loss or after it the stamps cannot say: such a state may be one cycle off (the row whose
    # difference spans the loss is then off the fit, see the outlier test above); no other.
    grid, cycle = resample_uniform(stamps, published, cycles=True)
    assert np.array_equal(cycle, published)
    assert np.max(np.abs(grid - stamps)) < 0.003
    on_grid = np.round((grid - grid[0]) / 0.001).astype(int)
    off = on_grid - published - np.median(on_grid - published)
    lost = np.diff(published) > 1
    assert np.max(np.abs(off)) <= 1 and np.mean(off != 0) < 2 * np.mean(lost)
    split = stretches(grid)
    assert len(split.gaps) == pytest.approx(np.sum(lost), rel=0.05)
    assert [round(at, 2) for at, length in split.gaps if length > 0.010] == [4.0]

"""Response analysis against exact analytic second-order and sinusoidal signals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import signal
from scipy.optimize import brentq

from jointctl.errors import JointCtlError
from jointctl.metrics.response import (
    AnalysisError,
    SineResponse,
    StepResponse,
    first_order_frequency_response,
    second_order_frequency_response,
    second_order_theory,
    sinusoid_response,
    step_response,
)

DT = 1e-3


def second_order_step(
    tau: np.ndarray, y0: float, yf: float, wn: float, zeta: float, zero_s: float = 0.0
) -> np.ndarray:
    """Exact step response y0 -> yf of (zero_s*s*wn^2 + wn^2)/(s^2 + 2 zeta wn s + wn^2).

    ``tau`` is time since the step [s]; ``zero_s`` = c/k adds a loop zero
    (derivative of the error in a PD loop).
    """
    sigma = zeta * wn
    wd = wn * math.sqrt(1.0 - zeta**2)
    env = np.exp(-sigma * tau)
    step = yf - y0
    y = yf - step * env * (np.cos(wd * tau) + sigma / wd * np.sin(wd * tau))
    return y + zero_s * step * wn**2 / wd * env * np.sin(wd * tau)


def record(
    wn: float,
    zeta: float,
    *,
    c0: float = -0.2,
    c1: float = -0.5,
    offset: float = 0.01,
    step_time: float = 0.5,
    zero_s: float = 0.0,
    duration: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """1 kHz record of a command step c0 -> c1 at step_time, response at rest before it.

    The response settles at command + offset (a steady offset such as gravity
    against a P loop). The default duration lets the tail decay to ~1e-10.
    """
    if duration is None:
        duration = step_time + 25.0 / (zeta * wn)
    t = np.arange(int(round(duration / DT))) * DT
    command = np.where(t < step_time, c0, c1)
    tau = np.clip(t - step_time, 0.0, None)
    y = second_order_step(tau, c0 + offset, c1 + offset, wn, zeta, zero_s)
    return t, command, np.where(t < step_time, c0 + offset, y)


def analytic_settling_and_rise(
    wn: float, zeta: float, band: float = 0.02, zero_s: float = 0.0
) -> tuple[float, float]:
    """2 % settling time and 10-90 % rise time of the exact unit step curve [s].

    Bracketed on a 10 us grid, then solved to machine precision with brentq.
    """
    def u(tau: float) -> float:
        return float(second_order_step(np.asarray(tau), 0.0, 1.0, wn, zeta, zero_s))

    grid = np.arange(0.0, 10.0 / (zeta * wn), 1e-5)
    err = second_order_step(grid, 0.0, 1.0, wn, zeta, zero_s) - 1.0
    i = int(np.flatnonzero(np.abs(err) > band)[-1])
    level = math.copysign(band, err[i])
    settle = brentq(lambda x: u(x) - 1.0 - level, grid[i], grid[i + 1], xtol=1e-12)
    rise = []
    for frac in (0.1, 0.9):
        j = int(np.argmax(err + 1.0 >= frac))
        rise.append(brentq(lambda x: u(x) - frac, grid[j - 1], grid[j], xtol=1e-12))
    return settle, rise[1] - rise[0]


def overshoot_theory(zeta: float) -> float:
    return 100.0 * math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta**2))


# --------------------------------------------------------------------------- step


@pytest.mark.parametrize(
    ("wn", "zeta", "c0", "c1"),
    [
        (19.9, 0.249, -0.2, -0.5),  # the chapter's step, downwards
        (19.9, 0.249, 0.0, 0.3),  # same, upwards
        (10.0, 0.05, 0.1, 0.4),  # lightly damped, many peaks
        (30.0, 0.7, 0.5, 0.2),  # two detectable peaks
        (30.0, 0.8, 0.0, 1.0),  # a single detectable peak: overshoot-formula guess
    ],
)
def test_step_fit_recovers_analytic_second_order(wn, zeta, c0, c1):
    offset = 0.01
    t, command, position = record(wn, zeta, c0=c0, c1=c1, offset=offset)
    result = step_response(t, command, position, step_time_s=0.5)

    assert result.natural_frequency_rad_s == pytest.approx(wn, rel=5e-3)
    assert result.damping_ratio == pytest.approx(zeta, rel=5e-3)
    assert result.overshoot_pct == pytest.approx(overshoot_theory(zeta), abs=0.5)
    settle, rise = analytic_settling_and_rise(wn, zeta)
    assert result.settling_time_s == pytest.approx(settle, abs=2e-3)
    assert result.rise_time_s == pytest.approx(rise, abs=1e-3)
    wd = wn * math.sqrt(1 - zeta**2)
    assert result.peak_time_s == pytest.approx(math.pi / wd, abs=1e-3)
    assert result.steady_state_error == pytest.approx(-offset, abs=1e-8)
    assert result.initial_value == pytest.approx(c0 + offset)
    assert result.final_value == pytest.approx(c1 + offset, abs=1e-8)
    assert result.fit_rms_error < 1e-9


def test_step_fit_is_near_exact_on_noise_free_data():
    t, command, position = record(19.9, 0.249)
    result = step_response(t, command, position, step_time_s=0.5)
    assert result.natural_frequency_rad_s == pytest.approx(19.9, rel=1e-9)
    assert result.damping_ratio == pytest.approx(0.249, rel=1e-9)
    # Default window: 8 envelope time constants, 8 / (0.249 * 19.9) = 1.614 s.
    assert result.fit_window_s == pytest.approx(8 / (0.249 * 19.9), abs=0.1)


def test_step_fit_with_noise():
    wn, zeta, noise = 19.9, 0.249, 1e-4  # 0.03 % of the 0.3 m step
    t, command, position = record(wn, zeta)
    rng = np.random.default_rng(20240601)
    noisy = position + rng.normal(0.0, noise, t.size)
    result = step_response(t, command, noisy, step_time_s=0.5)

    assert result.natural_frequency_rad_s == pytest.approx(wn, rel=5e-3)
    assert result.damping_ratio == pytest.approx(zeta, rel=5e-3)
    assert result.overshoot_pct == pytest.approx(overshoot_theory(zeta), abs=0.5)
    settle, _ = analytic_settling_and_rise(wn, zeta)
    # Noise moves the band crossing by about noise / slope (~1 ms at 1e-4 m).
    assert result.settling_time_s == pytest.approx(settle, abs=5e-3)
    assert result.steady_state_error == pytest.approx(-0.01, abs=1e-4)
    assert result.fit_rms_error == pytest.approx(noise, rel=0.1)


def test_step_fit_sees_the_poles_through_a_loop_zero():
    # PD loop with derivative on the error: the zero raises the overshoot above
    # the pole-only formula, but the fitted wn and zeta are still the poles'.
    wn, zeta, zero_s = 19.9, 0.249, 0.02
    t, command, position = record(wn, zeta, zero_s=zero_s)
    result = step_response(t, command, position, step_time_s=0.5)
    assert result.natural_frequency_rad_s == pytest.approx(wn, rel=1e-6)
    assert result.damping_ratio == pytest.approx(zeta, rel=1e-6)
    assert result.overshoot_pct > overshoot_theory(zeta) + 2.0
    settle, _ = analytic_settling_and_rise(wn, zeta, zero_s=zero_s)
    assert result.settling_time_s == pytest.approx(settle, abs=2e-3)


def test_a_response_carried_past_its_final_value_by_the_laws_zero_is_not_called_critically_damped():
    # PD loop with the derivative on the error, its poles real (m 1.01 kg, b + d = 80 N·s/m, p 400 N/m:
    # ζ of the poles 1.98): (d s + p)/(m s² + (b + d) s + p) overshoots 4.85 % on the zero alone. A damped
    # sinusoid fitted to it runs to ζ -> 1 (0.9999995 before), which says "no overshoot"; the figures are those
    # of the second-order loop that overshoots as much and peaks as late, and the note says why.
    m, c, p, d = 1.01, 80.0, 400.0, 80.0
    loop = signal.lti([d, p], [m, c, p])
    t = np.arange(0, 3.0, DT)
    tau = t[t >= 0.5] - 0.5
    _, y = signal.step(loop, T=tau)
    position = np.concatenate([np.zeros(np.count_nonzero(t < 0.5)), 0.01 * y])
    command = np.where(t < 0.5, 0.0, 0.01)
    result = step_response(t, command, position, step_time_s=0.5)
    assert 4.5 < result.overshoot_pct < 5.2
    zeta = -math.log(result.overshoot_pct / 100) / math.hypot(math.pi, math.log(result.overshoot_pct / 100))
    assert result.damping_ratio == pytest.approx(zeta, rel=1e-9)  # 0.69: what 4.85 % means
    wn = math.pi / (result.peak_time_s * math.sqrt(1 - zeta**2))
    assert result.natural_frequency_rad_s == pytest.approx(wn, rel=1e-9)
    assert "does not oscillate" in result.fit_note and "zero" in result.fit_note


def test_step_with_accumulated_time_and_step_between_samples():
    # Time stamps from repeated addition (not exact multiples) and a step time
    # that is not on a sample.
    wn, zeta, step_time = 19.9, 0.249, 0.5004
    t = np.cumsum(np.full(4000, DT)) - DT
    command = np.where(t < step_time, -0.2, -0.5)
    tau = np.clip(t - step_time, 0.0, None)
    position = np.where(t < step_time, -0.2, second_order_step(tau, -0.2, -0.5, wn, zeta))
    result = step_response(t, command, position, step_time_s=step_time)
    assert result.natural_frequency_rad_s == pytest.approx(wn, rel=1e-6)
    assert result.damping_ratio == pytest.approx(zeta, rel=1e-6)


def test_step_explicit_fit_window():
    t, command, position = record(19.9, 0.249)
    result = step_response(t, command, position, step_time_s=0.5, fit_window_s=0.4)
    assert result.fit_window_s == pytest.approx(0.4, abs=DT)
    assert result.damping_ratio == pytest.approx(0.249, rel=1e-6)


def test_step_settle_band_and_unsettled_record():
    t, command, position = record(19.9, 0.249)
    wide = step_response(t, command, position, step_time_s=0.5, settle_band=0.05)
    narrow = step_response(t, command, position, step_time_s=0.5)
    assert wide.settling_time_s < narrow.settling_time_s
    # A band far below the tail's residual oscillation is never reached.
    wn, zeta = 10.0, 0.02
    t, command, position = record(wn, zeta, duration=6.0)
    result = step_response(t, command, position, step_time_s=0.5, settle_band=0.001)
    assert result.settling_time_s is None
    assert json.loads(json.dumps(result.as_dict()))["settling_time_s"] is None


def test_step_result_is_frozen_and_json_ready():
    t, command, position = record(19.9, 0.249)
    result = step_response(t, command, position, step_time_s=0.5)
    assert isinstance(result, StepResponse)
    with pytest.raises(AttributeError):
        result.damping_ratio = 1.0  # type: ignore[misc]
    d = result.as_dict()
    assert set(d) == {
        "natural_frequency_rad_s",
        "damping_ratio",
        "overshoot_pct",
        "settling_time_s",
        "steady_state_error",
        "rise_time_s",
        "peak_time_s",
        "initial_value",
        "final_value",
        "fit_window_s",
        "fit_rms_error",
        "fit_note",
        "moving_at_step",
        "motion_at_step",
        "not_settled",
    }
    assert d.pop("fit_note") is None and d.pop("not_settled") is None  # fitted, settled
    assert d.pop("moving_at_step") is False
    assert all(type(v) is float for v in d.values())
    assert json.loads(json.dumps(d, allow_nan=False)) == d


def test_step_errors():
    t, command, position = record(19.9, 0.249)

    with pytest.raises(ValueError, match="no step in command.*it is constant"):
        step_response(t, np.full_like(t, -0.2), position, step_time_s=0.5)
    with pytest.raises(ValueError, match="no step in command.*changes at t=0.5 s"):
        step_response(t, command, position, step_time_s=0.3)  # wrong step time
    with pytest.raises(ValueError, match="inside the record"):
        step_response(t, command, position, step_time_s=t[-1] + 1.0)
    with pytest.raises(ValueError, match="inside the record"):
        step_response(t, command, position, step_time_s=0.0)

    short = t < 0.51
    with pytest.raises(ValueError, match="too short"):
        step_response(t[short], command[short], position[short], step_time_s=0.5)
    short = t < 0.54  # enough samples after the step, but the tail precedes it
    with pytest.raises(ValueError, match="too short.*last 10 %"):
        step_response(t[short], command[short], position[short], step_time_s=0.5)

    twice = command.copy()
    twice[t >= 2.0] = 0.0
    with pytest.raises(ValueError, match="changes again at t=2"):
        step_response(t, twice, position, step_time_s=0.5)

    with pytest.raises(ValueError, match="did not follow the step"):
        step_response(t, command, np.full_like(t, -0.2), step_time_s=0.5)

    # Overdamped (zeta = 5/3) response: nothing to fit an oscillation to. The figures read off the
    # samples stand (the 10-90 % rise of the slow pole, ln 9 / 5 s, as it dominates), ωn and ζ are
    # NaN and the note says why.
    tau = np.clip(t - 0.5, 0.0, None)
    p1, p2 = -5.0, -45.0  # poles of s^2 + 50 s + 225: wn = 15, zeta = 5/3
    overdamped = -0.2 - 0.3 * (1 + (p2 * np.exp(p1 * tau) - p1 * np.exp(p2 * tau)) / (p1 - p2))
    flat = step_response(t, command, overdamped, step_time_s=0.5)
    assert math.isnan(flat.natural_frequency_rad_s) and math.isnan(flat.damping_ratio)
    assert "no overshoot detected" in flat.fit_note and flat.overshoot_pct == pytest.approx(0.0, abs=1e-6)
    assert flat.rise_time_s == pytest.approx(math.log(9) / 5, rel=0.03)
    assert flat.final_value == pytest.approx(-0.5, abs=1e-4)
    assert step_response(t, command, position, step_time_s=0.5).fit_note is None

    with pytest.raises(ValueError, match="samples but time_s has"):
        step_response(t, command[:-1], position, step_time_s=0.5)
    with pytest.raises(ValueError, match="increase strictly"):
        step_response(t[::-1], command, position, step_time_s=0.5)
    with pytest.raises(ValueError, match="NaN"):
        step_response(t, command, np.where(t > 1.0, np.nan, position), step_time_s=0.5)


def test_analysis_error_is_a_jointctl_error():
    with pytest.raises(JointCtlError) as info:
        step_response([0.0, 1.0], [0.0, 0.0], [0.0, 0.0], step_time_s=0.5)
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, AnalysisError)
    assert info.value.code == "analysis"


# --------------------------------------------------------------------------- sine


def sine(t: np.ndarray, f: float, amp: float, phase_rad: float, offset: float = 0.0) -> np.ndarray:
    return offset + amp * np.sin(2 * math.pi * f * t + phase_rad)


@pytest.mark.parametrize(
    ("lag_deg", "expected"),
    [(30.0, 30.0), (-20.0, -20.0), (170.0, 170.0), (200.0, -160.0), (-180.0, 180.0)],
)
def test_sine_fit_ratio_and_lag(lag_deg, expected):
    f = 2.0
    t = np.arange(5500) * DT
    reference = sine(t, f, 0.1, 0.3, offset=0.05)
    # Response: lagged, scaled, offset, plus a 3rd harmonic the fit must ignore.
    response = sine(t, f, 0.08, 0.3 - math.radians(lag_deg), offset=-0.01)
    response += sine(t, 3 * f, 0.01, 1.0)
    result = sinusoid_response(t, reference, response, frequency_hz=f, start_s=1.0)

    assert isinstance(result, SineResponse)
    assert result.periods_used == 9  # [1.0, 5.5) s holds 9 whole 0.5 s periods
    assert result.amplitude_ratio == pytest.approx(0.8, rel=1e-9)
    assert result.phase_lag_deg == pytest.approx(expected, abs=1e-7)
    assert result.reference_amplitude == pytest.approx(0.1, rel=1e-9)
    assert result.response_amplitude == pytest.approx(0.08, rel=1e-9)
    assert result.reference_offset == pytest.approx(0.05, abs=1e-12)
    assert result.response_offset == pytest.approx(-0.01, abs=1e-12)
    d = result.as_dict()
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    assert d["periods_used"] == 9


@pytest.mark.parametrize("f", [1.0, 2.5, 3.0, 7.0])
def test_sine_staircase_reference_reports_the_fundamental(f):
    """A 100 Hz sample-and-hold of a sine lags by half a hold period at the fundamental.

    Continuous time: pi f / 100 rad, amplitude sinc. Sampled at 1 kHz the ten
    held samples 0..9 ms are centred on 4.5 ms, so the exact discrete lag is
    2 pi f * 4.5 ms: half a 1 ms sample less than the continuous value.
    """
    t = np.arange(6000) * DT
    hold = 0.01
    staircase = 0.2 * np.sin(2 * math.pi * f * np.floor(t / hold + 1e-9) * hold)
    smooth = 0.2 * np.sin(2 * math.pi * f * t)
    # The staircase as the "response" of the smooth sine: its lag is the hold's.
    result = sinusoid_response(t, smooth, staircase, frequency_hz=f, start_s=0.5)

    w_dt = 2 * math.pi * f * DT
    discrete_lag = math.degrees(w_dt * 4.5)
    discrete_ratio = math.sin(5 * w_dt) / (10 * math.sin(w_dt / 2))
    # Exact when a whole period is a whole number of holds (f = 1, 2.5 Hz);
    # otherwise the period is not a whole number of samples and a little of
    # the staircase's harmonics leaks in.
    exact = (1.0 / f / hold).is_integer()
    assert result.phase_lag_deg == pytest.approx(discrete_lag, abs=1e-9 if exact else 0.05)
    assert result.amplitude_ratio == pytest.approx(discrete_ratio, abs=1e-12 if exact else 1e-3)
    continuous_lag = math.degrees(math.pi * f * hold)
    half_sample = math.degrees(math.pi * f * DT)
    assert abs(result.phase_lag_deg - continuous_lag) <= half_sample + (1e-9 if exact else 0.05)
    assert result.amplitude_ratio == pytest.approx(np.sinc(f * hold), abs=1e-3)

    # The other way round, the smooth response "leads" the staircase reference.
    back = sinusoid_response(t, staircase, smooth, frequency_hz=f, start_s=0.5)
    assert back.phase_lag_deg == pytest.approx(-result.phase_lag_deg, abs=1e-9)


def test_sine_matches_simulated_mass_spring_damper():
    m, k, b = 1.0, 396.0, 9.9  # wn = 19.9 rad/s, zeta = 0.249
    f = 2.5
    t = np.arange(8000) * DT
    u = 0.1 * np.sin(2 * math.pi * f * t)
    _, y, _ = signal.lsim(([k], [m, b, k]), u, t)
    result = sinusoid_response(t, u, y, frequency_hz=f, start_s=3.0)
    ratio, lag = second_order_frequency_response(m, k, b, 2 * math.pi * f)
    assert result.amplitude_ratio == pytest.approx(ratio, rel=1e-4)
    assert result.phase_lag_deg == pytest.approx(lag, abs=0.01)


def test_sine_errors():
    t = np.arange(1000) * DT
    x = np.sin(2 * math.pi * 2.0 * t)
    with pytest.raises(ValueError, match="at least one period"):
        sinusoid_response(t, x, x, frequency_hz=2.0, start_s=0.6)
    with pytest.raises(ValueError, match="positive"):
        sinusoid_response(t, x, x, frequency_hz=0.0, start_s=0.0)
    with pytest.raises(ValueError, match="Nyquist"):
        sinusoid_response(t, x, x, frequency_hz=600.0, start_s=0.0)
    with pytest.raises(ValueError, match="no component"):
        sinusoid_response(t, np.full_like(t, 0.3), x, frequency_hz=2.0, start_s=0.0)
    with pytest.raises(ValueError, match="samples but time_s has"):
        sinusoid_response(t, x, x[:10], frequency_hz=2.0, start_s=0.0)


# --------------------------------------------------------------------------- theory


def test_second_order_theory():
    theory = second_order_theory(1.0, 19.9**2, 2 * 0.249 * 19.9)
    assert theory["natural_frequency_rad_s"] == pytest.approx(19.9)
    assert theory["damping_ratio"] == pytest.approx(0.249)
    assert theory["overshoot_pct"] == pytest.approx(overshoot_theory(0.249))
    assert theory["damped_frequency_rad_s"] == pytest.approx(19.9 * math.sqrt(1 - 0.249**2))
    over = second_order_theory(2.0, 100.0, 100.0)
    assert over["damping_ratio"] > 1 and over["overshoot_pct"] == 0.0
    with pytest.raises(ValueError, match="mass_kg"):
        second_order_theory(0.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="stiffness"):
        second_order_theory(1.0, -1.0, 1.0)


def test_second_order_frequency_response():
    m, k, b = 2.0, 800.0, 16.0  # wn = 20, zeta = 0.2
    ratio, lag = second_order_frequency_response(m, k, b, 20.0)
    assert isinstance(ratio, float) and isinstance(lag, float)
    assert ratio == pytest.approx(1 / (2 * 0.2))
    assert lag == pytest.approx(90.0)
    ratio, lag = second_order_frequency_response(m, k, b, np.array([0.0, 1e4]))
    assert ratio[0] == pytest.approx(1.0) and lag[0] == pytest.approx(0.0)
    assert ratio[1] < 1e-4 and lag[1] == pytest.approx(180.0, abs=0.1)


def test_first_order_frequency_response():
    m, kv, b = 2.0, 30.0, 10.0
    corner = (kv + b) / m
    ratio, lag = first_order_frequency_response(m, kv, b, corner)
    assert ratio == pytest.approx(kv / (kv + b) / math.sqrt(2))
    assert lag == pytest.approx(45.0)
    ratio, lag = first_order_frequency_response(m, kv, b, np.array([0.0]))
    assert ratio[0] == pytest.approx(kv / (kv + b)) and lag[0] == 0.0
    with pytest.raises(ValueError, match="gain"):
        first_order_frequency_response(m, 0.0, b, 1.0)


# --------------------------------------------------------------------------- settled, and moving at the step


def envelope(amplitude: float, wn: float, zeta: float, tau: float) -> float:
    """Largest |y - y_final| [m] the free second-order motion x(0) = amplitude, x'(0) = 0 can still
    reach ``tau`` [s] later: amplitude·exp(-ζωn·tau)/√(1 - ζ²)."""
    return amplitude * math.exp(-zeta * wn * tau) / math.sqrt(1 - zeta**2)


def test_a_response_still_ringing_in_its_last_tenth_has_no_steady_state():
    # ζ 0.05, ωn 10: 3 s of record; the last 10 % starts 2.2 s after the step, where the envelope is
    # still 0.3·exp(-1.1)/√(1 - ζ²) = 0.10 m: 16 times the ±2 % band (0.006 m).
    wn, zeta = 10.0, 0.05
    t, command, position = record(wn, zeta, duration=3.0)
    tail_start = t[-int(math.ceil(0.1 * t.size))]
    assert envelope(0.3, wn, zeta, tail_start - 0.5) > 10 * 0.02 * 0.3
    result = step_response(t, command, position, step_time_s=0.5)
    for claim in ("final_value", "steady_state_error", "overshoot_pct", "rise_time_s", "settling_time_s"):
        assert getattr(result, claim) is None, claim
    assert "not settled" in result.not_settled and "2 %" in result.not_settled
    # The fit needs no final value: it still recovers the loop.
    assert result.natural_frequency_rad_s == pytest.approx(wn, rel=5e-3)
    assert result.damping_ratio == pytest.approx(zeta, rel=5e-3)
    assert result.initial_value == pytest.approx(-0.19)
    assert json.loads(json.dumps(result.as_dict(), allow_nan=False))["final_value"] is None


def test_a_response_that_leaves_the_band_inside_its_last_tenth_has_not_settled():
    # The chapter's loop, the record cut so that the 2 % settling time falls inside its last 10 %:
    # the final value would be a mean over samples outside the band.
    wn, zeta = 19.9, 0.249
    settle, _ = analytic_settling_and_rise(wn, zeta)
    duration = (0.5 + settle) / 0.95  # the last tenth starts 0.05·duration before the settling time
    t, command, position = record(wn, zeta, duration=duration)
    assert step_response(t, command, position, step_time_s=0.5).not_settled is not None
    t, command, position = record(wn, zeta)
    settled = step_response(t, command, position, step_time_s=0.5)
    assert settled.not_settled is None and settled.final_value == pytest.approx(-0.49, abs=1e-8)


def free_motion_then_step(wn: float, zeta: float, sag: float, step_time: float, duration: float = 4.0):
    """The chapter's loop released at t = 0 ``sag`` [m] above its rest at -0.2 m (as gravity leaves
    a P loop started where it stands), its command stepping to -0.5 m at ``step_time`` [s]; the
    linear loop superposes the free motion and the step."""
    t = np.arange(int(round(duration / DT))) * DT
    command = np.where(t < step_time, -0.2, -0.5)
    free = second_order_step(t, -0.2 + sag, -0.2, wn, zeta)
    tau = np.clip(t - step_time, 0.0, None)
    stepped = second_order_step(tau, 0.0, -0.3, wn, zeta)
    return t, command, np.where(t < step_time, free, free + stepped)


@pytest.mark.parametrize("step_time, moving", [(0.1, True), (0.5, False)])
def test_a_response_still_moving_when_its_step_comes_is_flagged(step_time, moving):
    # Released 24.8 mm from rest (m·g/Kp of the 1-DOF robot), the loop's free motion has the
    # amplitude sag·exp(-ζωn·t)/√(1 - ζ²) at t: 15.6 mm at 0.1 s (beyond the ±2 % band of the
    # 0.3 m step, 6 mm), 2.1 mm at 0.5 s (within it).
    wn, zeta, sag = 19.9, 0.249, 0.0248
    t, command, position = free_motion_then_step(wn, zeta, sag, step_time)
    result = step_response(t, command, position, step_time_s=step_time)
    assert result.motion_at_step == pytest.approx(envelope(sag, wn, zeta, step_time), rel=1e-3)
    assert result.moving_at_step is moving
    assert (envelope(sag, wn, zeta, step_time) > 0.02 * 0.3) is moving


def test_a_first_order_drift_at_the_step_is_motion_too():
    # No oscillation after the step (a first-order loop, time constant 0.1 s): the motion before it
    # is a decay with the time constant the step's 10-90 % rise gives (rise / ln 9).
    t = np.arange(3000) * DT
    command = np.where(t < 0.5, -0.2, -0.5)
    tau_c = 0.1
    drift = 0.05 * np.exp(-t / tau_c)  # 0.05·exp(-5) = 0.34 mm left at the step
    position = -0.2 + drift + np.where(t < 0.5, 0.0, -0.3 * (1 - np.exp(-np.clip(t - 0.5, 0, None) / tau_c)))
    result = step_response(t, command, position, step_time_s=0.5)
    assert math.isnan(result.damping_ratio)
    assert result.motion_at_step == pytest.approx(0.05 * math.exp(-0.5 / tau_c), rel=0.01)
    assert result.moving_at_step is False
    early = step_response(t, np.where(t < 0.1, -0.2, -0.5), -0.2 + drift + np.where(
        t < 0.1, 0.0, -0.3 * (1 - np.exp(-np.clip(t - 0.1, 0, None) / tau_c))), step_time_s=0.1)
    assert early.motion_at_step == pytest.approx(0.05 * math.exp(-1.0), rel=0.01) and early.moving_at_step

"""Figures of merit read off recorded joint signals.

Pure numpy/scipy: every function takes 1-D arrays sampled at a uniform
period (seconds, SI units throughout) and returns a small frozen dataclass
whose :meth:`as_dict` is ready for ``json.dumps``.

* :func:`step_response` -- natural frequency and damping ratio from a
  nonlinear least-squares fit of the underdamped second-order step response,
  plus overshoot, rise, peak and settling times and the steady-state error
  read directly from the samples (those that need a final value only when the
  response settled), and whether the response was still moving when the step
  came.
* :func:`sinusoid_response` -- amplitude ratio and phase lag of a response to
  a sinusoidal reference, by linear least squares at the fundamental.
* :func:`second_order_theory`, :func:`second_order_frequency_response`,
  :func:`first_order_frequency_response` -- the textbook values to compare
  against (mass-spring-damper position loop, velocity loop).

Bad input (no step, record too short, no oscillation to fit...) raises
:class:`AnalysisError`, which is both a :class:`ValueError` and a
:class:`jointctl.errors.JointCtlError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import curve_fit

from jointctl.errors import JointCtlError

__all__ = [
    "AnalysisError",
    "SineResponse",
    "StepResponse",
    "first_order_frequency_response",
    "second_order_frequency_response",
    "second_order_theory",
    "sinusoid_response",
    "step_response",
]

FloatArray = NDArray[np.float64]

_MIN_POST_STEP_SAMPLES = 20
_INITIAL_VALUE_SAMPLES = 5  # samples just before the step averaged for y_initial
_ENVELOPE_TIME_CONSTANTS = 8.0  # default fit window: until exp(-8) of the envelope
#: Above this fitted ζ the envelope decays by more than exp(-8) within half a damped period (σ·π/ωd > 8): the
#: fitted motion does not oscillate within the window, and its textbook overshoot, exp(-πζ/√(1-ζ²)) < exp(-8)
#: (0.034 %), is below what the fit needs to run at all (0.1 % of the step).
_NO_OSCILLATION_ZETA = _ENVELOPE_TIME_CONSTANTS / math.hypot(math.pi, _ENVELOPE_TIME_CONSTANTS)


class AnalysisError(JointCtlError, ValueError):
    """A recorded signal cannot be analysed as asked (no step, too short, ...)."""

    code = "analysis"


class NoOscillation(AnalysisError):
    """A step response that does not overshoot: nothing for the second-order fit to fit."""


class _Result:
    """Mixin: JSON-ready dict of a dataclass of floats (None, ints and notes stay as they are)."""

    def as_dict(self) -> dict[str, float | int | str | None]:
        out: dict[str, float | int | str | None] = {}
        for f in fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if value is None or isinstance(value, (int, str)):
                out[f.name] = value
            else:
                out[f.name] = float(value)
        return out


@dataclass(frozen=True)
class StepResponse(_Result):
    """Figures of merit of a step response.

    **Settled.** The final value is the mean of the last 10 % of the record; it is a steady state
    only if the response stayed within the settling band (``settle_band`` of the step about that
    mean) over all of those samples. When it did not, the figures measured against the final
    value -- ``final_value``, ``steady_state_error``, ``overshoot_pct``, ``rise_time_s``,
    ``settling_time_s`` -- are None and ``not_settled`` says why; the fitted ωn and ζ need no final
    value (the fit's own asymptote is a free parameter) and stand.

    Attributes:
        natural_frequency_rad_s: omega_n of the fitted second-order response [rad/s].
        damping_ratio: zeta of the fitted second-order response [-].
        overshoot_pct: peak excursion beyond ``final_value`` in the direction of
            the step, as percent of the measured step size (0 if none) [%].
        settling_time_s: time after the step from which |y - final_value| stays
            within ``settle_band * |step size|`` [s].
        steady_state_error: ``command_final - final_value`` [m, or rad for a
            revolute joint].
        rise_time_s: 10 % to 90 % rise time of the measured step [s].
        peak_time_s: time from the step to the overshoot peak [s] (to the sample
            furthest in the step direction if there is no overshoot).
        initial_value: response just before the step (mean of the last 5 samples)
            [m or rad].
        final_value: mean of the last 10 % of the record [m or rad].
        fit_window_s: length of the record after the step used by the fit [s].
        fit_rms_error: RMS residual of the fit [m or rad].
        moving_at_step: whether ``motion_at_step`` exceeds ``settle_band`` of the
            commanded step (the settling band's width, taken from the command: the
            measured step carries the motion): the response had not come to rest when
            the step came, and the step's figures carry the rest of that motion (None
            when it could not be told).
        motion_at_step: amplitude of the motion before the step, at the step [m or
            rad]: the record before the step fitted, by linear least squares, with
            a rest plus the free motion of the loop the step revealed (the fitted
            damped oscillation; without one, a decay with the time constant of the
            step's 10-90 % rise, rise / ln 9), over at most 8 of its time constants;
            the oscillation's envelope (or the decay's distance from the rest) at
            the step. None with fewer than 3 samples before the step.
    """

    natural_frequency_rad_s: float
    damping_ratio: float
    overshoot_pct: float | None
    settling_time_s: float | None
    steady_state_error: float | None
    rise_time_s: float | None
    peak_time_s: float
    initial_value: float
    final_value: float | None
    fit_window_s: float
    fit_rms_error: float
    #: Why ωn and ζ are not the fitted oscillation's (None when they are): NaN for a response that does
    #: not overshoot (an overdamped loop, or ζ above about 0.9: no oscillation to fit); for a response
    #: that overshoots but whose fit does not oscillate (a zero of the loop carried it past its final
    #: value), those of the second-order loop that overshoots as much and peaks as late.
    fit_note: str | None = None
    moving_at_step: bool | None = None
    motion_at_step: float | None = None
    #: Why the figures that need a final value are None (None when the response settled).
    not_settled: str | None = None


@dataclass(frozen=True)
class SineResponse(_Result):
    """Gain and phase of a response to a sinusoidal reference, at the fundamental.

    Attributes:
        frequency_hz: the analysed frequency [Hz].
        amplitude_ratio: response amplitude / reference amplitude [-].
        phase_lag_deg: phase of the reference minus phase of the response,
            positive when the response lags, wrapped to (-180, 180] [deg].
        reference_amplitude: fitted amplitude of the reference [signal units].
        response_amplitude: fitted amplitude of the response [signal units].
        reference_offset: fitted mean of the reference [signal units].
        response_offset: fitted mean of the response [signal units].
        periods_used: whole periods in the fitted window.
    """

    frequency_hz: float
    amplitude_ratio: float
    phase_lag_deg: float
    reference_amplitude: float
    response_amplitude: float
    reference_offset: float
    response_offset: float
    periods_used: int


# --------------------------------------------------------------------------- helpers


def _signals(**named: ArrayLike) -> list[FloatArray]:
    """Convert to 1-D finite float arrays of one common length."""
    arrays: list[FloatArray] = []
    length: int | None = None
    for name, value in named.items():
        a = np.asarray(value, dtype=float)
        if a.ndim != 1:
            raise AnalysisError(f"{name} must be a 1-D array", value=a.shape)
        if length is not None and a.size != length:
            raise AnalysisError(
                f"{name} has {a.size} samples but time_s has {length}", value=a.size
            )
        if not np.all(np.isfinite(a)):
            raise AnalysisError(f"{name} contains NaN or infinite samples")
        length = a.size
        arrays.append(a)
    return arrays


def _sample_period(t: FloatArray) -> float:
    """Median sample period [s]; checks that time increases strictly."""
    if t.size < 2:
        raise AnalysisError("record too short: fewer than 2 samples", value=int(t.size))
    steps = np.diff(t)
    if np.any(steps <= 0):
        raise AnalysisError("time_s must increase strictly")
    return float(np.median(steps))


def _noise_std(y: FloatArray) -> float:
    """Robust white-noise standard deviation from sample-to-sample differences."""
    if y.size < 3:
        return 0.0
    d = np.diff(y)
    mad = float(np.median(np.abs(d - np.median(d))))
    return 1.4826 * mad / math.sqrt(2.0)


def _first_crossing(tau: FloatArray, u: FloatArray, level: float) -> float | None:
    """First time u reaches ``level`` (rising), linearly interpolated."""
    above = np.flatnonzero(u >= level)
    if above.size == 0:
        return None
    i = int(above[0])
    if i == 0:
        return float(tau[0])
    frac = (level - u[i - 1]) / (u[i] - u[i - 1])
    return float(tau[i - 1] + frac * (tau[i] - tau[i - 1]))


def _excursion_extrema(e: FloatArray, threshold: float) -> tuple[list[int], list[int]]:
    """Extremum index and sign of each excursion of ``e`` beyond +-threshold.

    Hysteresis: a new excursion starts only when ``e`` leaves the band on the
    other side, so noise around zero does not split half-cycles.
    """
    state = np.where(e > threshold, 1, np.where(e < -threshold, -1, 0))
    nz = np.flatnonzero(state)
    if nz.size == 0:
        return [], []
    signs = state[nz]
    starts = nz[np.r_[0, np.flatnonzero(np.diff(signs)) + 1]]
    ends = np.r_[starts[1:], e.size]
    idx: list[int] = []
    sgn: list[int] = []
    for start, end in zip(starts, ends):
        s = int(state[start])
        idx.append(int(start + np.argmax(s * e[start:end])))
        sgn.append(s)
    return idx, sgn


def _damped_model(
    tau: FloatArray, y_final: float, a: float, b: float, sigma: float, omega_d: float
) -> FloatArray:
    """y_final + exp(-sigma tau) (a cos(omega_d tau) + b sin(omega_d tau))."""
    env = np.exp(-sigma * tau)
    return y_final + env * (a * np.cos(omega_d * tau) + b * np.sin(omega_d * tau))


def _damped_jacobian(
    tau: FloatArray, y_final: float, a: float, b: float, sigma: float, omega_d: float
) -> FloatArray:
    env = np.exp(-sigma * tau)
    c = np.cos(omega_d * tau)
    s = np.sin(omega_d * tau)
    return np.column_stack(
        [
            np.ones_like(tau),
            env * c,
            env * s,
            -tau * env * (a * c + b * s),
            tau * env * (b * c - a * s),
        ]
    )


def _initial_guess(
    tau: FloatArray, e: FloatArray, step_abs: float, direction: float, noise: float
) -> tuple[float, float]:
    """First estimate of (sigma, omega_d) [1/s, rad/s] from the overshoot peaks.

    Uses the spacing of successive extrema of e = y - y_final (half the damped
    period) and the logarithmic decrement of their magnitudes; with a single
    detectable overshoot, the classic overshoot / peak-time formulas.
    """
    threshold = max(5.0 * noise, 1e-3 * step_abs)
    idx, sgn = _excursion_extrema(e, threshold)
    # Drop the initial excursion (before the first crossing of the final value)
    # and an extremum sitting on the last sample (truncated half-cycle).
    if idx and sgn[0] == -direction:
        idx, sgn = idx[1:], sgn[1:]
    if idx and idx[-1] == e.size - 1:
        idx, sgn = idx[:-1], sgn[:-1]
    if not idx:
        raise NoOscillation(
            "no overshoot detected after the step: the underdamped second-order fit "
            "needs an oscillating response (is the loop overdamped, or the record too short?)"
        )
    tp = tau[idx]
    amp = np.abs(e[idx])
    if len(idx) >= 2:
        k = np.arange(len(idx), dtype=float)
        half_period = float(np.polyfit(k, tp, 1)[0])
        omega_d = math.pi / half_period
        sigma = -float(np.polyfit(tp, np.log(amp), 1)[0])
        if sigma <= 0.0:
            sigma = 1e-3 * omega_d
        return sigma, omega_d
    ln_mp = math.log(min(float(amp[0]) / step_abs, 0.999))
    zeta = -ln_mp / math.sqrt(math.pi**2 + ln_mp**2)
    omega_d = math.pi / max(float(tp[0]), 1e-9)
    return zeta * omega_d / math.sqrt(1.0 - zeta**2), omega_d


# --------------------------------------------------------------------------- step


def step_response(
    time_s: ArrayLike,
    command: ArrayLike,
    position: ArrayLike,
    *,
    step_time_s: float,
    settle_band: float = 0.02,
    fit_window_s: float | None = None,
    ramp_s: float = 0.0,
) -> StepResponse:
    """Analyse the response ``position`` to a step of ``command`` at ``step_time_s``.

    Args:
        time_s: sample times [s], uniformly spaced.
        command: piecewise-constant command; its value just before
            ``step_time_s`` and its last value are the step's ends [m or rad].
        position: measured response [m or rad].
        step_time_s: time of the step [s].
        settle_band: half-width of the settling band as a fraction of the
            measured step size (0.02 = 2 %).
        fit_window_s: length of record after the step used by the fit [s];
            default: until the fitted envelope has decayed by exp(-8), using a
            first estimate from the peaks, or the end of the record.
        ramp_s: the command reaches its last value along a ramp of this many
            seconds from ``step_time_s`` (a step source's ``ramp_s``): its
            changes until then are the step's; times are still read from
            ``step_time_s`` (a short ramp delays the response by about half of it).

    The damping ratio and natural frequency come from a nonlinear least-squares
    fit of y = y_final + exp(-zeta wn tau) (a cos(wd tau) + b sin(wd tau)),
    wd = wn sqrt(1 - zeta^2), tau = t - step_time_s (equivalent to
    A exp(-zeta wn tau) cos(wd tau + phi)), so a loop zero or a small delay only
    changes a and b. Overshoot, rise, peak and settling times are read from the
    samples, relative to y_initial (just before the step) and y_final (mean of
    the last 10 % of the record).

    A fit whose oscillation the record cannot show (zeta above 0.93: its
    envelope falls by more than exp(-8) in half a damped period) while the
    samples overshoot is no description of that overshoot: the poles are (near)
    real and a zero of the loop -- the derivative on the error, whose step
    response is (d s + p)/(m s^2 + c s + p) -- carried the response past its
    final value (the fit runs to zeta -> 1 there). ``damping_ratio`` is then the
    zeta whose second-order step overshoots as much, -ln(Mp)/sqrt(pi^2 + ln(Mp)^2),
    ``natural_frequency_rad_s`` the wn that peaks at the measured peak time,
    pi/(tp sqrt(1 - zeta^2)), and ``fit_note`` says so with the fitted zeta.

    Raises:
        AnalysisError: the command has no step at ``step_time_s``, changes again
            later, the record is too short, or the response does not overshoot
            its final value by more than max(0.1 % of the step, 5 noise standard
            deviations) -- an overdamped loop, or zeta above about 0.9.
    """
    t, c, y = _signals(time_s=time_s, command=command, position=position)
    dt = _sample_period(t)
    if not 0.0 < settle_band < 1.0:
        raise AnalysisError("settle_band must be in (0, 1)", value=settle_band)
    eps = 1e-3 * dt
    pre = t < step_time_s - eps
    if not pre.any() or step_time_s > t[-1]:
        raise AnalysisError(
            f"step_time_s must lie inside the record ({t[0]:g} s, {t[-1]:g} s]",
            value=step_time_s,
        )
    post_idx = np.flatnonzero(~pre)
    if post_idx.size < _MIN_POST_STEP_SAMPLES:
        raise AnalysisError(
            f"record too short: {post_idx.size} samples after the step, "
            f"need at least {_MIN_POST_STEP_SAMPLES}",
            value=int(post_idx.size),
        )
    n_tail = max(1, int(math.ceil(0.1 * t.size)))
    if t[-n_tail] < step_time_s - eps:
        raise AnalysisError(
            "record too short: the last 10 % of the record (used for the final value) "
            "starts before the step",
            value=float(t[-1] - step_time_s),
        )

    c_scale = max(1.0, float(np.max(np.abs(c))))
    jumps = np.flatnonzero(np.abs(np.diff(c)) > 1e-12 * c_scale) + 1  # first sample of a new value
    near = (t[jumps] >= step_time_s - dt - eps) & (t[jumps] <= step_time_s + 2.0 * dt + eps)
    if not near.any():
        where = ", ".join(f"{x:g}" for x in t[jumps][:3])
        found = f"it changes at t={where} s" if where else "it is constant"
        raise AnalysisError(f"no step in command at step_time_s={step_time_s:g} s: {found}")
    later = jumps[t[jumps] > step_time_s + max(0.0, ramp_s) + 2.0 * dt + eps]
    if later.size:
        raise AnalysisError(
            f"command changes again at t={t[later[0]]:g} s after the step at {step_time_s:g} s; "
            "step_response needs the command held constant after the step (trim the record)",
        )
    c_initial = float(c[jumps[near][0] - 1])
    c_final = float(c[-1])
    if abs(c_final - c_initial) <= 1e-12 * c_scale:
        raise AnalysisError(f"no net step in command at step_time_s={step_time_s:g} s")

    y_initial = float(np.mean(y[pre][-_INITIAL_VALUE_SAMPLES:]))
    y_final = float(np.mean(y[-n_tail:]))
    step = y_final - y_initial
    noise = _noise_std(y[-n_tail:])
    if abs(step) <= max(10.0 * noise, 1e-12 * max(1.0, abs(y_final))):
        raise AnalysisError(
            f"the response did not follow the step: it moved {step:g} "
            f"(noise level {noise:g})",
        )
    step_abs = abs(step)
    direction = 1.0 if step > 0 else -1.0

    tau = t[post_idx] - step_time_s
    yp = y[post_idx]
    e = yp - y_final

    # Read off the samples.
    k_peak = int(np.argmax(direction * e))
    overshoot_pct = 100.0 * max(0.0, float(direction * e[k_peak])) / step_abs
    peak_time_s = float(tau[k_peak])
    u = direction * (yp - y_initial) / step_abs
    t10 = _first_crossing(tau, u, 0.1)
    t90 = _first_crossing(tau, u, 0.9)
    if t10 is None or t90 is None:
        raise AnalysisError("the response never reaches 90 % of the step")
    band = settle_band * step_abs
    outside = np.flatnonzero(np.abs(e) > band)
    settling_time_s: float | None
    if outside.size == 0:
        settling_time_s = float(tau[0])
    elif outside[-1] == e.size - 1:
        settling_time_s = None
    else:
        i = int(outside[-1])
        level = math.copysign(band, e[i])
        frac = (e[i] - level) / (e[i] - e[i + 1])
        settling_time_s = float(tau[i] + frac * (tau[i + 1] - tau[i]))
    not_settled = _not_settled(t[-n_tail:], y[-n_tail:] - y_final, band, settle_band)
    read_off = {"overshoot_pct": overshoot_pct, "settling_time_s": settling_time_s,
                "steady_state_error": c_final - y_final, "rise_time_s": t90 - t10, "final_value": y_final}
    if not_settled is not None:
        read_off = dict.fromkeys(read_off)
    read_off.update(peak_time_s=peak_time_s, initial_value=y_initial, not_settled=not_settled)

    def motion(basis) -> dict[str, float | bool | None]:
        """``motion_at_step`` and ``moving_at_step`` from the loop's free motion ``basis``."""
        amplitude = _motion_at_step(t[pre] - step_time_s, y[pre], basis)
        limit = settle_band * abs(c_final - c_initial)
        return {"motion_at_step": amplitude, "moving_at_step": None if amplitude is None else amplitude > limit}

    # Fit the damped oscillation (none to fit without an overshoot: the read-off figures stand alone).
    try:
        sigma0, omega_d0 = _initial_guess(tau, e, step_abs, direction, noise)
    except NoOscillation as exc:
        time_constant = (t90 - t10) / math.log(9.0)
        return StepResponse(natural_frequency_rad_s=math.nan, damping_ratio=math.nan, fit_window_s=0.0,
                            fit_rms_error=math.nan, fit_note=exc.message, **read_off,
                            **motion(lambda x: [np.exp(-x / time_constant)]))
    window = fit_window_s if fit_window_s is not None else _ENVELOPE_TIME_CONSTANTS / sigma0
    if window <= 0:
        raise AnalysisError("fit_window_s must be positive", value=fit_window_s)
    in_fit = tau <= window
    if np.count_nonzero(in_fit) < _MIN_POST_STEP_SAMPLES:
        raise AnalysisError(
            f"fit window of {window:g} s holds fewer than {_MIN_POST_STEP_SAMPLES} samples"
        )
    tau_w, y_w = tau[in_fit], yp[in_fit]
    env = np.exp(-sigma0 * tau_w)
    basis = np.column_stack(
        [np.ones_like(tau_w), env * np.cos(omega_d0 * tau_w), env * np.sin(omega_d0 * tau_w)]
    )
    (yf0, a0, b0), *_ = np.linalg.lstsq(basis, y_w, rcond=None)
    try:
        params, _ = curve_fit(
            _damped_model,
            tau_w,
            y_w,
            p0=[yf0, a0, b0, sigma0, omega_d0],
            jac=_damped_jacobian,
            method="lm",
            maxfev=2000,
        )
    except (RuntimeError, ValueError) as exc:
        raise AnalysisError(f"second-order fit did not converge: {exc}") from exc
    sigma, omega_d = float(params[3]), abs(float(params[4]))
    wn = math.hypot(sigma, omega_d)
    if not math.isfinite(wn) or wn == 0.0:
        raise AnalysisError("second-order fit failed: no oscillation found")
    residual = y_w - _damped_model(tau_w, *params)

    def oscillation(x: FloatArray) -> list[FloatArray]:
        envelope = np.exp(-sigma * x)
        return [envelope * np.cos(omega_d * x), envelope * np.sin(omega_d * x)]

    zeta, note = sigma / wn, None
    if zeta > _NO_OSCILLATION_ZETA and 0.0 < overshoot_pct < 100.0:
        wn, zeta, note = _equivalent_second_order(overshoot_pct, peak_time_s, zeta)
    return StepResponse(
        natural_frequency_rad_s=wn,
        damping_ratio=zeta,
        fit_window_s=float(tau_w[-1]),
        fit_rms_error=float(np.sqrt(np.mean(residual**2))),
        fit_note=note,
        **read_off,
        **motion(oscillation),
    )


def _equivalent_second_order(overshoot_pct: float, peak_time_s: float, fitted_zeta: float) -> tuple[float, float, str]:
    """(ωn [rad/s], ζ, note) of the second-order loop ``ωn²/(s² + 2ζωn s + ωn²)`` whose step overshoots
    ``overshoot_pct`` [%] and peaks at ``peak_time_s`` [s], for a response whose fitted oscillation (ζ
    ``fitted_zeta``) does not oscillate."""
    log_mp = math.log(overshoot_pct / 100.0)
    zeta = -log_mp / math.hypot(math.pi, log_mp)
    wn = math.pi / (peak_time_s * math.sqrt(1.0 - zeta**2))
    note = (f"the fitted motion does not oscillate (ζ {fitted_zeta:.6g}: its envelope falls by more than e^"
            f"{_ENVELOPE_TIME_CONSTANTS:g} in half a period), yet the response overshoots {overshoot_pct:.3g} %: a "
            "zero of the loop (the derivative on the error) carried it past its final value; ωn and ζ are those of "
            "the second-order loop that overshoots as much and peaks as late")
    return wn, zeta, note


def _not_settled(t_tail: FloatArray, e_tail: FloatArray, band: float, settle_band: float) -> str | None:
    """Why the response has not settled (None if it has): a sample of the last 10 % of the record
    (``t_tail`` [s], ``e_tail`` its distance from the tail's mean) lies outside the settling band
    (``band``, ``settle_band`` of the step)."""
    worst = int(np.argmax(np.abs(e_tail)))
    if abs(e_tail[worst]) <= band:
        return None
    return (f"not settled: in the last 10 % of the record ({t_tail[0]:.4g}-{t_tail[-1]:.4g} s), whose mean would "
            f"be the final value, the response is still {abs(e_tail[worst]):.3g} from that mean at "
            f"{t_tail[worst]:.4g} s, outside the ±{100 * settle_band:g} % settling band (±{band:.3g}); the final "
            "value, steady-state error, overshoot, rise and settling times are not given (a longer record "
            "lets the response settle)")


def _motion_at_step(tau: FloatArray, y: FloatArray, basis) -> float | None:
    """Amplitude [signal units] at the step (``tau`` = 0) of the free motion before it: ``y`` at
    ``tau`` < 0 [s] fitted by linear least squares with a rest plus ``basis(tau)`` (one column, a
    decay, or two, a damped oscillation's cosine and sine), over the samples where the basis is
    within exp(8) of its value at the step (8 of its time constants); the decay's coefficient, or
    the oscillation's envelope. None with fewer than 3 samples."""
    columns = basis(tau)
    scale = np.max(np.abs(np.column_stack(columns)), axis=1)
    keep = scale <= math.exp(_ENVELOPE_TIME_CONSTANTS)
    if np.count_nonzero(keep) < 3:
        return None
    matrix = np.column_stack([np.ones(int(np.count_nonzero(keep))), *(c[keep] for c in columns)])
    coefficients, *_ = np.linalg.lstsq(matrix, y[keep], rcond=None)
    return float(np.hypot.reduce(coefficients[1:])) if len(columns) > 1 else float(abs(coefficients[1]))


# --------------------------------------------------------------------------- sine


def _wrap_deg(angle: float) -> float:
    """Wrap an angle to (-180, 180] degrees."""
    return -((-angle + 180.0) % 360.0 - 180.0)


def sinusoid_response(
    time_s: ArrayLike,
    reference: ArrayLike,
    response: ArrayLike,
    *,
    frequency_hz: float,
    start_s: float,
) -> SineResponse:
    """Amplitude ratio and phase lag of ``response`` to a sinusoidal ``reference``.

    Both signals are fitted on [start_s, end of record), truncated to a whole
    number of periods, by linear least squares to a + b sin(wt) + c cos(wt),
    w = 2 pi frequency_hz. Over whole periods this is the Fourier component at
    the fundamental, so harmonics (a staircase reference from a sample-and-hold,
    a distorted response) do not bias the result.

    Args:
        time_s: sample times [s], uniformly spaced.
        reference: the commanded sinusoid [signal units].
        response: the measured response [same units].
        frequency_hz: the reference frequency [Hz].
        start_s: start of the analysed window [s] (skip the transient).

    Raises:
        AnalysisError: bad frequency, window shorter than one period, or a
            reference without a component at ``frequency_hz``.
    """
    t, r, y = _signals(time_s=time_s, reference=reference, response=response)
    dt = _sample_period(t)
    if not (math.isfinite(frequency_hz) and frequency_hz > 0.0):
        raise AnalysisError("frequency_hz must be positive", value=frequency_hz)
    if frequency_hz >= 0.5 / dt:
        raise AnalysisError(
            f"frequency_hz must be below the Nyquist frequency {0.5 / dt:g} Hz",
            value=frequency_hz,
        )
    period = 1.0 / frequency_hz
    span = t[-1] + dt - start_s
    periods = int(math.floor(span / period + 1e-9))
    if periods < 1:
        raise AnalysisError(
            f"record too short: {max(span, 0.0):g} s after start_s={start_s:g} s, "
            f"need at least one period ({period:g} s)",
        )
    eps = 1e-3 * dt
    window = (t >= start_s - eps) & (t < start_s + periods * period - 0.5 * dt)
    if np.count_nonzero(window) < 4:
        raise AnalysisError("record too short: fewer than 4 samples in the window")
    tw = t[window]
    w = 2.0 * math.pi * frequency_hz
    basis = np.column_stack([np.ones_like(tw), np.sin(w * tw), np.cos(w * tw)])
    coef, *_ = np.linalg.lstsq(basis, np.column_stack([r[window], y[window]]), rcond=None)
    (r_off, y_off), (r_s, y_s), (r_c, y_c) = coef
    r_amp, y_amp = math.hypot(r_s, r_c), math.hypot(y_s, y_c)
    if r_amp <= 1e-12 * max(1.0, abs(r_off)):
        raise AnalysisError(f"the reference has no component at {frequency_hz:g} Hz")
    # b sin(wt) + c cos(wt) = R sin(wt + theta), theta = atan2(c, b).
    lag = math.degrees(math.atan2(r_c, r_s) - math.atan2(y_c, y_s))
    return SineResponse(
        frequency_hz=float(frequency_hz),
        amplitude_ratio=y_amp / r_amp,
        phase_lag_deg=_wrap_deg(lag),
        reference_amplitude=r_amp,
        response_amplitude=y_amp,
        reference_offset=float(r_off),
        response_offset=float(y_off),
        periods_used=periods,
    )


# --------------------------------------------------------------------------- theory


def _check_plant(mass_kg: float, damping: float) -> None:
    if not mass_kg > 0.0:
        raise AnalysisError("mass_kg must be positive", value=mass_kg)
    if not damping >= 0.0:
        raise AnalysisError("damping must be non-negative", value=damping)


def _scalar_or_array(x: NDArray[np.float64]) -> float | FloatArray:
    return float(x) if x.ndim == 0 else x


def second_order_theory(mass_kg: float, stiffness: float, damping: float) -> dict[str, float]:
    """Textbook step-response figures of m x'' + b x' + k x = k u.

    Args:
        mass_kg: moving mass m [kg] (or inertia [kg m^2]).
        stiffness: k [N/m], e.g. the position gain Kp of a P(D) loop.
        damping: b [N s/m], e.g. Kd plus viscous joint damping.

    Returns:
        ``natural_frequency_rad_s`` = sqrt(k/m), ``damping_ratio`` =
        b / (2 sqrt(k m)), ``damped_frequency_rad_s`` = wn sqrt(1 - zeta^2)
        (0 if zeta >= 1) and ``overshoot_pct`` = 100 exp(-zeta pi / sqrt(1 - zeta^2))
        (0 if zeta >= 1).
    """
    _check_plant(mass_kg, damping)
    if not stiffness > 0.0:
        raise AnalysisError("stiffness must be positive", value=stiffness)
    wn = math.sqrt(stiffness / mass_kg)
    zeta = damping / (2.0 * math.sqrt(stiffness * mass_kg))
    if zeta < 1.0:
        root = math.sqrt(1.0 - zeta**2)
        overshoot = 100.0 * math.exp(-zeta * math.pi / root)
        wd = wn * root
    else:
        overshoot, wd = 0.0, 0.0
    return {
        "natural_frequency_rad_s": wn,
        "damping_ratio": zeta,
        "damped_frequency_rad_s": wd,
        "overshoot_pct": overshoot,
    }


def second_order_frequency_response(
    mass_kg: float, stiffness: float, damping: float, omega_rad_s: ArrayLike
) -> tuple[float | FloatArray, float | FloatArray]:
    """Amplitude ratio [-] and phase lag [deg, 0..180] of G(s) = k / (m s^2 + b s + k).

    ``omega_rad_s`` [rad/s] may be a scalar (floats returned) or an array.
    """
    _check_plant(mass_kg, damping)
    if not stiffness > 0.0:
        raise AnalysisError("stiffness must be positive", value=stiffness)
    w = np.asarray(omega_rad_s, dtype=float)
    den = (stiffness - mass_kg * w**2) + 1j * damping * w
    with np.errstate(divide="ignore"):
        ratio = stiffness / np.abs(den)
    lag = np.degrees(np.arctan2(damping * w, stiffness - mass_kg * w**2))
    return _scalar_or_array(ratio), _scalar_or_array(lag)


def first_order_frequency_response(
    mass_kg: float, gain: float, damping: float, omega_rad_s: ArrayLike
) -> tuple[float | FloatArray, float | FloatArray]:
    """Amplitude ratio [-] and phase lag [deg, 0..90] of a velocity loop.

    G(s) = Kv / (m s + Kv + b): plant m v' = u - b v under u = Kv (v_ref - v).

    Args:
        mass_kg: m [kg]; gain: Kv [N s/m]; damping: b [N s/m];
        omega_rad_s: angular frequency [rad/s], scalar or array.
    """
    _check_plant(mass_kg, damping)
    if not gain > 0.0:
        raise AnalysisError("gain must be positive", value=gain)
    w = np.asarray(omega_rad_s, dtype=float)
    pole = gain + damping
    ratio = gain / np.hypot(pole, mass_kg * w)
    lag = np.degrees(np.arctan2(mass_kg * w, pole))
    return _scalar_or_array(ratio), _scalar_or_array(lag)

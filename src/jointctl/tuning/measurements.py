"""Figures of merit of the command source running now, read off the live buffer.

For a step: overshoot, settling time (2 % band), the oscillation (damped) frequency and the
fitted natural frequency and damping ratio (:func:`jointctl.metrics.response.step_response`); the
figures that need a final value only once the response has settled (the note says why until then).
For a sine: amplitude ratio and phase lag at the sine's frequency, over the latest whole periods
after the transient (:func:`~jointctl.metrics.response.sinusoid_response`). The response is
the quantity the commanded controller controls (position or velocity) of its joint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from jointctl.metrics.response import AnalysisError, sinusoid_response, step_response
from jointctl.tuning.live_buffer import LiveBuffer

STEP_LEAD_S = 0.1  # record kept before the step [s]
STEP_MIN_AFTER_S = 0.3  # first measurement this long after the step [s]
STEP_WINDOW_S = 5.0  # the longest record after the step that is analysed [s]
SINE_MIN_SETTLE_S = 1.0  # transient skipped after a sine starts, at least [s]
SINE_MAX_WINDOW_S = 5.0  # the latest this many seconds are analysed (whole periods) [s]


@dataclass(frozen=True)
class SourceRun:
    """A command source as applied: to which joint, what it is, and the loop time it started [s]."""

    joint: str
    controlled: str  # "position" or "velocity"
    description: dict[str, Any]
    started_s: float


def measure(buffer: LiveBuffer, run: SourceRun | None, now_s: float, period_s: float) -> dict[str, Any]:
    """``{"kind", "complete", "values", "note"}`` for the source in ``run`` at loop time ``now_s``."""
    kind = run.description.get("type") if run is not None else None
    if kind == "step":
        return _step(buffer, run, now_s, period_s)
    if kind == "sine":
        return _sine(buffer, run, now_s, period_s)
    return {"kind": None, "complete": True, "values": {},
            "note": "measurements run for step and sine sources"}


def _signals(buffer: LiveBuffer, run: SourceRun, start_s: float, stop_s: float, period_s: float):
    columns = [buffer.column("time"), buffer.column(f"{run.joint}.reference"),
               buffer.column(f"{run.joint}.{run.controlled}")]
    start = max(0, math.floor(start_s / period_s))
    rows, first, _ = buffer.rows(start, math.floor(stop_s / period_s) + 1, columns)
    if first > start:
        raise AnalysisError("the record of the step is no longer in the buffer (window too long ago)")
    return rows[:, 0], rows[:, 1], rows[:, 2]


def _step(buffer: LiveBuffer, run: SourceRun, now_s: float, period_s: float) -> dict[str, Any]:
    step_s = run.started_s + float(run.description["at"])
    result: dict[str, Any] = {"kind": "step", "complete": False, "values": {}, "note": None,
                              "step_time_s": step_s}
    elapsed = now_s - step_s
    if elapsed < STEP_MIN_AFTER_S:
        result["note"] = "waiting for the step"
        return result
    end_s = step_s + min(elapsed, STEP_WINDOW_S)
    try:
        time_s, command, response = _signals(buffer, run, max(run.started_s, step_s - STEP_LEAD_S), end_s,
                                             period_s)
        fit = step_response(time_s, command, response, step_time_s=step_s)
    except AnalysisError as exc:
        result["note"] = exc.message
        result["complete"] = elapsed >= STEP_WINDOW_S
        return result
    zeta, wn = fit.damping_ratio, fit.natural_frequency_rad_s
    damped = wn * math.sqrt(1.0 - zeta * zeta) if zeta < 1.0 else 0.0
    result["values"] = {
        "overshoot_pct": fit.overshoot_pct,
        "settling_time_s": fit.settling_time_s,
        "oscillation_frequency_hz": damped / (2.0 * math.pi),
        "natural_frequency_rad_s": wn,
        "damping_ratio": zeta,
        "rise_time_s": fit.rise_time_s,
        "steady_state_error": fit.steady_state_error,
    }
    result["note"] = fit.not_settled  # why the figures of the final value are not there yet (None once settled)
    # Done when the fit had all it wanted (its window ends before the record does) and the
    # response has settled, or when the longest window is reached.
    settled = fit.settling_time_s is not None and elapsed > fit.settling_time_s + 0.5
    result["complete"] = elapsed >= STEP_WINDOW_S or (settled and fit.fit_window_s < elapsed - 0.05)
    return result


def _sine(buffer: LiveBuffer, run: SourceRun, now_s: float, period_s: float) -> dict[str, Any]:
    frequency = float(run.description["frequency_hz"])
    result: dict[str, Any] = {"kind": "sine", "complete": False, "values": {}, "note": None}
    if frequency <= 0:
        result.update(note="a sine of 0 Hz is a constant", complete=True)
        return result
    period = 1.0 / frequency
    settle = max(SINE_MIN_SETTLE_S, 2.0 * period)
    if now_s - run.started_s < settle + period:
        result["note"] = "waiting for the transient to pass"
        return result
    start = max(run.started_s + settle, now_s - max(SINE_MAX_WINDOW_S, period))
    try:
        time_s, command, response = _signals(buffer, run, start, now_s, period_s)
        fit = sinusoid_response(time_s, command, response, frequency_hz=frequency, start_s=float(np.min(time_s)))
    except AnalysisError as exc:
        result["note"] = exc.message
        return result
    result["values"] = {"frequency_hz": frequency, "amplitude_ratio": fit.amplitude_ratio,
                        "phase_lag_deg": fit.phase_lag_deg, "periods_used": fit.periods_used}
    return result

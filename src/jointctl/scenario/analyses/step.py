"""A position loop's step response against the loop as it runs and the linearised loops about the rest pose
(:mod:`jointctl.scenario.analyses.step_theory`): prismatic or revolute, under gravity, coupled to the robot's
other joints, its effort clamped, its commands late; with the reason where that theory does not apply."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from jointctl.metrics.expectations import Margin, share_of
from jointctl.scenario.analyses.common import (analysed_joint, command_config, joint_plant, plot_effort,
                                               run_events, units)
from jointctl.scenario.analyses.step_theory import STEADY, StepTheory, step_theory
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.figures import StepMarks
from jointctl.recording.trace import Trace
from jointctl.metrics.response import StepResponse, step_response

#: The settling band's half-width, a share of the step (the step analysis' settling time uses it).
SETTLE_BAND = 0.02
#: The peak effort after the step against the loop as it runs': the model computes the controller's own
#: command (a clamped one is the limit itself); 2 % is a neighbour's coupling or a plant the model lacks.
PEAK_MARGIN = Margin(0.02, True, "the model computes the controller's own command; more is a neighbour's coupling "
                     "or a plant the model lacks")


def analyse_step(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Step response of a position loop: ωn, ζ, overshoot, settling, steady error, the peak effort after
    the step (``peak_effort_n`` or ``peak_effort_n_m``) and the share of cycles after the step with the
    effort at its limit; ``expected`` from the step theory (None where it does not apply,
    ``not_applicable`` saying why), ``theory`` how it got there (``theory.model``: the loop as it runs'
    figures, read as the run's).

    A run that did not settle has no final value, steady-state error, overshoot, rise or settling
    time (None) and ``not_settled`` says why; a run still moving when its step came has
    ``moving_at_step`` true (:class:`~jointctl.metrics.response.StepResponse`). Both are
    ``warnings`` too."""
    joint = analysed_joint(session, params)
    cfg = command_config(session, joint)
    step_time = float(cfg.get("at", 0.0))
    t = trace.time_s
    cmd, pos = trace.joint(joint, "reference"), trace.joint(joint, "position")
    result = step_response(t, cmd, pos, step_time_s=step_time, settle_band=SETTLE_BAND,
                           ramp_s=float(cfg.get("ramp_s", 0.0)))
    plant = joint_plant(session, joint)
    theory = step_theory(session, trace, joint, step_time, SETTLE_BAND, ramp_s=float(cfg.get("ramp_s", 0.0)))
    joint_units = units(session, joint)
    unit = joint_units.position
    zoom = (step_time - 0.1, step_time + 1.0)
    marks = step_marks(t, pos, step_time, result, theory)
    curve = theory.response(t)
    moved = theory.not_applicable.get("overshoot_pct", "").startswith("the other joints' loops move")
    label = "model of the joint alone (its neighbours move it)" if moved else "model: the loop as it runs"
    events = run_events(session, trace)
    for name, window, what in (("position.png", None, "step response"), ("position_zoom.png", zoom, "step (zoom)")):
        figures.plot_step(out / name, t, cmd, pos, title=f"{session.scenario.name}: {joint} {what}", unit=unit,
                          marks=marks, theory=curve, theory_label=label, zoom=window, events=events)
    plot_effort(session, trace, out, joint)

    effort_unit = joint_units.effort.lower().replace("·", "_")

    def named(key: str) -> str:  # the steady-state error and the peak effort in the joint's own units
        return {"steady_state_error": f"steady_state_error_{unit}", "peak_effort": f"peak_effort_{effort_unit}"}.get(
            key, key)

    metrics = {named(k): v for k, v in result.as_dict().items()}
    after = trace.joint(joint, "effort")[t >= step_time]
    metrics[named("peak_effort")] = float(np.max(np.abs(after))) if after.size else None
    metrics["effort_saturated_share_after_step"] = theory.details["saturated_share_after_step"]
    step = float(cmd[-1] - cmd[t < step_time][-1])
    details = dict(theory.details)
    if "model" in details:
        details["model"] = {named(k): v for k, v in details["model"].items()}
    out_metrics = {**metrics, "expected": {named(k): v for k, v in theory.expected.items()},
                   "plant": plant.__dict__, "theory": details,
                   "margins": {named("steady_state_error"): share_of(step, "step"), named("peak_effort"): PEAK_MARGIN}}
    if theory.not_applicable:
        out_metrics["not_applicable"] = {named(k): v for k, v in theory.not_applicable.items()}
    out_metrics["warnings"] = step_warnings(result, step, SETTLE_BAND, unit)
    return out_metrics


def step_warnings(result: StepResponse, step: float, band: float, unit: str) -> list[str]:
    """The sentences a step's figures need beside them: it did not settle (``not_settled``), or it was
    still moving when the step came (its motion beyond the ±``band`` share of the ``step``)."""
    found = [result.not_settled] if result.not_settled is not None else []
    if result.moving_at_step:
        found.append(f"moving at the step: the motion before it still had an amplitude of {result.motion_at_step:.3g} "
                     f"{unit} about its rest when the step came, more than the ±{100 * band:g} % settling band of "
                     f"the {abs(step):.3g} {unit} step ({band * abs(step):.3g} {unit}); the step's figures carry that "
                     "motion (step later, or start the run at rest)")
    return found


def step_marks(t: np.ndarray, position: np.ndarray, step_time_s: float, result: StepResponse,
               theory: StepTheory) -> StepMarks:
    """What the step figures mark (:class:`~jointctl.recording.figures.StepMarks`): the measured
    initial and final values, overshoot peak, 10-90 % rise and settling time of ``result``, the
    ±:data:`SETTLE_BAND` band, and the final value of the loop as it runs as the expected one (where the
    steady-state error is expected)."""
    rise: list[float | None] = [None, None]
    if result.final_value is not None:  # a rise to the final value (a run that did not settle has none)
        step = result.final_value - result.initial_value
        after = t >= step_time_s
        tau, progress = t[after] - step_time_s, np.sign(step) * (position[after] - result.initial_value) / abs(step)
        rise = [_first_crossing(tau, progress, level) for level in (0.1, 0.9)]
    peak = int(np.argmin(np.abs(t - (step_time_s + result.peak_time_s))))
    expected = (theory.details.get("model") or {}).get("final_value") if theory.expected.get(STEADY) is not None \
        else None
    return StepMarks(
        step_time_s=step_time_s, initial_value=result.initial_value, final_value=result.final_value,
        settle_band=SETTLE_BAND, overshoot_pct=result.overshoot_pct, peak_time_s=float(t[peak]),
        peak_value=float(position[peak]),
        rise_start_s=None if rise[0] is None else step_time_s + rise[0],
        rise_end_s=None if rise[1] is None else step_time_s + rise[1],
        settling_time_s=result.settling_time_s, expected_final=expected)


def _first_crossing(tau: np.ndarray, progress: np.ndarray, level: float) -> float | None:
    """The first time [s] ``progress`` reaches ``level``, interpolated between samples; None if never."""
    above = np.flatnonzero(progress >= level)
    if not above.size:
        return None
    i = int(above[0])
    if i == 0:
        return float(tau[0])
    return float(tau[i - 1] + (level - progress[i - 1]) / (progress[i] - progress[i - 1]) * (tau[i] - tau[i - 1]))

"""A position loop's step response against the linearised loop about the rest pose
(:mod:`jointctl.scenario.analyses.step_theory`): prismatic or revolute, under gravity, coupled to
the robot's other joints; with the reason where that theory does not apply."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from jointctl.metrics.expectations import share_of
from jointctl.scenario.analyses.common import (analysed_joint, command_config, joint_plant, plot_effort,
                                               run_events, units)
from jointctl.scenario.analyses.step_theory import step_theory
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.trace import Trace
from jointctl.metrics.response import step_response


def analyse_step(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Step response of a position loop: ωn, ζ, overshoot, settling, steady error, and the share of
    cycles after the step with the effort at its limit; ``expected`` from the step theory (None
    where it does not apply, ``not_applicable`` saying why), ``theory`` how it got there."""
    joint = analysed_joint(session, params)
    cfg = command_config(session, joint)
    step_time = float(cfg.get("at", 0.0))
    t = trace.time_s
    cmd, pos = trace.joint(joint, "reference"), trace.joint(joint, "position")
    result = step_response(t, cmd, pos, step_time_s=step_time)
    plant = joint_plant(session, joint)
    theory = step_theory(session, trace, joint, step_time)
    unit = units(session, joint).position
    zoom = (step_time - 0.1, step_time + 1.0)
    events = run_events(session, trace)
    figures.plot_command_and_position(out / "position.png", t, cmd, pos, unit=unit, events=events,
                                      title=f"{session.scenario.name}: {joint} step response")
    figures.plot_command_and_position(out / "position_zoom.png", t, cmd, pos, zoom=zoom, unit=unit, events=events,
                                      title=f"{session.scenario.name}: {joint} step (zoom)")
    plot_effort(session, trace, out, joint)

    def named(key: str) -> str:  # the steady-state error in the joint's own unit, said in its name
        return f"steady_state_error_{unit}" if key == "steady_state_error" else key

    metrics = {named(k): v for k, v in result.as_dict().items()}
    metrics["effort_saturated_share_after_step"] = theory.details["saturated_share_after_step"]
    step = float(cmd[-1] - cmd[t < step_time][-1])
    out_metrics = {**metrics, "expected": {named(k): v for k, v in theory.expected.items()},
                   "plant": plant.__dict__, "theory": theory.details,
                   "margins": {named("steady_state_error"): share_of(step, "step")}}
    if theory.not_applicable:
        out_metrics["not_applicable"] = {named(k): v for k, v in theory.not_applicable.items()}
    return out_metrics

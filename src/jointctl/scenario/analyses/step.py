"""A position loop's step response against the second-order theory of the joint's plant."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from jointctl.scenario.analyses.common import analysed_joint, command_config, joint_plant, plot_effort
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.trace import Trace
from jointctl.metrics.response import second_order_theory, step_response


def analyse_step(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Step response of a position loop: ωn, ζ, overshoot, settling, steady error."""
    joint = analysed_joint(session, params)
    cfg = command_config(session, joint)
    step_time = float(cfg.get("at", 0.0))
    t = trace.time_s
    cmd, pos = trace.joint(joint, "reference"), trace.joint(joint, "position")
    result = step_response(t, cmd, pos, step_time_s=step_time)
    plant = joint_plant(session, joint)
    theory = second_order_theory(plant.moving_mass_kg, plant.kp, plant.damping + plant.kd)
    expected = {
        "natural_frequency_rad_s": theory["natural_frequency_rad_s"],
        "damping_ratio": theory["damping_ratio"],
        "overshoot_pct": theory["overshoot_pct"],
        "steady_state_error": -plant.moving_mass_kg * plant.gravity_along_axis_m_s2 / plant.kp,
    }
    unit = "m" if session.robot.joint(joint).is_prismatic else "rad"
    zoom = (step_time - 0.1, step_time + 1.0)
    figures.plot_command_and_position(out / "position.png", t, cmd, pos,
                                      title=f"{session.scenario.name}: {joint} step response")
    figures.plot_command_and_position(out / "position_zoom.png", t, cmd, pos, zoom=zoom,
                                      title=f"{session.scenario.name}: {joint} step (zoom)")
    plot_effort(session, trace, out, joint)
    # The steady-state error in the joint's own unit, said in its name.
    metrics = {f"steady_state_error_{unit}" if k == "steady_state_error" else k: v for k, v in result.as_dict().items()}
    expected[f"steady_state_error_{unit}"] = expected.pop("steady_state_error")
    return {**metrics, "expected": expected, "plant": plant.__dict__}

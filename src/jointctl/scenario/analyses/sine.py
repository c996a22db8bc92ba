"""Position and velocity loops driven by a sinusoid, against the plant's frequency response."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from jointctl.errors import ConfigError
from jointctl.scenario.analyses.common import (analysed_joint, command_config, joint_plant, plot_effort,
                                               run_events, units)
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.trace import Trace
from jointctl.metrics.response import (
    first_order_frequency_response,
    second_order_frequency_response,
    sinusoid_response,
)


def _sine_frequency_hz(session: Session, joint: str, cfg: dict[str, Any], params) -> float:
    if "frequency_hz" in params:
        return float(params["frequency_hz"])
    if cfg.get("type") == "sine":
        return float(cfg["frequency_hz"])
    raise ConfigError("give analysis.frequency_hz for a command that is not a sine",
                      source=session.scenario.source, field="analysis.frequency_hz")


def _sine_fit(session: Session, trace: Trace, params: dict[str, Any], quantity: str,
              default_start_s: float):
    """Fit the command and the joint's ``quantity`` at the drive frequency."""
    joint = analysed_joint(session, params)
    freq = _sine_frequency_hz(session, joint, command_config(session, joint), params)
    t = trace.time_s
    command, signal = trace.joint(joint, "reference"), trace.joint(joint, quantity)
    result = sinusoid_response(t, command, signal, frequency_hz=freq,
                               start_s=float(params.get("start_s", default_start_s)))
    return joint, freq, t, command, signal, result, joint_plant(session, joint)


def analyse_sine(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Position loop driven by a sinusoid: amplitude ratio and phase lag at the drive frequency."""
    joint, freq, t, cmd, pos, result, plant = _sine_fit(session, trace, params, "position", 1.0)
    ratio, lag = second_order_frequency_response(plant.moving_mass_kg, plant.kp,
                                                 plant.damping + plant.kd, 2 * math.pi * freq)
    figures.plot_command_and_position(out / "position.png", t, cmd, pos, unit=units(session, joint).position,
                                      title=f"{session.scenario.name}: {joint} sine tracking",
                                      events=run_events(session, trace))
    plot_effort(session, trace, out, joint)
    return {"phase_lag_deg": result.phase_lag_deg, "amplitude_ratio": result.amplitude_ratio,
            "frequency_hz": freq, "periods_used": result.periods_used,
            "expected": {"phase_lag_deg": float(lag), "amplitude_ratio": float(ratio)},
            "plant": plant.__dict__}


def analyse_velocity_sine(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Velocity loop driven by a sinusoid: first-order gain and phase lag."""
    joint, freq, t, cmd, vel, result, plant = _sine_fit(session, trace, params, "velocity", 0.5)
    ratio, lag = first_order_frequency_response(plant.moving_mass_kg, plant.kp, plant.damping,
                                                2 * math.pi * freq)
    joint_units, events = units(session, joint), run_events(session, trace)
    figures.plot_command_and_position(out / "velocity.png", t, cmd, vel, ylabel="velocity",
                                      unit=joint_units.velocity, command_label="velocity command",
                                      position_label="velocity", events=events,
                                      title=f"{session.scenario.name}: {joint} velocity tracking")
    figures.plot_series(out / "position.png", t, {f"{joint} position": trace.joint(joint, "position")},
                        title=f"{session.scenario.name}: {joint} position", ylabel="position",
                        unit=joint_units.position, events=events)
    plot_effort(session, trace, out, joint)
    return {"velocity_amplitude_ratio": result.amplitude_ratio,
            "velocity_phase_lag_deg": result.phase_lag_deg, "frequency_hz": freq,
            "expected": {"velocity_amplitude_ratio": float(ratio), "velocity_phase_lag_deg": float(lag)},
            "plant": plant.__dict__}

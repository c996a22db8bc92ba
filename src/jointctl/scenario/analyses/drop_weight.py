"""A weight dropped on the position-controlled robot (figure 11.5): impacts, peak and steady forces."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from jointctl.metrics.expectations import share_of
from jointctl.scenario.analyses.common import (
    CONTACT_THRESHOLD_N,
    STEADY_WINDOW_S,
    analysed_joint,
    analysed_sensor,
    dropped_object,
    effort_limit_levels,
    joint_plant,
    run_events,
    sensor_link_mass,
    units,
)
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.figures import Panel
from jointctl.recording.trace import Trace


def contact_episodes(force_z: np.ndarray, unloaded_n: float) -> int:
    """Separate contact episodes: times the sensed load rises above the threshold."""
    loaded = np.abs(force_z - unloaded_n) > CONTACT_THRESHOLD_N
    return int(np.count_nonzero(loaded[1:] & ~loaded[:-1]) + (1 if loaded[0] else 0))


def analyse_drop_weight(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """A weight dropped on the position-controlled robot: impacts, peak and steady forces (fig. 11.5)."""
    joint, sensor = analysed_joint(session, params), analysed_sensor(session, params)
    weight = dropped_object(session)
    t = trace.time_s
    effort, position = trace.joint(joint, "effort"), trace.joint(joint, "position")
    force_z = trace[f"{sensor}.force_z"]
    steady = t >= t[-1] - STEADY_WINDOW_S
    before = (t < weight.spawn_at_s) & (t >= weight.spawn_at_s - 0.1)
    plant = joint_plant(session, joint)
    g = -plant.gravity_along_axis_m_s2
    plate = sensor_link_mass(session, sensor)
    expected_effort = (plant.moving_mass_kg + weight.mass_kg) * g
    metrics = {
        "impacts": contact_episodes(force_z, float(force_z[before].mean())),
        "peak_sensor_force_n": float(np.max(np.abs(force_z))),
        "steady_effort_n": float(effort[steady].mean()),
        "steady_sensor_force_z_n": float(force_z[steady].mean()),
        "steady_position_m": float(position[steady].mean()),
        "expected": {
            "steady_effort_n": expected_effort,
            "steady_sensor_force_z_n": -(weight.mass_kg + plate) * g,
            "steady_position_m": float(trace.joint(joint, "reference")[-1]) - expected_effort / plant.kp,
        },
        "margins": {"steady_position_m": share_of(expected_effort / plant.kp, "sag")},
        "plant": plant.__dict__,
    }
    name = session.scenario.name
    joint_units, events = units(session, joint), run_events(session, trace)
    limits = effort_limit_levels(session, joint)
    if joint_units.effort == "N":  # a prismatic joint's effort and the sensed force share one axis
        panels = [Panel({f"{joint} effort": effort, f"{sensor} force z": force_z}, "force", "N", limits)]
    else:
        panels = [Panel({f"{joint} effort": effort}, "effort", joint_units.effort, limits),
                  Panel({f"{sensor} force z": force_z}, "force", "N")]
    figures.plot_panels(out / "effort_and_force.png", t, panels, events=events,
                        title=f"{name}: actuator effort and sensed force")
    figures.plot_command_and_position(out / "position.png", t, trace.joint(joint, "reference"), position,
                                      unit=joint_units.position, events=events, title=f"{name}: {joint} position")
    return metrics

"""Turn a recorded run into metrics and figures, with the theory they are compared to.

A scenario's ``analysis`` names one of :data:`ANALYSES`. Each analysis reads
the trace, writes PNG figures into the output folder and returns the metrics
(measured figures plus an ``expected`` mapping of the same keys computed
from the model: moving mass, joint damping, controller gains, gravity).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from jointctl.errors import ConfigError
from jointctl.scenario.session import Session
from jointctl.tools import figures
from jointctl.tools.recorder import Trace
from jointctl.tools.response_analysis import (
    first_order_frequency_response,
    second_order_frequency_response,
    second_order_theory,
    sinusoid_response,
    step_response,
)


@dataclass(frozen=True)
class JointPlant:
    """What the theory needs about one prismatic or revolute joint and its loop.

    ``moving_mass_kg`` is the mass (or inertia about the axis) the joint moves,
    ``damping`` its viscous damping, ``gravity_along_axis_m_s2`` gravity
    projected on the joint axis, ``gains`` the commanding controller's PID gains.
    """

    moving_mass_kg: float
    damping: float
    gravity_along_axis_m_s2: float
    kp: float
    kd: float


def joint_plant(session: Session, joint: str) -> JointPlant:
    world = session.world
    m, d = world.model, world.data
    jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, joint)
    body = m.jnt_bodyid[jid]
    mujoco.mj_forward(m, d)
    if m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_SLIDE:
        mass = float(m.body_subtreemass[body])
    else:  # inertia about the axis, from the joint-space mass matrix
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, full, d.qM) if hasattr(d, "qM") else mujoco.mj_fullM(m, d, full)
        dof = m.jnt_dofadr[jid]
        mass = float(full[dof, dof])
    axis = np.array(d.xaxis[jid])
    gravity = float(np.dot(m.opt.gravity, axis))
    controller = session.manager.commanding(joint)
    gains = controller.pid.gains
    return JointPlant(mass, float(m.dof_damping[m.jnt_dofadr[jid]]), gravity, gains.p, gains.d)


def _command_config(session: Session, joint: str) -> dict[str, Any]:
    controller = session.manager.commanding(joint)
    cfg = session.scenario.commands.get(controller.name) if controller else None
    if cfg is None:
        raise ConfigError("the analysis needs a command source for the joint's controller",
                          source=session.scenario.source, field="analysis.joint", value=joint)
    return cfg


def _joint(session: Session, params: dict[str, Any]) -> str:
    joint = params.get("joint")
    if joint not in session.hardware.joint_names:
        raise ConfigError("names no joint of the robot", source=session.scenario.source,
                          field="analysis.joint", value=joint)
    return joint


def analyse_step(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Step response of a position loop: ωn, ζ, overshoot, settling, steady error."""
    joint = _joint(session, params)
    cfg = _command_config(session, joint)
    step_time = float(cfg.get("at", 0.0))
    t = trace.time_s
    cmd, pos = trace.joint(joint, "command"), trace.joint(joint, "position")
    result = step_response(t, cmd, pos, step_time_s=step_time)
    plant = joint_plant(session, joint)
    theory = second_order_theory(plant.moving_mass_kg, plant.kp, plant.damping + plant.kd)
    expected = {
        "natural_frequency_rad_s": theory["natural_frequency_rad_s"],
        "damping_ratio": theory["damping_ratio"],
        "overshoot_pct": theory["overshoot_pct"],
        "steady_state_error_m": -plant.moving_mass_kg * plant.gravity_along_axis_m_s2 / plant.kp,
    }
    zoom = (step_time - 0.1, step_time + 1.0)
    figures.plot_command_and_position(out / "position.png", t, cmd, pos,
                                      title=f"{session.scenario.name}: {joint} step response")
    figures.plot_command_and_position(out / "position_zoom.png", t, cmd, pos, zoom=zoom,
                                      title=f"{session.scenario.name}: {joint} step (zoom)")
    figures.plot_series(out / "effort.png", t, {f"{joint} effort": trace.joint(joint, "effort")},
                        title=f"{session.scenario.name}: {joint} effort", ylabel="effort [N]")
    metrics = {k: v for k, v in result.as_dict().items()}
    return {**metrics, "expected": expected, "plant": plant.__dict__}


def _sine_frequency_hz(session: Session, joint: str, cfg: dict[str, Any], params) -> float:
    if "frequency_hz" in params:
        return float(params["frequency_hz"])
    if cfg.get("type") == "sine":
        return float(cfg["frequency_hz"])
    raise ConfigError("give analysis.frequency_hz for a command that is not a sine",
                      source=session.scenario.source, field="analysis.frequency_hz")


def analyse_sine(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Position loop driven by a sinusoid: amplitude ratio and phase lag at the drive frequency."""
    joint = _joint(session, params)
    cfg = _command_config(session, joint)
    freq = _sine_frequency_hz(session, joint, cfg, params)
    start = float(params.get("start_s", 1.0))
    t = trace.time_s
    cmd, pos = trace.joint(joint, "command"), trace.joint(joint, "position")
    result = sinusoid_response(t, cmd, pos, frequency_hz=freq, start_s=start)
    plant = joint_plant(session, joint)
    ratio, lag = second_order_frequency_response(plant.moving_mass_kg, plant.kp,
                                                 plant.damping + plant.kd, 2 * math.pi * freq)
    figures.plot_command_and_position(out / "position.png", t, cmd, pos,
                                      title=f"{session.scenario.name}: {joint} sine tracking")
    figures.plot_series(out / "effort.png", t, {f"{joint} effort": trace.joint(joint, "effort")},
                        title=f"{session.scenario.name}: {joint} effort", ylabel="effort [N]")
    return {"phase_lag_deg": result.phase_lag_deg, "amplitude_ratio": result.amplitude_ratio,
            "frequency_hz": freq, "periods_used": result.periods_used,
            "expected": {"phase_lag_deg": float(lag), "amplitude_ratio": float(ratio)},
            "plant": plant.__dict__}


def analyse_velocity_sine(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Velocity loop driven by a sinusoid: first-order gain and phase lag."""
    joint = _joint(session, params)
    cfg = _command_config(session, joint)
    freq = _sine_frequency_hz(session, joint, cfg, params)
    start = float(params.get("start_s", 0.5))
    t = trace.time_s
    cmd, vel = trace.joint(joint, "command"), trace.joint(joint, "velocity")
    result = sinusoid_response(t, cmd, vel, frequency_hz=freq, start_s=start)
    plant = joint_plant(session, joint)
    ratio, lag = first_order_frequency_response(plant.moving_mass_kg, plant.kp, plant.damping,
                                                2 * math.pi * freq)
    figures.plot_command_and_position(out / "velocity.png", t, cmd, vel, ylabel="velocity [m/s]",
                                      command_label="velocity command", position_label="velocity",
                                      title=f"{session.scenario.name}: {joint} velocity tracking")
    figures.plot_series(out / "position.png", t, {f"{joint} position": trace.joint(joint, "position")},
                        title=f"{session.scenario.name}: {joint} position", ylabel="position [m]")
    figures.plot_series(out / "effort.png", t, {f"{joint} effort": trace.joint(joint, "effort")},
                        title=f"{session.scenario.name}: {joint} effort", ylabel="effort [N]")
    return {"velocity_amplitude_ratio": result.amplitude_ratio,
            "velocity_phase_lag_deg": result.phase_lag_deg, "frequency_hz": freq,
            "expected": {"velocity_amplitude_ratio": float(ratio), "velocity_phase_lag_deg": float(lag)},
            "plant": plant.__dict__}


Analysis = Callable[[Session, Trace, Path, dict[str, Any]], dict[str, Any]]

ANALYSES: dict[str, Analysis] = {
    "step_response": analyse_step,
    "sine_response": analyse_sine,
    "velocity_sine_response": analyse_velocity_sine,
}


def check_analysis(session: Session) -> Analysis | None:
    """The scenario's analysis function, checked before the run starts."""
    spec = session.scenario.analysis
    if spec is None:
        return None
    fn = ANALYSES.get(spec["type"])
    if fn is None:
        raise ConfigError(f"unknown analysis (known: {', '.join(ANALYSES)})",
                          source=session.scenario.source, field="analysis.type", value=spec["type"])
    _joint(session, spec)
    return fn

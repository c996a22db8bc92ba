"""What the analyses share: the joint's plant from the robot's dynamics, the scenario's joint, sensor,
object and command, re-runs of the scenario with changes, tracking errors and the effort plot."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from jointctl.errors import ConfigError
from jointctl.model.dynamics import RobotDynamics
from jointctl.scenario.session import Session
from jointctl.scenario.spec import flatten
from jointctl.recording import figures
from jointctl.recording.trace import Trace, load_trace

CONTACT_THRESHOLD_N = 1.0  # sensed force beyond the unloaded reading that counts as contact
STEADY_WINDOW_S = 1.0      # steady values are means over the last second of the run


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
    """The plant of ``joint`` from the robot's dynamics at the pose the run ended in, under the
    scenario's gravity: the joint-space inertia's diagonal entry is the mass (prismatic) or the
    inertia about the axis (revolute) the joint moves, armature included."""
    hardware = session.hardware
    dynamics = RobotDynamics(session.robot, session.scenario.gravity_m_s2, joints=hardware.joint_names)
    dynamics.set_pose(hardware.position)
    k = dynamics.joint_names.index(joint)
    mass = float(dynamics.mass_matrix()[k, k])
    gravity = float(np.dot(session.scenario.gravity_m_s2, dynamics.joint_axis(joint)))
    gains = session.manager.commanding(joint).pid.gains
    return JointPlant(mass, float(dynamics.damping[k]), gravity, gains.p, gains.d)


def command_config(session: Session, joint: str) -> dict[str, Any]:
    """The scenario's command source of the controller commanding ``joint``."""
    controller = session.manager.commanding(joint)
    cfg = session.scenario.commands.get(controller.name) if controller else None
    if cfg is None:
        raise ConfigError("the analysis needs a command source for the joint's controller",
                          source=session.scenario.source, field="analysis.joint", value=joint)
    return cfg


def analysed_joint(session: Session, params: dict[str, Any]) -> str:
    """The joint ``analysis.joint`` names, checked against the hardware's joints."""
    return _named(session, params, "joint", session.hardware.joint_names, "joint")


def dropped_object(session: Session):
    """The scenario's first object: the weight dropped on the robot."""
    objects = session.scenario.objects
    if not objects:
        raise ConfigError("the analysis needs an object dropped on the robot",
                          source=session.scenario.source, field="objects")
    return objects[0]


def analysed_sensor(session: Session, params: dict[str, Any]) -> str:
    """The force-torque sensor ``analysis.sensor`` names, checked against the hardware's sensors."""
    return _named(session, params, "sensor", session.hardware.sensor_names, "force-torque sensor")


def _named(session: Session, params: dict[str, Any], key: str, known, what: str) -> str:
    value = params.get(key)
    if value not in known:
        raise ConfigError(f"names no {what} of the robot", source=session.scenario.source,
                          field=f"analysis.{key}", value=value)
    return value


def sensor_link_mass(session: Session, sensor: str) -> float:
    """Mass [kg] the sensor carries when unloaded: its own link (the plate)."""
    spec = next(s for s in session.robot.sensors if s.name == sensor)
    inertial = session.robot.link(spec.link).inertial
    return inertial.mass_kg if inertial else 0.0


def plot_effort(session: Session, trace: Trace, out: Path, joint: str) -> None:
    """``effort.png``: the joint's effort over the run."""
    figures.plot_series(out / "effort.png", trace.time_s, {f"{joint} effort": trace.joint(joint, "effort")},
                        title=f"{session.scenario.name}: {joint} effort", ylabel="effort [N]")


def run_variant(session: Session, out: Path, controller_overrides: dict[str, Any],
                **scenario_changes: Any) -> Trace:
    """Run the session's scenario again with extra controller overrides (and other scenario
    fields replaced); return its trace."""
    scenario = dataclasses.replace(
        session.scenario, analysis=None,
        controller_overrides={**session.scenario.controller_overrides, **flatten(controller_overrides)},
        **scenario_changes)
    with Session(scenario, out_dir=out) as variant:
        variant.run()
    return load_trace(variant.trace_path)


def rms_tracking_error(trace: Trace, joints: tuple[str, ...], start_s: float, end_s: float) -> float:
    """RMS over ``joints`` and time of (reference - position) within [start_s, end_s]."""
    t = trace.time_s
    window = (t >= start_s) & (t <= end_s)
    errors = np.array([trace.joint(j, "reference")[window] - trace.joint(j, "position")[window] for j in joints])
    return float(np.sqrt(np.mean(errors**2)))

"""What the analyses share: the joint's plant from the robot's dynamics, the scenario's joint, sensor,
object and command, re-runs of the scenario with changes, tracking errors, and what every figure
shows: each joint's units (from its type), its effort limit lines, the run's events (objects
spawned and their impacts, goals started and ended) and the effort plot."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from jointctl.control.position_loop import position_loop
from jointctl.errors import ConfigError
from jointctl.scenario.session import Session
from jointctl.scenario.spec import flatten
from jointctl.recording import figures
from jointctl.recording.figures import Event, Level
from jointctl.recording.trace import Trace, load_trace
from jointctl.recording.units import JointUnits, joint_units

CONTACT_THRESHOLD_N = 1.0  # sensed force beyond the unloaded reading that counts as contact
STEADY_WINDOW_S = 1.0      # steady values are means over the last second of the run
UNLOADED_WINDOW_S = 0.1    # the unloaded sensor reading: its mean over this long before an object appears


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
    """The plant of ``joint`` from the simulated robot's dynamics (the session's ``plant``: a scenario's payload
    and model changes included) at the pose the run ended in, under the scenario's gravity: the joint-space
    inertia's diagonal entry is the mass (prismatic) or the inertia about the axis (revolute) the joint moves,
    armature included."""
    hardware = session.hardware
    dynamics = session.dynamics(session.plant, hardware.joint_names)
    dynamics.set_pose(hardware.position)
    k = dynamics.joint_names.index(joint)
    mass = float(dynamics.mass_matrix()[k, k])
    gravity = float(np.dot(session.scenario.gravity_m_s2, dynamics.joint_axis(joint)))
    controller = session.manager.commanding(joint)
    gains = (position_loop(controller, joint) or controller).pid.gains
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


def units(session: Session, joint: str) -> JointUnits:
    """The SI units of ``joint``'s signals: m and N for a prismatic joint, rad and N·m otherwise."""
    return joint_units(session.robot.joint(joint))


def common_units(session: Session, joints) -> JointUnits:
    """The units ``joints`` share (a figure of several joints has one axis); where prismatic and
    revolute joints mix, each unit names both ("m, rad") and is shown without a prefix."""
    found = {units(session, j) for j in joints}
    if len(found) == 1:
        return found.pop()
    return JointUnits(*(", ".join(sorted({getattr(u, f) for u in found}))
                        for f in ("position", "velocity", "acceleration", "effort")))


def effort_limit_levels(session: Session, joint: str, *, series: str | None = None) -> list[Level]:
    """The lines at ``joint``'s effort limit ±limit (none without a positive limit), in N or N·m;
    ``series``: the figure's series of that joint (several joints on one axis): the lines take its
    colour and their label names the joint."""
    spec = session.robot.joint(joint)
    limit = spec.limits.effort if spec.limits is not None else 0.0
    if not limit or not limit > 0 or not np.isfinite(limit):
        return []
    text = f"{joint} limit" if series is not None else "effort limit"
    text += f" ±{limit:g} {units(session, joint).effort}"
    return [Level(limit, text, series=series), Level(-limit, text, series=series)]


def run_events(session: Session, trace: Trace) -> list[Event]:
    """The moments a reader of the run's figures wants to see, in loop time [s]: each object's spawn
    (``scenario.objects[].spawn_at_s``, "<name> spawned"), its impact ("<name> impact": the first
    sample after the spawn where a force sensor's reading departs by more than
    :data:`CONTACT_THRESHOLD_N` from its mean over the :data:`UNLOADED_WINDOW_S` before it), and
    each accepted trajectory goal's start and end ("goal start", "goal end: succeeded"; numbered
    when there are several), and each refused one when it was sent ("goal rejected")."""
    events: list[Event] = []
    t = trace.time_s
    sensors = [s.name for s in session.robot.sensors
               if all(f"{s.name}.force_{a}" in trace.columns for a in "xyz")]
    for obj in sorted(session.scenario.objects, key=lambda o: o.spawn_at_s):
        if obj.spawn_at_s > t[-1]:
            continue
        events.append(Event(obj.spawn_at_s, f"{obj.name} spawned", "spawn"))
        impacts = [time for time in (_first_load_change(trace, sensor, obj.spawn_at_s) for sensor in sensors)
                   if time is not None]
        if impacts:
            events.append(Event(min(impacts), f"{obj.name} impact", "contact"))
    goals = [g for g in session.goals if g.validated is not None]
    for k, goal in enumerate(goals):
        number = f" {k + 1}" if len(goals) > 1 else ""
        events.append(Event(float(goal.validated.start_time_s), f"goal{number} start", "goal"))
        if goal.result is not None and goal.result.time_s <= t[-1]:
            events.append(Event(float(goal.result.time_s), f"goal{number} end: {goal.status.value}", "goal"))
    for time_s, _ in session.rejected_goals:
        if time_s <= t[-1]:
            events.append(Event(float(time_s), "goal rejected", "rejected"))
    return events


def _first_load_change(trace: Trace, sensor: str, after_s: float) -> float | None:
    """The first time [s] at or after ``after_s`` at which ``sensor``'s force departs from its
    unloaded reading by more than :data:`CONTACT_THRESHOLD_N` (None if it never does)."""
    t = trace.time_s
    force = np.column_stack([trace[f"{sensor}.force_{a}"] for a in "xyz"])
    before = (t < after_s) & (t >= after_s - UNLOADED_WINDOW_S)
    if not before.any():
        before = np.arange(t.size) == max(int(np.searchsorted(t, after_s)) - 1, 0)
    unloaded = force[before].mean(axis=0)
    loaded = np.flatnonzero((t >= after_s) & (np.linalg.norm(force - unloaded, axis=1) > CONTACT_THRESHOLD_N))
    return float(t[loaded[0]]) if loaded.size else None


def plot_effort(session: Session, trace: Trace, out: Path, joint: str) -> None:
    """``effort.png`` (and ``.svg``): the joint's effort over the run [N or N·m], its effort limit
    lines and the run's events."""
    figures.plot_series(out / "effort.png", trace.time_s, {f"{joint} effort": trace.joint(joint, "effort")},
                        title=f"{session.scenario.name}: {joint} effort", ylabel="effort",
                        unit=units(session, joint).effort, levels=effort_limit_levels(session, joint),
                        events=run_events(session, trace))


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

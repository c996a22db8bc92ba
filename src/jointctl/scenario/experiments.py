"""Turn a recorded run into metrics and figures, with the theory they are compared to.

A scenario's ``analysis`` names one of :data:`ANALYSES`. Each analysis reads
the trace, writes PNG figures into the output folder and returns the metrics
(measured figures plus an ``expected`` mapping of the same keys computed
from the model: moving mass, joint damping, controller gains, gravity).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from jointctl.control.cartesian_admittance_controller import CartesianAdmittanceController
from jointctl.errors import ConfigError
from jointctl.model.dynamics import RobotDynamics
from jointctl.scenario.minimal_robot_analysis import analyse_minimal_robot_trajectory
from jointctl.scenario.session import Session
from jointctl.scenario.spec import flatten
from jointctl.tools import figures
from jointctl.tools.recorder import Trace, load_trace
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
    _plot_effort(session, trace, out, joint)
    metrics = result.as_dict()
    return {**metrics, "expected": expected, "plant": plant.__dict__}


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
    joint = _joint(session, params)
    freq = _sine_frequency_hz(session, joint, _command_config(session, joint), params)
    t = trace.time_s
    command, signal = trace.joint(joint, "command"), trace.joint(joint, quantity)
    result = sinusoid_response(t, command, signal, frequency_hz=freq,
                               start_s=float(params.get("start_s", default_start_s)))
    return joint, freq, t, command, signal, result, joint_plant(session, joint)


def _plot_effort(session: Session, trace: Trace, out: Path, joint: str) -> None:
    figures.plot_series(out / "effort.png", trace.time_s, {f"{joint} effort": trace.joint(joint, "effort")},
                        title=f"{session.scenario.name}: {joint} effort", ylabel="effort [N]")


def analyse_sine(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Position loop driven by a sinusoid: amplitude ratio and phase lag at the drive frequency."""
    joint, freq, t, cmd, pos, result, plant = _sine_fit(session, trace, params, "position", 1.0)
    ratio, lag = second_order_frequency_response(plant.moving_mass_kg, plant.kp,
                                                 plant.damping + plant.kd, 2 * math.pi * freq)
    figures.plot_command_and_position(out / "position.png", t, cmd, pos,
                                      title=f"{session.scenario.name}: {joint} sine tracking")
    _plot_effort(session, trace, out, joint)
    return {"phase_lag_deg": result.phase_lag_deg, "amplitude_ratio": result.amplitude_ratio,
            "frequency_hz": freq, "periods_used": result.periods_used,
            "expected": {"phase_lag_deg": float(lag), "amplitude_ratio": float(ratio)},
            "plant": plant.__dict__}


def analyse_velocity_sine(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Velocity loop driven by a sinusoid: first-order gain and phase lag."""
    joint, freq, t, cmd, vel, result, plant = _sine_fit(session, trace, params, "velocity", 0.5)
    ratio, lag = first_order_frequency_response(plant.moving_mass_kg, plant.kp, plant.damping,
                                                2 * math.pi * freq)
    figures.plot_command_and_position(out / "velocity.png", t, cmd, vel, ylabel="velocity [m/s]",
                                      command_label="velocity command", position_label="velocity",
                                      title=f"{session.scenario.name}: {joint} velocity tracking")
    figures.plot_series(out / "position.png", t, {f"{joint} position": trace.joint(joint, "position")},
                        title=f"{session.scenario.name}: {joint} position", ylabel="position [m]")
    _plot_effort(session, trace, out, joint)
    return {"velocity_amplitude_ratio": result.amplitude_ratio,
            "velocity_phase_lag_deg": result.phase_lag_deg, "frequency_hz": freq,
            "expected": {"velocity_amplitude_ratio": float(ratio), "velocity_phase_lag_deg": float(lag)},
            "plant": plant.__dict__}


CONTACT_THRESHOLD_N = 1.0  # sensed force beyond the unloaded reading that counts as contact
STEADY_WINDOW_S = 1.0      # steady values are means over the last second of the run


def contact_episodes(force_z: np.ndarray, unloaded_n: float) -> int:
    """Separate contact episodes: times the sensed load rises above the threshold."""
    loaded = np.abs(force_z - unloaded_n) > CONTACT_THRESHOLD_N
    return int(np.count_nonzero(loaded[1:] & ~loaded[:-1]) + (1 if loaded[0] else 0))


def _object(session: Session, params: dict[str, Any]):
    objects = session.scenario.objects
    if not objects:
        raise ConfigError("the analysis needs an object dropped on the robot",
                          source=session.scenario.source, field="objects")
    return objects[0]


def _sensor(session: Session, params: dict[str, Any]) -> str:
    sensor = params.get("sensor")
    if sensor not in session.hardware.sensor_names:
        raise ConfigError("names no force-torque sensor of the robot", source=session.scenario.source,
                          field="analysis.sensor", value=sensor)
    return sensor


def _sensor_link_mass(session: Session, sensor: str) -> float:
    """Mass [kg] the sensor carries when unloaded: its own link (the plate)."""
    spec = next(s for s in session.robot.sensors if s.name == sensor)
    inertial = session.robot.link(spec.link).inertial
    return inertial.mass_kg if inertial else 0.0


def analyse_drop_weight(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """A weight dropped on the position-controlled robot: impacts, peak and steady forces (fig. 11.5)."""
    joint, sensor, weight = _joint(session, params), _sensor(session, params), _object(session, params)
    t = trace.time_s
    effort, position = trace.joint(joint, "effort"), trace.joint(joint, "position")
    force_z = trace[f"{sensor}.force_z"]
    steady = t >= t[-1] - STEADY_WINDOW_S
    before = (t < weight.spawn_at_s) & (t >= weight.spawn_at_s - 0.1)
    plant = joint_plant(session, joint)
    g = -plant.gravity_along_axis_m_s2
    plate = _sensor_link_mass(session, sensor)
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
            "steady_position_m": float(trace.joint(joint, "command")[-1]) - expected_effort / plant.kp,
        },
        "plant": plant.__dict__,
    }
    name = session.scenario.name
    figures.plot_series(out / "effort_and_force.png", t,
                        {f"{joint} effort [N]": effort, f"{sensor} force z [N]": force_z},
                        title=f"{name}: actuator effort and sensed force", ylabel="force [N]")
    figures.plot_command_and_position(out / "position.png", t, trace.joint(joint, "command"), position,
                                      title=f"{name}: {joint} position")
    return metrics


def nac_loaded_decay_rate(*, moving_mass_kg: float, load_kg: float, joint_damping: float, velocity_gain: float,
                          mass: float, stiffness: float, damping: float, period_s: float,
                          joint_state_every: int = 1, force_every: int = 1) -> float:
    """Linear theory of the 1-DOF NAC carrying a load: the decay rate [1/s] of its slowest mode
    (negative: the loop is unstable and the motion grows), cycle by cycle as jointctl's loop runs it.

    Around the loaded rest point the load moves with the piston, so the sensor reads
    ``F = -load·(g + a)`` with ``a`` the acceleration of the step before the reading. Each cycle
    the admittance controller takes the signals that are due (position and velocity every
    ``joint_state_every`` cycles, force every ``force_every``; held in between), integrates
    ``v_ref += (K (x_att - x) - B v + F) / M · dt``; the velocity controller (P only) applies
    ``Kv (v_ref - v)`` on the moving mass with the joint's damping (implicit, as MuJoCo's Euler
    integrator treats it), then the step integrates velocity and position (semi-implicit Euler).
    The map over one common sample period is linear; its spectral radius ρ gives the rate
    ``-ln(ρ) / period``. Valid while the load stays on the sensor (small motions); the velocity
    clamp and the load lifting off are the non-linearities it leaves out.
    """
    m, dt = moving_mass_kg + load_kg, period_s

    def cycle(s: np.ndarray, sample_state: bool, sample_force: bool) -> np.ndarray:
        x, v, a_before, v_ref, x_held, v_held, f_held = s  # deviations from the loaded rest
        if sample_state:
            x_held, v_held = x, v
        if sample_force:
            f_held = -load_kg * a_before
        v_ref = v_ref + (-stiffness * x_held - damping * v_held + f_held) / mass * dt
        a = (velocity_gain * (v_ref - v) - joint_damping * v) / (m + dt * joint_damping)
        v = v + a * dt
        return np.array([x + v * dt, v, a, v_ref, x_held, v_held, f_held])

    cycles = math.lcm(joint_state_every, force_every)
    monodromy = np.eye(7)
    for k in range(cycles):
        step = np.column_stack([cycle(e, k % joint_state_every == 0, k % force_every == 0) for e in np.eye(7)])
        monodromy = step @ monodromy
    radius = float(np.max(np.abs(np.linalg.eigvals(monodromy))))
    return -math.log(radius) / (cycles * dt)


def oscillation_decay_rate(time_s: np.ndarray, residual: np.ndarray, *, upper: float = 0.01,
                           lower: float = 1e-5) -> float:
    """Measured decay rate [1/s] of a ringing: a straight-line fit of ln|peak| against time over
    the peaks of ``|residual|`` below ``upper`` (after the last one above it: the landing) and
    above ``lower`` (before numerical noise). NaN with fewer than three such peaks."""
    r = np.abs(residual)
    peaks = np.flatnonzero((r[1:-1] > r[:-2]) & (r[1:-1] >= r[2:])) + 1
    large = peaks[r[peaks] > upper]
    if large.size:
        peaks = peaks[peaks > large[-1]]
    peaks = peaks[r[peaks] >= lower]
    if peaks.size < 3:
        return math.nan
    return -float(np.polyfit(time_s[peaks], np.log(r[peaks]), 1)[0])


#: Controller keys a ``nac_drop`` comparison may set: which signals the controller holds, at which rate.
NAC_SAMPLING_KEYS = ("joint_state_rate_hz", "force_rate_hz")


def _nac_comparisons(session: Session, params: dict[str, Any]) -> dict[str, dict[str, float]]:
    compare = params.get("compare") or {}
    source = session.scenario.source
    if not isinstance(compare, dict):
        raise ConfigError("must map a name to the rates it samples at", source=source, field="analysis.compare",
                          value=compare)
    for label, rates in compare.items():
        field = f"analysis.compare.{label}"
        if not str(label).isidentifier():
            raise ConfigError("must be a name made of letters, digits and _", source=source, field=field)
        if not isinstance(rates, dict) or not rates or set(rates) - set(NAC_SAMPLING_KEYS):
            raise ConfigError(f"must set {' and/or '.join(NAC_SAMPLING_KEYS)}", source=source, field=field,
                              value=rates)
    return compare


def analyse_nac_drop(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """Natural admittance control catching a weight (fig. 11.6), run inside the loop and, for each
    entry of ``compare``, again with the controller holding signals at lower rates
    (``{name: {joint_state_rate_hz: .., force_rate_hz: ..}}``), as a node fed over topics does.

    For each run: the rest position against statics (``x_att + F/K`` with the force sensed at rest),
    the peak to peak at rest, the settling time into ``settle_band_m`` (default 0.1 mm) of that rest
    point from the first contact, the lift-offs of the weight at rest, and the decay rate of the
    ringing against :func:`nac_loaded_decay_rate`. Keys of a comparison run carry its name as a prefix.
    """
    joint, sensor, weight = _joint(session, params), _sensor(session, params), _object(session, params)
    nac = session.manager.controller(params.get("controller", ""))
    compare = _nac_comparisons(session, params)
    band = float(params.get("settle_band_m", 1e-4))
    plant = joint_plant(session, joint)
    load = weight.mass_kg + _sensor_link_mass(session, sensor)
    dt = session.loop.period_s
    t = trace.time_s
    steady = t >= t[-1] - STEADY_WINDOW_S
    before = (t < weight.spawn_at_s) & (t >= weight.spawn_at_s - 0.1)
    force_z = trace[f"{sensor}.force_z"]
    unloaded_force = float(force_z[before].mean())

    def every(rates: dict[str, float], key: str) -> int:
        rate = rates.get(key)
        return max(1, round(1.0 / (rate * dt))) if rate else 1

    def run_metrics(run: Trace, prefix: str, rates: dict[str, float]) -> tuple[dict, dict]:
        position, force = run.joint(joint, "position"), run[f"{sensor}.force_z"]
        rest_force = float(force[steady].mean())
        expected_rest = nac.attractor + rest_force / nac.stiffness
        contact = np.flatnonzero(np.abs(force - unloaded_force) > CONTACT_THRESHOLD_N)
        first_contact = float(t[contact[0]]) if contact.size else math.nan
        outside = np.flatnonzero(np.abs(position - expected_rest) > band)
        settled_at = float(t[outside[-1] + 1]) if outside.size and outside[-1] + 1 < len(t) else math.nan
        on_disk = np.abs(force[steady] - unloaded_force) > CONTACT_THRESHOLD_N
        measured = {
            "rest_position_loaded_m": float(position[steady].mean()),
            "steady_sensor_force_z_n": rest_force,
            "peak_to_peak_at_rest_m": float(np.ptp(position[steady])),
            "settling_time_s": settled_at - first_contact,
            "weight_lift_offs_at_rest": int(np.count_nonzero(on_disk[:-1] & ~on_disk[1:])),
            "decay_rate_1_per_s": oscillation_decay_rate(t, position - expected_rest),
        }
        decay = nac_loaded_decay_rate(
            moving_mass_kg=plant.moving_mass_kg, load_kg=load, joint_damping=plant.damping,
            velocity_gain=plant.kp, mass=nac.mass, stiffness=nac.stiffness, damping=nac.damping,
            period_s=dt, joint_state_every=every(rates, "joint_state_rate_hz"),
            force_every=every(rates, "force_rate_hz"))
        # Statics predict a rest point only for a loop that comes to rest (decay > 0).
        expected = {"rest_position_loaded_m": expected_rest} if decay > 0 else {}
        expected["decay_rate_1_per_s"] = decay
        if prefix:
            measured.update({key: float(rates[key]) for key in NAC_SAMPLING_KEYS if key in rates})
        return ({prefix + k: v for k, v in measured.items()}, {prefix + k: v for k, v in expected.items()})

    metrics, expected = run_metrics(trace, "", {})
    rest_unloaded = float(trace.joint(joint, "position")[before].mean())
    metrics = {
        "rest_position_unloaded_m": rest_unloaded,
        **metrics,
        "expected_rest_position_loaded_m": expected["rest_position_loaded_m"],
        "peak_sensor_force_n": float(np.max(np.abs(force_z))),
        "settle_band_m": band,
    }
    expected["rest_position_unloaded_m"] = nac.attractor + unloaded_force / nac.stiffness
    series = {"in the loop: every signal at the loop rate": trace.joint(joint, "position")}
    for label, rates in compare.items():
        run = _run_variant(session, out / label, {f"{nac.name}.{key}": value for key, value in rates.items()})
        more, more_expected = run_metrics(run, f"{label}_", rates)
        metrics.update(more)
        expected.update(more_expected)
        held = ", ".join(f"{key.removesuffix('_rate_hz').replace('_', ' ')} at {value:g} Hz"
                         for key, value in rates.items())
        series[f"{label}: {held}"] = run.joint(joint, "position")
    metrics["expected"] = expected
    name = session.scenario.name
    figures.plot_series(out / "position.png", t, series, title=f"{name}: {joint} position",
                        ylabel="position [m]")
    figures.plot_series(out / "force.png", t, {f"{sensor} force z": force_z},
                        title=f"{name}: sensed force", ylabel="force [N]")
    return metrics


def _run_variant(session: Session, out: Path, controller_overrides: dict[str, Any],
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


def analyse_nac_catch(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """The 7-DOF arm's Cartesian natural admittance control catching a dropped weight (fig. 11.7),
    and the same run with the chapter's damping (``chapter_damping``, default B = 10·I).

    The flange position is the forward kinematics of the recorded joint positions (the robot's
    own model); the sensed force is rotated into the base frame and the controller's tare is
    subtracted, as the controller does. Rest values are means over the last
    ``steady_window_s`` (default 1 s); the unloaded rest is the mean over the 0.1 s before the
    weight appears; the expected loaded rest is ``p_att + K⁻¹·F`` for the mean force F of the
    same window. First contact: the tared vertical force departs from its unloaded value by
    more than CONTACT_THRESHOLD_N. ``overshoot_m``: how far the flange goes below its loaded
    rest point after the first contact. ``settling_time_s``: from the first contact until the
    flange's (3-D) distance from its loaded rest point stays within a band of 2 % of the sag
    (unloaded minus loaded rest height) or 1 mm, whichever is larger; NaN if it never does.
    The chapter-damping run is measured against the main run's loaded rest point (the statics
    do not depend on B, and that run may lose its weight, so has no loaded rest of its own);
    ``*_load_lost_s`` is when the sensed load vanished for good (NaN while it is held).
    The weight's final position, in the flange frame, must be over the plate and at the
    height of resting on it (``weight_on_plate``).
    """
    sensor, weight = _sensor(session, params), _object(session, params)
    nac = session.manager.controller(params.get("controller", ""))
    if not isinstance(nac, CartesianAdmittanceController):
        raise ConfigError("must name a CartesianAdmittanceController", source=session.scenario.source,
                          field="analysis.controller", value=params.get("controller"))
    window_s = float(params.get("steady_window_s", STEADY_WINDOW_S))
    chapter_damping = [float(b) for b in params.get("chapter_damping", [10.0, 10.0, 10.0])]
    sensor_link = next(s for s in session.robot.sensors if s.name == sensor).link
    dynamics = RobotDynamics(session.robot, joints=nac.joint_names)  # the robot's own model

    def catch(run: Trace, rest: np.ndarray | None = None) -> dict[str, Any]:
        t = run.time_s
        q = np.column_stack([run.joint(j, "position") for j in nac.joint_names])
        p, _ = dynamics.poses(nac.frame, q)
        sensed = np.column_stack([run[f"{sensor}.force_{a}"] for a in "xyz"])
        force = np.einsum("nij,nj->ni", dynamics.poses(sensor_link, q)[1], sensed) - nac.tare_force
        steady = t >= t[-1] - window_s
        before = (t < weight.spawn_at_s) & (t >= weight.spawn_at_s - 0.1)
        if rest is None:
            rest = p[steady].mean(axis=0)
        unloaded, unloaded_force = p[before].mean(axis=0), force[before].mean(axis=0)
        loaded = (t >= weight.spawn_at_s) & (np.abs(force[:, 2] - unloaded_force[2]) > CONTACT_THRESHOLD_N)
        contact = np.flatnonzero(loaded)
        if not contact.size:
            raise ConfigError("the weight never reached the sensor plate", source=session.scenario.source,
                              field="objects[0].xyz", value=list(weight.xyz))
        first, last = int(contact[0]), int(contact[-1])
        band = max(0.02 * abs(rest[2] - unloaded[2]), 0.001)
        outside = np.flatnonzero(np.linalg.norm(p - rest, axis=1) > band)
        settled = int(outside[-1]) + 1 if outside.size else first
        return {
            "t": t, "p": p, "force": force, "sensed": sensed, "rest": rest, "unloaded": unloaded,
            "steady_force": force[steady].mean(axis=0), "unloaded_force": unloaded_force,
            "first_contact_s": float(t[first]),
            "load_lost_s": float(t[last + 1]) if last + 1 < len(t) else math.nan,
            "overshoot_m": max(0.0, float(rest[2] - p[first:, 2].min())),
            "settling_time_s": float(t[settled] - t[first]) if settled < len(t) else math.nan,
            "band_m": band,
        }

    main = catch(trace)
    chapter = catch(_run_variant(session, out / "chapter_damping", {f"{nac.name}.damping": chapter_damping}),
                    rest=main["rest"])
    expected_rest = nac.attractor + main["steady_force"] / nac.stiffness
    expected_sag = (main["unloaded_force"][2] - main["steady_force"][2]) / nac.stiffness[2]

    # Where the weight ended, in the flange frame, against the plate's top and radius.
    dynamics.set_pose([trace.joint(j, "position")[-1] for j in nac.joint_names], inertia=False)
    flange = dynamics.frame(nac.frame)
    weight_p, _ = session.world.body_pose(weight.name)
    offset = flange.rotation.T @ (weight_p - flange.position)
    plate = next((c for c in session.robot.link(sensor_link).collisions if c.geometry.kind == "cylinder"),
                 None)
    plate_top = plate.origin.xyz[2] + plate.geometry.length_m / 2 if plate else 0.0
    plate_radius = plate.geometry.radius_m if plate else math.inf
    resting_height = plate_top + weight.half_height_m
    on_plate = bool(math.hypot(offset[0], offset[1]) <= plate_radius
                    and abs(offset[2] - resting_height) <= 0.01)

    metrics: dict[str, Any] = {
        "flange_rest_position_m": main["rest"].tolist(),
        "expected_flange_rest_position_m": expected_rest.tolist(),
        "flange_unloaded_rest_position_m": main["unloaded"].tolist(),
        "steady_sensor_force_base_frame_n": main["steady_force"].tolist(),
        "tare_force_base_frame_n": nac.tare_force.tolist(),
        "rest_error_m": float(np.linalg.norm(main["rest"] - expected_rest)),
        "sag_m": float(main["unloaded"][2] - main["rest"][2]),
        "peak_sensor_force_n": float(np.max(np.linalg.norm(main["sensed"], axis=1))),
        "first_contact_s": main["first_contact_s"],
        "overshoot_m": main["overshoot_m"],
        "settling_time_s": main["settling_time_s"],
        "settling_band_m": main["band_m"],
        "load_lost_s": main["load_lost_s"],
        "damping_n_s_m": nac.damping.tolist(),
        "chapter_damping_n_s_m": chapter_damping,
        "chapter_damping_overshoot_m": chapter["overshoot_m"],
        "chapter_damping_settling_time_s": chapter["settling_time_s"],
        "chapter_damping_peak_sensor_force_n": float(np.max(np.linalg.norm(chapter["sensed"], axis=1))),
        "chapter_damping_load_lost_s": chapter["load_lost_s"],
        "weight_offset_in_flange_frame_m": offset.tolist(),
        "weight_resting_height_m": resting_height,
        "weight_on_plate": on_plate,
        "expected": {"flange_rest_position_m": expected_rest.tolist(),
                     "sag_m": float(expected_sag)},
    }
    name = session.scenario.name
    t = main["t"]
    figures.plot_series(out / "flange_z.png", t,
                        {f"B = {tuple(nac.damping.tolist())} N·s/m": main["p"][:, 2],
                         f"chapter: B = {tuple(chapter_damping)} N·s/m": chapter["p"][:, 2]},
                        title=f"{name}: flange height", ylabel="z [m]")
    figures.plot_series(out / "flange_xy.png", t,
                        {"x": main["p"][:, 0], "y": main["p"][:, 1],
                         "x, chapter damping": chapter["p"][:, 0], "y, chapter damping": chapter["p"][:, 1]},
                        title=f"{name}: flange x and y", ylabel="position [m]")
    forces = ({f"F{a} (base frame, tared)": main["force"][:, k] for k, a in enumerate("xyz")}
              | {"Fz, chapter damping": chapter["force"][:, 2]})
    contact_s = main["first_contact_s"]
    for suffix, zoom in (("", None), ("_impact", (contact_s - 0.05, contact_s + 0.3)),
                         ("_after_impact", (contact_s + 0.5, float(t[-1])))):
        label = f" ({suffix[1:].replace('_', ' ')})" if suffix else ""
        figures.plot_series(out / f"force{suffix}.png", t, forces, zoom=zoom,
                            title=f"{name}: sensed force{label}", ylabel="force [N]")
    return metrics


def _rms_tracking_error(trace: Trace, joint: str, start_s: float, end_s: float) -> float:
    """RMS of (reference - position) over [start_s, end_s]: how well the joint follows its reference."""
    t = trace.time_s
    window = (t >= start_s) & (t <= end_s)
    error = trace.joint(joint, "command")[window] - trace.joint(joint, "position")[window]
    return float(np.sqrt(np.mean(error**2)))


def analyse_trajectory_tracking(session: Session, trace: Trace, out: Path,
                                params: dict[str, Any]) -> dict[str, Any]:
    """A trajectory goal executed in jointctl's default and in the chapter's mode (figs. 11.8, 11.9)."""
    joint = _joint(session, params)
    if not session.goals:
        raise ConfigError("the analysis needs an accepted trajectory goal", source=session.scenario.source,
                          field="goals")
    goal = session.goals[0]
    start = goal.validated.start_time_s
    end = start + float(goal.validated.times_s[-1])
    chapter_overrides = params.get("chapter_mode") or {}
    chapter = _run_variant(session, out / "chapter_mode", dict(chapter_overrides))
    t = trace.time_s
    column = goal.trajectory.joint_names.index(joint)
    points_t = start + np.array([p.time_from_start_s for p in goal.trajectory.points])
    points_q = np.array([p.positions[column] for p in goal.trajectory.points])
    name = session.scenario.name
    figures.plot_series(out / "coarse_points.png", points_t, {"trajectory points": points_q},
                        title=f"{name}: the client's coarse points (fig. 11.8)", ylabel="position [m]",
                        markers=True)
    figures.plot_series(out / "interpolated_command.png", t,
                        {"chapter mode: linear, 100 Hz": chapter.joint(joint, "command"),
                         "jointctl: cubic, 1 kHz": trace.joint(joint, "command")},
                        title=f"{name}: interpolated command (fig. 11.9)", ylabel="position [m]")
    figures.plot_series(out / "position.png", t,
                        {"reference": trace.joint(joint, "command"),
                         "position, chapter mode": chapter.joint(joint, "position"),
                         "position, jointctl feed-forward": trace.joint(joint, "position")},
                        title=f"{name}: {joint} position", ylabel="position [m]")
    figures.plot_series(out / "tracking_error.png", t,
                        {"chapter mode": chapter.joint(joint, "command") - chapter.joint(joint, "position"),
                         "jointctl feed-forward": trace.joint(joint, "command") - trace.joint(joint, "position")},
                        title=f"{name}: tracking error", ylabel="reference - position [m]")
    chapter_rms = _rms_tracking_error(chapter, joint, start, end)
    ff_rms = _rms_tracking_error(trace, joint, start, end)
    return {
        "result": goal.status.value,
        "points": len(goal.trajectory.points),
        "duration_s": end - start,
        "rms_tracking_error_m_chapter_mode": chapter_rms,
        "rms_tracking_error_m_feedforward": ff_rms,
        "error_reduction": chapter_rms / ff_rms,
    }


def _rms_joint_error(trace: Trace, joints: tuple[str, ...], start_s: float, end_s: float) -> float:
    """RMS over joints and time of (reference - position) within [start_s, end_s]."""
    t = trace.time_s
    window = (t >= start_s) & (t <= end_s)
    errors = np.array([trace.joint(j, "command")[window] - trace.joint(j, "position")[window] for j in joints])
    return float(np.sqrt(np.mean(errors**2)))


def analyse_arm_pose(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """The arm moved to a pose in jointctl's default, in the chapter's streamer mode and with
    velocity feed-forward only; and the droop of the pose without gravity compensation."""
    if not session.goals:
        raise ConfigError("the analysis needs an accepted trajectory goal", source=session.scenario.source,
                          field="goals")
    goal = session.goals[0]
    joints = goal.validated.joint_names
    start = goal.validated.start_time_s + float(goal.validated.times_s[0])  # the first point: the pose it leaves
    end = goal.validated.start_time_s + float(goal.validated.times_s[-1])
    variants = {name: _run_variant(session, out / name, params.get(name) or {})
                for name in ("chapter_mode", "velocity_ff")}
    final = np.array([trace.joint(j, "position")[-1] for j in joints])
    target = goal.validated.positions[-1]
    metrics: dict[str, Any] = {
        "duration_s": end - start,
        "result": goal.status.value,
        "rms_tracking_error_rad_chapter_mode": _rms_joint_error(variants["chapter_mode"], joints, start, end),
        "rms_tracking_error_rad_velocity_ff": _rms_joint_error(variants["velocity_ff"], joints, start, end),
        "rms_tracking_error_rad_feedforward": _rms_joint_error(trace, joints, start, end),
        "final_error_rad": float(np.max(np.abs(final - target))),
    }
    metrics["error_reduction"] = (metrics["rms_tracking_error_rad_chapter_mode"]
                                  / metrics["rms_tracking_error_rad_feedforward"])
    t = trace.time_s
    name = session.scenario.name
    for label, run in (("jointctl", trace), *variants.items()):
        figures.plot_series(out / f"tracking_error_{label}.png", t,
                            {j: run.joint(j, "command") - run.joint(j, "position") for j in joints},
                            title=f"{name}: tracking error, {label.replace('_', ' ')}",
                            ylabel="reference - position [rad]")
    droop_params = params.get("uncompensated")
    if droop_params is not None:
        pose = dict(zip(joints, target.tolist()))
        droop = _run_variant(session, out / "uncompensated", droop_params, goals=(),
                             initial_positions=pose, duration_s=float(params.get("droop_duration_s", 10.0)))
        sag = np.array([droop.joint(j, "position")[-1] for j in joints]) - target
        metrics["uncompensated_droop_rad"] = float(np.max(np.abs(sag)))
        metrics["uncompensated_droop_by_joint_rad"] = sag.tolist()
        figures.plot_series(out / "uncompensated_droop.png", droop.time_s,
                            {j: droop.joint(j, "position") for j in joints},
                            title=f"{name}: holding the pose without gravity compensation",
                            ylabel="joint angle [rad]")
    return metrics


Analysis = Callable[[Session, Trace, Path, dict[str, Any]], dict[str, Any]]

ANALYSES: dict[str, Analysis] = {
    "step_response": analyse_step,
    "sine_response": analyse_sine,
    "velocity_sine_response": analyse_velocity_sine,
    "drop_weight": analyse_drop_weight,
    "nac_drop": analyse_nac_drop,
    "nac_catch": analyse_nac_catch,
    "trajectory_tracking": analyse_trajectory_tracking,
    "arm_pose": analyse_arm_pose,
    "minimal_robot_trajectory": analyse_minimal_robot_trajectory,
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
    if spec["type"] in _JOINT_ANALYSES:
        _joint(session, spec)
    return fn


_JOINT_ANALYSES = frozenset({"step_response", "sine_response", "velocity_sine_response", "drop_weight",
                             "nac_drop", "trajectory_tracking"})

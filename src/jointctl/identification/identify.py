"""``jointctl identify``: excite a joint of a simulated robot (or read a recorded trace) and fit its model.

On a robot, the joint's own position controller (the robot's ``position`` controller file, or
another named one) follows a :func:`~jointctl.identification.excitation.planned_chirp` from where
the joint rests while every other joint holds; the loop runs in simulated time. Its amplitude is the
largest whose predicted position, speed and effort (the loop's model driven by the chirp) stay inside
fractions of the joint's limits and the user's (the rule of :mod:`jointctl.identification.safety`).
A guard watches the measured motion: should the joint come within ``GUARD_FRACTION`` of the range of
a limit, or cross ``--workspace``, ``--max-velocity`` or ``--max-effort``, the reference ramps back
to the start and the identification is refused saying what, where and when. The share of the
excitation's cycles at the actuator's effort or velocity limit is measured (``excitation.saturation``
in the metrics); above ``saturation_share`` (1 %) nothing is fitted.
The recorded position, velocity and applied effort are fitted by
:func:`~jointctl.identification.plant_fit.fit_plant`, after subtracting the load the other joints'
recorded motion puts on the joint, computed from the robot's model
(:mod:`~jointctl.identification.coupling`). On hardware that servos the joint itself (a
robot another node serves on the ROS graph) :func:`identify_servoed` sends the same chirp to the
joint's position loop and fits the states as they arrived (:func:`fit_states`, their grid by
:func:`on_grid`); :func:`identify_states` fits states recorded elsewhere (a rosbag),
:func:`identify_trace` a ``trace.csv``.

Outputs (``out_dir``): ``trace.csv`` (robot runs), ``identify_<joint>.png`` (measured effort
against the fitted model's, and the position) and ``metrics.json``: ``mass_kg`` /
``damping_n_s_m`` / ``friction_n`` / ``gravity_load_n`` on a prismatic joint,
``inertia_kg_m2`` / ``damping_n_m_s_rad`` / ``friction_n_m`` / ``gravity_sin_n_m`` /
``gravity_cos_n_m`` on a revolute one, each with ``*_ci95``, and the fit's residual; ``coupling``
("model" or "none": states of one joint only) and ``coupling_rms`` [N or N·m], with ``coupling_pose``
(the others' positions the inertia is for) and the model's own ``model_inertia_kg_m2`` / ``model_mass_kg``
there; ``sample_period_s`` and ``acceleration`` (the differences); ``data``: samples received, given to
the fit and fitted, the ``outliers`` and all rows ``left_out`` (see
:mod:`~jointctl.identification.plant_fit`), the number of ``gaps`` and the longest ``GAPS_LISTED`` of
them cut (``at_s``, ``length_s``), ``span_s``, ``usable_s`` and ``share_used`` (of the recording;
``excitation_share_used`` of the excitation); ``warnings``: what makes the figures doubtful
(:func:`fit_warnings`), which the command line prints too. ``metrics.json`` is strict JSON: a figure
that is not a finite number (not measured, or unbounded) is ``null``
(:mod:`jointctl.recording.metrics_file`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointctl.control.joint_controllers import JointPositionController, derivative_law
from jointctl.errors import ConfigError
from jointctl.identification.coupling import Coupling, chain_coupling
from jointctl.identification.excitation import Chirp, plan_identification
from jointctl.identification.frequency_response import held_reference, servo_reference, session_gravity
from jointctl.identification.plant_fit import (MAX_SHIFT_CYCLES, MIN_SAMPLES, IdentificationError, PlantFit,
                                               difference_rows, fit_plant, resample_uniform, stamp_period, stretches)
from jointctl.identification.safety import (DEFAULT, GUARD_FRACTION, Guard, Safety, SaturationMonitor, run_guarded,
                                            saturation_text)
from jointctl.scenario.session import Session
from jointctl.scenario.spec import Scenario
from jointctl.recording.figures import Panel, plot_panels, plot_series
from jointctl.recording.metrics_file import write_metrics
from jointctl.recording.trace import load_trace
from jointctl.recording.units import joint_units

#: Rest before the excitation, for the joint to settle where its controller holds it [s].
SETTLE_S = 1.0
#: Rest after it, for the joint to come to rest again [s].
SETTLE_AFTER_S = 2.0
#: A fit whose model explains less of the effort's variance than this is reported with a warning.
R_SQUARED_WARNING = 0.95
#: ... as is one that left more than this share of its rows out (outliers and, at sparse rates, their
#: neighbours): a robust fit vouches for a majority only.
LEFT_OUT_WARNING = 0.5
#: metrics.json lists the longest this many gaps cut (``data.gaps`` counts them all).
GAPS_LISTED = 20


def identify_on_robot(scenario: Scenario, joint: str, *, out_dir: str | Path | None = None,
                      amplitude: float | None = None, duration_s: float = 10.0, f_start_hz: float = 0.2,
                      f_end_hz: float = 3.0, fit_friction: bool = True, safety: Safety | None = None,
                      plant: dict | None = None) -> tuple[PlantFit, dict]:
    """Excite ``joint`` of the scenario's robot and fit it; (fit, metrics). See the module docstring."""
    return identify_in_session(Session(scenario, out_dir=out_dir), joint, out_dir=out_dir, amplitude=amplitude,
                               duration_s=duration_s, f_start_hz=f_start_hz, f_end_hz=f_end_hz,
                               fit_friction=fit_friction, safety=safety, plant=plant)


def identify_in_session(session, joint: str, *, out_dir: str | Path | None = None, amplitude: float | None = None,
                        duration_s: float = 10.0, f_start_hz: float = 0.2, f_end_hz: float = 3.0,
                        fit_friction: bool = True, safety: Safety | None = None,
                        plant: dict | None = None) -> tuple[PlantFit, dict]:
    """The same in a session that exists (a new one, or a live robot's: anything with ``loop``,
    ``hardware``, ``robot``, ``manager`` and ``run``), through the joint's own position controller.
    ``safety`` (limits, fractions) and ``plant`` (an identification's metrics) plan the excitation."""
    _movable(session.robot, joint)
    controller = session.manager.commanding(joint)
    if not isinstance(controller, JointPositionController):
        raise ConfigError("the joint needs a started effort_controllers/JointPositionController to follow the "
                          "excitation (use a position controller file)", field="--joint", value=joint)
    hardware = session.hardware
    index = hardware.joint_index(joint)
    samples: list[tuple] = []

    def record(time_s: float) -> None:  # every joint: the others' motion loads this one
        samples.append((time_s, tuple(hardware.position), tuple(hardware.velocity), hardware.effort[index]))

    session.loop.add_observer(record)
    try:
        excitation = _excite(session, joint, controller.set_reference, amplitude=amplitude, duration_s=duration_s,
                             f_start_hz=f_start_hz, f_end_hz=f_end_hz, safety=safety, plant=plant,
                             start=controller.reference_input[0])
    finally:
        session.loop.remove_observer(record)
    t, q_all, qd_all, u = (np.array(column) for column in zip(*samples))
    q, qd = q_all[:, index], qd_all[:, index]
    coupling = chain_coupling(session.robot, joint, hardware.joint_names, t, q_all, qd_all,
                              gravity_m_s2=session.manager.context.gravity_m_s2)
    fit = fit_plant(t, q, qd, u, joint_type=session.robot.joint(joint).type, fit_friction=fit_friction,
                    coupling_torque=coupling.torque, inertia_scale=coupling.inertia_scale)
    return fit, _finish(fit, joint, excitation, out_dir, t, q, qd, u, coupling, loop_period_s=session.loop.period_s)


def identify_servoed(session: Session, joint: str, *, out_dir: str | Path | None = None,
                     amplitude: float | None = None, duration_s: float = 10.0, f_start_hz: float = 0.2,
                     f_end_hz: float = 3.0, fit_friction: bool = True, safety: Safety | None = None,
                     plant: dict | None = None) -> tuple[PlantFit, dict]:
    """The same on hardware that servos the joint itself and records every state it receives (a
    robot served on the ROS graph, :class:`~jointctl.ros.served_hardware.ServedRobotHardware`):
    the chirp goes to the joint's position command interface (the served position loop's
    reference), the fit takes the states as they arrived, put on a uniform grid; forward
    differences when they came every control period, central ones when sparser. ``session`` runs
    paced as it is (the wall clock) and starts no controller that commands the joint."""
    hardware = session.hardware
    _movable(session.robot, joint)
    loop, set_reference = servo_reference(hardware, joint)
    if loop != "position":
        raise ConfigError("the hardware has no position loop for it (identification follows a position "
                          "reference)", field="--joint", value=joint)
    hardware.start_recording()
    excitation = _excite(session, joint, set_reference, amplitude=amplitude, duration_s=duration_s,
                         f_start_hz=f_start_hz, f_end_hz=f_end_hz, safety=safety, plant=plant,
                         start=held_reference(hardware, joint))
    stamps, positions, velocities, efforts = hardware.recorded_all(joint)
    k = hardware.joint_index(joint)
    states = fit_states(session.robot, joint, hardware.joint_names, stamps, positions, velocities,
                        [row[k] for row in efforts], loop_period_s=session.loop.period_s,
                        gravity_m_s2=session.scenario.gravity_m_s2, fit_friction=fit_friction)
    return states.fit, _finish(states.fit, joint, excitation, out_dir, states.t, states.q, states.qd, states.u,
                               states.coupling, received=len(stamps), loop_period_s=session.loop.period_s)


@dataclass(frozen=True)
class FittedStates:
    """Joint states fitted (:func:`fit_states`): the fit, and what it was fitted to on its grid: ``t`` [s]
    from 0, the joint's ``q``, ``qd``, ``u``, and the chain's ``coupling``."""

    fit: PlantFit
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    u: np.ndarray
    coupling: Coupling


def fit_states(robot, joint: str, joint_names, stamps, positions, velocities, effort, *, loop_period_s: float,
               gravity_m_s2=(0.0, 0.0, -9.81), fit_friction: bool = True) -> FittedStates:
    """Fit ``joint`` of ``robot`` from joint states as they arrived: ``stamps`` [s], every joint's
    ``positions`` and ``velocities`` (one row per state, columns in the order of ``joint_names``) and
    the joint's ``effort``, from a control loop of ``loop_period_s`` [s], put on a grid
    (:func:`on_grid`); the other joints' load comes off with the robot's model (:func:`chain_coupling`)."""
    n = len(joint_names)
    t, columns, every_cycle = on_grid(stamps, [*np.asarray(positions, dtype=float).T,
                                               *np.asarray(velocities, dtype=float).T, effort], loop_period_s)
    q_all, qd_all, u = np.column_stack(columns[:n]), np.column_stack(columns[n:2 * n]), columns[-1]
    acceleration = "forward" if every_cycle else "central"
    coupling = chain_coupling(robot, joint, joint_names, t, q_all, qd_all, gravity_m_s2=gravity_m_s2,
                              acceleration=acceleration)
    k = list(joint_names).index(joint)
    q, qd = q_all[:, k], qd_all[:, k]
    fit = fit_plant(t, q, qd, u, joint_type=robot.joint(joint).type, fit_friction=fit_friction,
                    acceleration=acceleration, max_shift_cycles=MAX_SHIFT_CYCLES if every_cycle else 0,
                    coupling_torque=coupling.torque, inertia_scale=coupling.inertia_scale)
    return FittedStates(fit, t, q, qd, u, coupling)


def on_grid(stamps, columns, loop_period_s: float) -> tuple[np.ndarray, list[np.ndarray], bool]:
    """(``t`` [s] from 0, ``columns`` on it, whether the states came every cycle) for joint states
    stamped ``stamps`` [s] from a loop of ``loop_period_s`` (:func:`resample_uniform`). States of every
    cycle (their period under 1.5 loop periods) keep their cycles' grid and are fitted with forward
    differences and the effort's alignment searched (0 to ``MAX_SHIFT_CYCLES`` cycles); sparser ones
    (joint states at 50 Hz from a 1 kHz loop) are interpolated onto a grid of their period and fitted
    with central differences, the effort where it was sampled (a shift of one sample would be twenty
    cycles: the search would only fit the noise)."""
    if len(stamps) < MIN_SAMPLES:
        raise IdentificationError(f"too few joint states to fit (at least {MIN_SAMPLES})", field="samples",
                                  value=len(stamps))
    stamps = np.asarray(stamps, dtype=float)
    period = stamp_period(np.unique(stamps))
    every_cycle = period < 1.5 * loop_period_s
    t, *on = resample_uniform(stamps - stamps.min(), *(np.asarray(c, dtype=float) for c in columns),
                              cycles=every_cycle, period_s=period)
    return t, on, every_cycle


def identify_states(stamps, q, qd, u, joint: str, joint_type: str, *, source: str, loop_period_s: float = 0.001,
                    out_dir: str | Path | None = None, fit_friction: bool = True) -> tuple[PlantFit, dict]:
    """Fit ``joint`` from joint states as they were received (``stamps`` [s], not necessarily
    uniform: a bag, a subscriber) from a loop of ``loop_period_s``, put on a grid (:func:`on_grid`;
    one joint: no coupling). ``source`` names where they came from."""
    t, (q, qd, u), every_cycle = on_grid(stamps, [q, qd, u], loop_period_s)
    fit = fit_plant(t, q, qd, u, joint_type=joint_type, fit_friction=fit_friction,
                    acceleration="forward" if every_cycle else "central",
                    max_shift_cycles=MAX_SHIFT_CYCLES if every_cycle else 0)
    metrics = _metrics(fit, joint, received=len(stamps), loop_period_s=loop_period_s)
    metrics["trace"] = source
    if out_dir is not None:
        _write(out_dir, joint, fit, metrics, t, q, qd, u)
    return fit, metrics


def _movable(robot, joint: str) -> None:
    if not robot.has_joint(joint) or not robot.joint(joint).is_movable:
        movable = ", ".join(j.name for j in robot.movable_joints)
        raise ConfigError(f"no movable joint of that name (movable: {movable})", field="--joint", value=joint)


def _excite(session: Session, joint: str, set_reference, *, amplitude, duration_s, f_start_hz,
            f_end_hz, safety: Safety | None = None, plant: dict | None = None,
            start: float | None = None) -> tuple[Chirp, float, float, dict]:
    """Run the planned chirp through ``set_reference`` (settle, excite, settle), its amplitude by the
    rule of :mod:`jointctl.identification.safety` on the joint's loop model (the plant from ``plant``
    or the robot model), from ``start`` [m or rad], the reference the loop holds (default: where the
    joint is), with the saturation counted and the limits guarded; (the chirp, the joint's
    lower and upper limits, a report of the plan and the saturation). SafetyStop when a limit was
    crossed (the joint brought back), IdentificationError when the actuator saturated in more than
    ``safety.saturation_share`` of the excitation's cycles (nothing fitted)."""
    safety = safety or DEFAULT
    hardware = session.hardware
    index = hardware.joint_index(joint)
    hardware.read()
    lower, upper, _ = session.robot.joint(joint).range_and_speed()
    rest = hardware.position[index] if start is None else float(start)
    chirp, allowance, planned_on = plan_identification(
        session.robot, joint, rest, pose=dict(zip(hardware.joint_names, hardware.position)),
        loop=loop_settings(session, joint), period_s=session.loop.period_s, gravity_m_s2=session_gravity(session),
        safety=safety, plant=plant, amplitude=amplitude, duration_s=duration_s, f_start_hz=f_start_hz,
        f_end_hz=f_end_hz, settle_after_s=SETTLE_AFTER_S)
    envelope = allowance.envelope
    guard = Guard(hardware, index, envelope, band=GUARD_FRACTION * (upper - lower)
                  if math.isfinite(upper - lower) else math.inf)
    monitor = SaturationMonitor(hardware, index, envelope.effort_limit, envelope.velocity_limit,
                                safety.saturation_margin)
    started = session.loop.time_s

    def excite(time_s: float) -> None:
        set_reference(guard.reference(time_s, chirp(time_s - started - SETTLE_S)))

    session.loop.add_input(excite)
    watchers = (monitor, guard.observe)  # bound once: removal compares identity
    for hook in watchers:
        session.loop.add_observer(hook)
    try:
        run_guarded(session, SETTLE_S + duration_s + SETTLE_AFTER_S, guard)
    finally:
        session.loop.remove_input(excite)
        for hook in watchers:
            session.loop.remove_observer(hook)
    if guard.trip is not None:
        raise guard.error("the excitation")
    share = monitor.share(started + SETTLE_S - 1e-9, started + SETTLE_S + duration_s - 1e-9)
    report = {"binds": allowance.binds, "safe_amplitude": allowance.amplitude, "planned_on": planned_on,
              "predicted": allowance.predicted(chirp.amplitude), "saturation": {**monitor.describe(), **share,
                                                                                 "threshold": safety.saturation_share}}
    if share["share"] > safety.saturation_share:
        raise IdentificationError(
            f"the actuator saturated: {saturation_text(share, monitor, envelope.unit)} during the excitation, more "
            f"than {100 * safety.saturation_share:g} %: the effort measured is not the effort that moved the plant, "
            "so nothing was fitted; give a smaller --amplitude, a lower --f-end-hz, or a --plant closer to the robot",
            field="saturation", value=round(share["share"], 4))
    return chirp, lower, upper, report


def loop_settings(session, joint: str) -> tuple[dict | None, str, bool, float | None]:
    """(gains ``{"p", "i", "d"}``, derivative law, whether its p alone holds gravity (a droop), effort
    limit) of the position loop that moves ``joint``: the session's JointPositionController, or a served
    ros_control or ros2_control loop (its gains through dynamic_reconfigure, or its pid_controller's
    parameters); (None, "error", False, None) when unknown (a loop without gains)."""
    controller = session.manager.commanding(joint)
    if isinstance(controller, JointPositionController):
        g = controller.pid.gains
        droops = not g.i and "gravity" not in controller.feedforward_terms
        return {"p": g.p, "i": g.i, "d": g.d}, controller.derivative, droops, controller.effort_limit
    hardware = session.hardware
    served = getattr(hardware, "controllers", None)
    if isinstance(served, dict) and joint in served and hasattr(hardware, "gains"):
        name = served[joint][1]
        gains = hardware.gains(name)
        if gains is None:  # the hardware's own servo (a forward command controller): no gains to model
            return None, "error", False, None
        parameters = hardware.controller_parameters().get(name, {})
        feedforward = parameters.get("feedforward", {}) if isinstance(parameters, dict) else {}
        droops = not gains.get("i") and not (isinstance(feedforward, dict) and feedforward.get("gravity"))
        return ({k: float(gains.get(k, 0.0)) for k in ("p", "i", "d")}, derivative_law(parameters), droops, None)
    return None, "error", False, None


def _finish(fit: PlantFit, joint: str, excitation: tuple[Chirp, float, float, dict], out_dir, t, q, qd, u,
            coupling: Coupling | None = None, *, received: int | None = None,
            loop_period_s: float | None = None) -> dict:
    chirp, lower, upper, report = excitation
    metrics = _metrics(fit, joint, received=len(t) if received is None else received, loop_period_s=loop_period_s)
    start = t[0] + SETTLE_S  # the excitation's window, and the share of it the gaps left
    lost = sum(max(0.0, min(at + length, start + chirp.duration_s) - max(at, start)) for at, length in fit.gaps)
    metrics["data"]["excitation_share_used"] = 1.0 - lost / chirp.duration_s
    if coupling is not None:
        metrics["coupling_pose"] = coupling.pose
        metrics["model_mass_kg" if fit.joint_type == "prismatic" else "model_inertia_kg_m2"] = coupling.model_inertia
    metrics["excitation"] = {"amplitude": chirp.amplitude, "f_start_hz": chirp.f_start_hz,
                             "f_end_hz": chirp.f_end_hz, "duration_s": chirp.duration_s, "start": chirp.start,
                             "position_min": float(q.min()), "position_max": float(q.max()),
                             "rest_before": float(q[t - t[0] <= SETTLE_S][-1]), "rest_after": float(q[-1]),
                             "lower": lower, "upper": upper, **report}
    if out_dir is not None:
        _write(out_dir, joint, fit, metrics, t, q, qd, u, coupling)
    return metrics


def identify_trace(path: str | Path, joint: str, joint_type: str, *, out_dir: str | Path | None = None,
                   fit_friction: bool = True) -> tuple[PlantFit, dict]:
    """Fit ``joint`` from a recorded ``trace.csv`` (every cycle recorded); (fit, metrics)."""
    path = Path(path)
    try:
        trace = load_trace(path)
    except (OSError, ValueError, StopIteration) as exc:
        raise ConfigError(f"cannot read the trace ({exc})", source=str(path)) from None
    try:
        t, q, qd, u = (trace.joint(joint, quantity) if quantity else trace.time_s
                       for quantity in (None, "position", "velocity", "effort"))
    except KeyError:
        raise ConfigError("no columns for that joint in the trace", source=str(path), field="--joint",
                          value=joint) from None
    fit = fit_plant(t, q, qd, u, joint_type=joint_type, fit_friction=fit_friction)
    metrics = _metrics(fit, joint)
    metrics["trace"] = str(path)
    if out_dir is not None:
        _write(out_dir, joint, fit, metrics, t, q, qd, u)
    return fit, metrics


def _metrics(fit: PlantFit, joint: str, *, received: int | None = None, loop_period_s: float | None = None) -> dict:
    prismatic = fit.joint_type == "prismatic"
    unit = {"inertia": "mass_kg" if prismatic else "inertia_kg_m2",
            "damping": "damping_n_s_m" if prismatic else "damping_n_m_s_rad",
            "friction": "friction_n" if prismatic else "friction_n_m"}
    metrics: dict = {"joint": joint, "joint_type": fit.joint_type}
    for name, key in unit.items():
        metrics[key] = getattr(fit, name)
        metrics[f"{key}_ci95"] = getattr(fit, f"{name}_ci95")
    if prismatic:
        metrics["gravity_load_n"] = fit.gravity_load
        metrics["gravity_load_n_ci95"] = fit.gravity_load_ci95
    else:
        metrics["gravity_sin_n_m"] = fit.gravity_sin
        metrics["gravity_cos_n_m"] = fit.gravity_cos
    metrics.update(residual_rms=fit.residual_rms, r_squared=fit.r_squared, samples=fit.samples,
                   effort_shift_cycles=fit.effort_shift_cycles, coupling=fit.coupling,
                   coupling_rms=fit.coupling_rms, sample_period_s=fit.sample_period_s,
                   acceleration=fit.acceleration)
    listed = sorted(sorted(fit.gaps, key=lambda gap: -gap[1])[:GAPS_LISTED])
    metrics["data"] = {"samples_received": fit.samples_given if received is None else int(received),
                       "samples_given": fit.samples_given, "samples_fitted": fit.samples,
                       "outliers": fit.outliers, "left_out": fit.left_out, "gaps": len(fit.gaps),
                       "gaps_cut": [{"at_s": at, "length_s": length} for at, length in listed],
                       "span_s": fit.span_s, "usable_s": fit.usable_s, "share_used": fit.share_used}
    metrics["warnings"] = fit_warnings(fit, loop_period_s)
    return metrics


def fit_warnings(fit: PlantFit, loop_period_s: float | None = None) -> list[str]:
    """What makes ``fit``'s figures doubtful, one sentence each (empty when nothing does): r² below
    ``R_SQUARED_WARNING``, more than ``LEFT_OUT_WARNING`` of the rows left out; and then,
    for states sparser than a control loop of ``loop_period_s`` [s], the rate they need and the
    ros_control parameter that sets it."""
    warnings = []
    if fit.r_squared < R_SQUARED_WARNING:
        warnings.append(f"a poor fit: the model explains only {fit.r_squared:.3g} of the effort's variance (r² below "
                        f"{R_SQUARED_WARNING:g}), so its figures are not the joint's")
    rows = fit.samples + fit.left_out
    if rows and fit.left_out / rows > LEFT_OUT_WARNING:
        share = 100 * fit.left_out / rows
        warnings.append(f"{fit.left_out} of the {rows} samples where the joint moves ({share:.0f} %) were left out "
                        f"({fit.outliers} outliers, their effort off the motion, and the samples next to them): "
                        "the fit rests on fewer than half")
    if warnings and fit.acceleration == "central" and loop_period_s:
        rate = 1.0 / loop_period_s
        warnings.append(f"the joint states came every {1e3 * fit.sample_period_s:.3g} ms, sparser than the "
                        f"{rate:.4g} Hz control loop: each holds one cycle's effort, which the motion between them "
                        f"does not show; publish them every cycle (joint_state_controller's publish_rate: {rate:g}) "
                        "and identify again")
    return warnings


def _write(out_dir, joint, fit: PlantFit, metrics: dict, t, q, qd, u, coupling: Coupling | None = None) -> None:
    """``identify_<joint>.png`` (and ``.svg``): the measured effort against the model's [N or N·m],
    the residual (measured minus model) below; ``identify_<joint>_position.png``: the excitation
    [m or rad]; ``metrics.json``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    split = stretches(t)
    shift = fit.effort_shift_cycles
    at, qdd = difference_rows(split.index, qd, split.dt, shift, fit.acceleration)
    unit = joint_units(fit.joint_type == "prismatic")
    measured = u[at + shift]
    series = {"measured effort": measured}
    if coupling is None:
        model = series["identified model"] = fit.effort(q[at], qd[at], qdd)
    else:  # the joint's own model plus the others' load computed from the robot's model
        load = np.nan_to_num(coupling.torque[at])
        model = fit.effort(q[at], qd[at], coupling.inertia_scale[at] * qdd) + load
        series["identified model + coupling"] = model
        series["coupling (robot model)"] = load
    # Below the fit, what it leaves unexplained: the measured effort minus the model's.
    plot_panels(out / f"identify_{joint}.png", t[at],
                [Panel(series, "effort", unit.effort, height=2.0),
                 Panel({"measured - model": measured - model}, "residual", unit.effort)],
                title=f"{joint}: measured effort against the identified model (R² {fit.r_squared:.5f})")
    plot_series(out / f"identify_{joint}_position.png", t, {"position": q},
                title=f"{joint}: the excitation", ylabel="position", unit=unit.position)
    write_metrics(out, metrics)  # strict JSON: a figure not measured or unbounded is null


__all__ = ["Chirp", "FittedStates", "fit_states", "fit_warnings", "identify_in_session", "identify_on_robot",
           "identify_servoed", "identify_states", "identify_trace", "on_grid"]

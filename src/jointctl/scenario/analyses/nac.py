"""The 1-DOF natural admittance controller catching a weight (figure 11.6), in the loop and with the
signals held as a node fed over topics holds them, against statics and the sampled loop's theory."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from jointctl.errors import ConfigError
from jointctl.metrics.expectations import share_of
from jointctl.scenario.analyses.common import (
    CONTACT_THRESHOLD_N,
    STEADY_WINDOW_S,
    analysed_joint,
    analysed_sensor,
    dropped_object,
    joint_plant,
    run_events,
    run_variant,
    sensor_link_mass,
    units,
)
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.trace import Trace


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
    joint, sensor = analysed_joint(session, params), analysed_sensor(session, params)
    weight = dropped_object(session)
    nac = session.manager.controller(params.get("controller", ""))
    compare = _nac_comparisons(session, params)
    band = float(params.get("settle_band_m", 1e-4))
    plant = joint_plant(session, joint)
    load = weight.mass_kg + sensor_link_mass(session, sensor)
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
        run = run_variant(session, out / label, {f"{nac.name}.{key}": value for key, value in rates.items()})
        more, more_expected = run_metrics(run, f"{label}_", rates)
        metrics.update(more)
        expected.update(more_expected)
        held = ", ".join(f"{key.removesuffix('_rate_hz').replace('_', ' ')} at {value:g} Hz"
                         for key, value in rates.items())
        series[f"{label}: {held}"] = run.joint(joint, "position")
    metrics["expected"] = expected
    # Rest positions: a share of the sag the load causes (loaded minus unloaded rest).
    sag = abs(expected["rest_position_loaded_m"] - expected["rest_position_unloaded_m"])
    metrics["margins"] = {key: share_of(sag, "sag") for key in expected if "rest_position" in key}
    name = session.scenario.name
    events = run_events(session, trace)
    figures.plot_series(out / "position.png", t, series, title=f"{name}: {joint} position",
                        ylabel="position", unit=units(session, joint).position, events=events)
    figures.plot_series(out / "force.png", t, {f"{sensor} force z": force_z},
                        title=f"{name}: sensed force", ylabel="force", unit="N", events=events)
    return metrics

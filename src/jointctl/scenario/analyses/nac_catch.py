"""The 7-DOF arm's Cartesian natural admittance control catching a weight (figure 11.7)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from jointctl.control.cartesian_admittance_controller import CartesianAdmittanceController
from jointctl.errors import ConfigError
from jointctl.metrics.expectations import share_of
from jointctl.model.dynamics import RobotDynamics
from jointctl.scenario.analyses.common import (
    CONTACT_THRESHOLD_N,
    STEADY_WINDOW_S,
    analysed_sensor,
    dropped_object,
    run_events,
    run_variant,
)
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.figures import Event
from jointctl.recording.trace import Trace


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
    sensor, weight = analysed_sensor(session, params), dropped_object(session)
    nac = session.manager.controller(params.get("controller", ""))
    if not isinstance(nac, CartesianAdmittanceController):
        raise ConfigError("must name a CartesianAdmittanceController", source=session.scenario.source,
                          field="analysis.controller", value=params.get("controller"))
    chapter_damping = [float(b) for b in params.get("chapter_damping", [10.0, 10.0, 10.0])]
    flange = FlangeRecord(session, nac, sensor, weight, float(params.get("steady_window_s", STEADY_WINDOW_S)))
    main = flange.catch(trace)
    chapter = flange.catch(run_variant(session, out / "chapter_damping", {f"{nac.name}.damping": chapter_damping}),
                           rest=main.rest)
    expected_rest = nac.attractor + main.steady_force / nac.stiffness
    expected_sag = (main.unloaded_force[2] - main.steady_force[2]) / nac.stiffness[2]
    offset, resting_height, on_plate = flange.weight_on_plate(trace)
    metrics: dict[str, Any] = {
        "flange_rest_position_m": main.rest.tolist(),
        "expected_flange_rest_position_m": expected_rest.tolist(),
        "flange_unloaded_rest_position_m": main.unloaded.tolist(),
        "steady_sensor_force_base_frame_n": main.steady_force.tolist(),
        "tare_force_base_frame_n": nac.tare_force.tolist(),
        "rest_error_m": float(np.linalg.norm(main.rest - expected_rest)),
        "sag_m": float(main.unloaded[2] - main.rest[2]),
        "peak_sensor_force_n": main.peak_sensed_force_n,
        "first_contact_s": main.first_contact_s,
        "overshoot_m": main.overshoot_m,
        "settling_time_s": main.settling_time_s,
        "settling_band_m": main.band_m,
        "load_lost_s": main.load_lost_s,
        "damping_n_s_m": nac.damping.tolist(),
        "chapter_damping_n_s_m": chapter_damping,
        "chapter_damping_overshoot_m": chapter.overshoot_m,
        "chapter_damping_settling_time_s": chapter.settling_time_s,
        "chapter_damping_peak_sensor_force_n": chapter.peak_sensed_force_n,
        "chapter_damping_load_lost_s": chapter.load_lost_s,
        "weight_offset_in_flange_frame_m": offset.tolist(),
        "weight_resting_height_m": resting_height,
        "weight_on_plate": on_plate,
        "expected": {"flange_rest_position_m": expected_rest.tolist(),
                     "sag_m": float(expected_sag)},
        "margins": {key: share_of(expected_sag, "sag") for key in ("flange_rest_position_m", "sag_m")},
    }
    # The impact as this analysis finds it (the tared base-frame force), beside the run's other events.
    events = [e for e in run_events(session, trace) if e.kind != "contact"]
    events.append(Event(main.first_contact_s, f"{weight.name} impact", "contact"))
    _plot(out, session.scenario.name, nac, chapter_damping, main, chapter, events)
    return metrics


@dataclass(frozen=True)
class Catch:
    """One run's flange motion and sensed force (base frame, tared) and the catch's figures."""

    t: np.ndarray
    p: np.ndarray
    force: np.ndarray
    sensed: np.ndarray
    rest: np.ndarray
    unloaded: np.ndarray
    steady_force: np.ndarray
    unloaded_force: np.ndarray
    first_contact_s: float
    load_lost_s: float
    overshoot_m: float
    settling_time_s: float
    band_m: float

    @property
    def peak_sensed_force_n(self) -> float:
        return float(np.max(np.linalg.norm(self.sensed, axis=1)))


class FlangeRecord:
    """Reads the flange's motion and the base-frame force out of a recorded run, with the robot's
    own model (forward kinematics of the recorded joint positions)."""

    def __init__(self, session: Session, nac: CartesianAdmittanceController, sensor: str, weight,
                 window_s: float) -> None:
        self.session, self.nac, self.sensor, self.weight, self.window_s = session, nac, sensor, weight, window_s
        self.sensor_link = next(s for s in session.robot.sensors if s.name == sensor).link
        self.dynamics = RobotDynamics(session.robot, joints=nac.joint_names)

    def catch(self, run: Trace, rest: np.ndarray | None = None) -> Catch:
        nac, weight, dynamics = self.nac, self.weight, self.dynamics
        t = run.time_s
        q = np.column_stack([run.joint(j, "position") for j in nac.joint_names])
        p, _ = dynamics.poses(nac.frame, q)
        sensed = np.column_stack([run[f"{self.sensor}.force_{a}"] for a in "xyz"])
        force = np.einsum("nij,nj->ni", dynamics.poses(self.sensor_link, q)[1], sensed) - nac.tare_force
        steady = t >= t[-1] - self.window_s
        before = (t < weight.spawn_at_s) & (t >= weight.spawn_at_s - 0.1)
        if rest is None:
            rest = p[steady].mean(axis=0)
        unloaded, unloaded_force = p[before].mean(axis=0), force[before].mean(axis=0)
        loaded = (t >= weight.spawn_at_s) & (np.abs(force[:, 2] - unloaded_force[2]) > CONTACT_THRESHOLD_N)
        contact = np.flatnonzero(loaded)
        if not contact.size:
            raise ConfigError("the weight never reached the sensor plate", source=self.session.scenario.source,
                              field="objects[0].xyz", value=list(weight.xyz))
        first, last = int(contact[0]), int(contact[-1])
        band = max(0.02 * abs(rest[2] - unloaded[2]), 0.001)
        outside = np.flatnonzero(np.linalg.norm(p - rest, axis=1) > band)
        settled = int(outside[-1]) + 1 if outside.size else first
        return Catch(
            t=t, p=p, force=force, sensed=sensed, rest=rest, unloaded=unloaded,
            steady_force=force[steady].mean(axis=0), unloaded_force=unloaded_force,
            first_contact_s=float(t[first]),
            load_lost_s=float(t[last + 1]) if last + 1 < len(t) else math.nan,
            overshoot_m=max(0.0, float(rest[2] - p[first:, 2].min())),
            settling_time_s=float(t[settled] - t[first]) if settled < len(t) else math.nan,
            band_m=band)

    def weight_on_plate(self, trace: Trace) -> tuple[np.ndarray, float, bool]:
        """Where the weight ended in the flange frame [m], the height [m] at which it rests on the
        plate, and whether it is there: over the plate's radius, within 1 cm of that height."""
        nac, dynamics = self.nac, self.dynamics
        dynamics.set_pose([trace.joint(j, "position")[-1] for j in nac.joint_names], inertia=False)
        flange = dynamics.frame(nac.frame)
        weight_p, _ = self.session.world.body_pose(self.weight.name)
        offset = flange.rotation.T @ (weight_p - flange.position)
        plate = next((c for c in self.session.robot.link(self.sensor_link).collisions
                      if c.geometry.kind == "cylinder"), None)
        plate_top = plate.origin.xyz[2] + plate.geometry.length_m / 2 if plate else 0.0
        plate_radius = plate.geometry.radius_m if plate else math.inf
        resting_height = plate_top + self.weight.half_height_m
        on_plate = bool(math.hypot(offset[0], offset[1]) <= plate_radius
                        and abs(offset[2] - resting_height) <= 0.01)
        return offset, resting_height, on_plate


def _plot(out: Path, name: str, nac: CartesianAdmittanceController, chapter_damping: list[float], main: Catch,
          chapter: Catch, events: list[Event]) -> None:
    t = main.t
    figures.plot_series(out / "flange_z.png", t,
                        {f"B = {tuple(nac.damping.tolist())} N·s/m": main.p[:, 2],
                         f"chapter: B = {tuple(chapter_damping)} N·s/m": chapter.p[:, 2]},
                        title=f"{name}: flange height", ylabel="z", unit="m", events=events)
    figures.plot_series(out / "flange_xy.png", t,
                        {"x": main.p[:, 0], "y": main.p[:, 1],
                         "x, chapter damping": chapter.p[:, 0], "y, chapter damping": chapter.p[:, 1]},
                        title=f"{name}: flange x and y", ylabel="position", unit="m", events=events)
    forces = ({f"F{a} (base frame, tared)": main.force[:, k] for k, a in enumerate("xyz")}
              | {"Fz, chapter damping": chapter.force[:, 2]})
    contact_s = main.first_contact_s
    for suffix, zoom in (("", None), ("_impact", (contact_s - 0.05, contact_s + 0.3)),
                         ("_after_impact", (contact_s + 0.5, float(t[-1])))):
        label = f" ({suffix[1:].replace('_', ' ')})" if suffix else ""
        figures.plot_series(out / f"force{suffix}.png", t, forces, zoom=zoom, events=events,
                            title=f"{name}: sensed force{label}", ylabel="force", unit="N")

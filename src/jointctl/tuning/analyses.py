"""The tuning page's Identify, Bode and Auto-tune panels: jointctl's identification tools on the page's robot.

With ``"live": true``, Identify and Bode run on the page's robot itself instead: the excitation
joins its running loop (after the page's command sources, which it overrides meanwhile), in its
loop time (13 s for an identification, about a minute for the sweep at speed 1), and the
controller's reference goes back to what it was when it ends; a pause or reset meanwhile ends it
with an error. Auto-tune always designs and checks on a copy.

Otherwise each runs on a simulated copy of the page's robot: its scenario with the gains and
gravity live on the page now, starting from the pose the robot holds now, in simulated time (a
second or two of wall-clock time), so the live loop is never disturbed and nothing changes until
the page applies gains through its usual gain requests (the Auto-tune panel's Apply, and Revert to
the gains the analysis started from). Replies (``live``: where it ran)::

    {"type": "analysis", "request": "identify", "controller": C, "live": false,
        "result": {mass_kg, damping..., r_squared}}
    {"type": "analysis", "request": "bode", "controller": C, "result": {frequencies_hz, gain_db, phase_deg,
        model: {gain_db, phase_deg, gain_margin_db, phase_crossover_hz, phase_margin_deg, gain_crossover_hz...},
        bandwidth_hz, resonance_hz, phase_minus_90_hz..., curves: {band_hz, frequencies_hz, closed_gain_db,
        closed_phase_deg, loop_gain_db, loop_phase_deg}}}

The Bode reply's ``curves`` are the loop model's on a dense log grid (:data:`CURVE_POINTS`) over the
sweep's band, widened to take in the margins' frequencies when they lie within a decade of it: the
closed loop (reference -> response) and the open loop (broken at the plant input; its 0 dB crossing
gives the phase margin, its -180° crossing the gain margin).
    {"type": "analysis", "request": "autotune", "controller": C, "result": {gains, previous_gains, model,
        robot: {step_overshoot_pct, bandwidth_hz...}}}
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from typing import Any

import numpy as np

from jointctl.scenario.spec import Scenario, parse_override
from jointctl.tuning.gains import PidGroup
from jointctl.tuning.requests import Analyse, RequestError

#: The Bode panel's sweep: 16 log-spaced frequencies over this band [Hz].
BODE_BAND_HZ = (0.5, 20.0)
BODE_POINTS = 16
CURVE_POINTS = 200


def live_copy(tuner, overrides=()) -> Scenario:
    """The page's scenario with its live PID gains, gravity and pose (the joints' measured
    positions as initial positions), plus ``overrides``: ``controllers.NAME.pid.p=VALUE`` strings, and
    ``initial_positions.JOINT=VALUE`` (where a check starts the joint)."""
    scenario = tuner.scenario
    merged = dict(scenario.controller_overrides)
    for name, group in tuner.groups.items():
        if isinstance(group, PidGroup):
            values = group.values()
            for key in ("p", "i", "d"):
                merged[f"{name}.pid.{key}"] = values[key]
    placed = {}
    for item in overrides:
        key, value = parse_override(item)
        if key.startswith("initial_positions."):
            placed[key.removeprefix("initial_positions.")] = value
        else:
            merged[key.removeprefix("controllers.")] = value
    gravity = tuner._gravity_z()
    hardware = tuner.hardware
    pose = {**scenario.initial_positions, **dict(zip(hardware.joint_names, hardware.position)), **placed}
    changes: dict[str, Any] = {"controller_overrides": merged, "commands": {}, "objects": (),
                               "initial_positions": pose}
    if gravity is not None:
        changes["gravity_m_s2"] = (0.0, 0.0, gravity)
    return dataclasses.replace(scenario, **changes)


class LiveSession:
    """The page's running robot as a session for jointctl's identification tools (a ``live``
    analysis): their hooks join its loop while it runs (the excitation after the page's own command
    sources, so it has the last word), and :meth:`run` waits while the loop thread runs that much
    loop time. A pause, a reset or a shutdown meanwhile ends the analysis with a RequestError."""

    def __init__(self, tuner) -> None:
        self.tuner = tuner
        self.loop, self.hardware, self.manager = tuner.loop, tuner.hardware, tuner.manager
        self.robot = tuner.session.robot

    def run(self, duration_s: float) -> None:
        tuner, loop = self.tuner, self.loop
        end, epoch = loop.time_s + duration_s - 1e-9, tuner.epoch
        last_s, moved_at = loop.time_s, time.monotonic()
        while loop.time_s < end:
            if tuner.paused or tuner.shutdown or tuner.reset_wanted or tuner.epoch != epoch:
                raise RequestError("the robot was paused, reset or stopped during the live analysis: nothing "
                                   "was measured", field="live", value=True)
            if loop.time_s != last_s:
                last_s, moved_at = loop.time_s, time.monotonic()
            elif time.monotonic() - moved_at > LIVE_STALL_S:
                raise RequestError(f"the robot's loop has not run for {LIVE_STALL_S:g} s", field="live", value=True)
            time.sleep(LIVE_POLL_S)

    def __enter__(self) -> LiveSession:
        return self

    def __exit__(self, *exc) -> None:
        pass


#: How often a live analysis looks at the loop's time, and how long the loop may stand still [s].
LIVE_POLL_S = 0.005
LIVE_STALL_S = 5.0
_live = threading.Lock()  # one live analysis at a time: two excitations would fight over the joint


def run_live(tuner, request: Analyse, controller) -> dict[str, Any]:
    """Run an identify or bode ``request`` on the page's running robot (:class:`LiveSession`; the
    request reader takes ``live`` for those two only); the controller's reference goes back to what
    it was when it ends."""
    from jointctl.identification.frequency_response import compare, measure_in_session
    from jointctl.identification.identify import identify_in_session

    if tuner.paused:
        raise RequestError("the robot is paused: resume it to analyse it live", field="live", value=True)
    if not _live.acquire(blocking=False):
        raise RequestError("a live analysis is already running", field="live", value=True)
    session = LiveSession(tuner)
    previous = controller.reference
    try:
        if request.kind == "identify":
            return identify_in_session(session, controller.joint)[1]
        hardware = tuner.hardware
        pose = dict(zip(hardware.joint_names, hardware.position))
        points, context = measure_in_session(session, request.controller, bode_frequencies())
        pose[context["joint"]] = context["rest"]
        return compare(points, context, request.controller, None, session.robot, pose)
    finally:
        tuner.at_next_cycle(lambda t: controller.set_reference(previous))
        _live.release()


def bode_frequencies() -> np.ndarray:
    """The Bode panel's sweep: ``BODE_POINTS`` log-spaced frequencies over ``BODE_BAND_HZ``."""
    return np.logspace(math.log10(BODE_BAND_HZ[0]), math.log10(BODE_BAND_HZ[1]), BODE_POINTS)


def model_curves(result: dict[str, Any]) -> dict[str, Any] | None:
    """The Bode reply's ``curves`` (see the module docstring) for a :func:`~jointctl.identification.
    frequency_response.compare` result; None when it has no model."""
    from jointctl.identification.frequency_response import LoopModel

    model = result.get("model")
    measured = [f for f in result.get("frequencies_hz", []) if f > 0]
    if not model or not measured:
        return None
    loop = LoopModel(model["mass"], model["damping"], model["p"], model["i"], model["d"], result["period_s"],
                     result["loop"], result.get("derivative", "error"))
    low, high = min(measured), max(measured)
    nyquist = 0.49 / result["period_s"]
    for key in ("gain_crossover_hz", "phase_crossover_hz"):
        f = model.get(key)
        if f is not None and math.isfinite(f) and low / 10 <= f <= high * 10:
            low, high = min(low, f / 1.2), max(high, f * 1.2)
    high = min(high, nyquist)
    f = np.logspace(math.log10(low), math.log10(high), CURVE_POINTS)
    closed_gain, closed_phase = loop.response(f)
    open_loop = loop.loop_response(f)
    open_phase = np.degrees(np.unwrap(np.angle(open_loop)))
    open_phase -= 360.0 * np.round((open_phase[0] + 90.0) / 360.0)  # start near -90° (one integrator), not +270°
    return {"band_hz": [low, high], "frequencies_hz": f.tolist(), "closed_gain_db": closed_gain.tolist(),
            "closed_phase_deg": closed_phase.tolist(), "loop_gain_db": (20 * np.log10(np.abs(open_loop))).tolist(),
            "loop_phase_deg": open_phase.tolist()}


def run_analysis(tuner, request: Analyse) -> dict[str, Any]:
    """Run ``request`` on a simulated copy of the page's robot, or on the robot itself when it is
    ``live`` (see the module docstring)."""
    from jointctl.identification.autotune import autotune
    from jointctl.identification.frequency_response import bode
    from jointctl.identification.identify import identify_on_robot

    controller = tuner.commandable.get(request.controller)
    if controller is None:
        raise RequestError(f"no joint controller of that name (controllers: {', '.join(tuner.commandable)})",
                           field="controller", value=request.controller)
    if request.live:
        result = run_live(tuner, request, controller)
        if request.kind == "bode":
            result["curves"] = model_curves(result)
        return {"type": "analysis", "request": request.kind, "controller": request.controller, "live": True,
                "result": result}
    if tuner.sim is None:
        raise RequestError("analyses run on a simulated copy of the robot; this one is real hardware (analyse it "
                           "live)", field="type", value=request.kind)
    if request.kind == "identify":
        _, metrics = identify_on_robot(live_copy(tuner), controller.joint)
        result = metrics
    elif request.kind == "bode":
        result = bode(live_copy(tuner), request.controller, bode_frequencies())
        result["curves"] = model_curves(result)
    else:
        result = autotune(lambda overrides: live_copy(tuner, overrides), request.controller,
                          bandwidth_hz=request.spec["bandwidth_hz"], zeta=request.spec["zeta"],
                          step=request.spec["step"])
    return {"type": "analysis", "request": request.kind, "controller": request.controller, "live": False,
            "result": result}


__all__ = ["BODE_BAND_HZ", "BODE_POINTS", "CURVE_POINTS", "LiveSession", "bode_frequencies", "live_copy",
           "model_curves", "run_analysis", "run_live"]

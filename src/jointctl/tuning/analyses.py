"""The tuning page's Identify, Bode and Auto-tune panels: jointctl's identification tools on the page's robot.

Each runs on a simulated copy of the page's robot: its scenario with the gains and gravity live on
the page now, starting from the pose the robot holds now, in simulated time (a second or two of wall-clock time), so the live loop is never
disturbed and nothing changes until the page applies gains through its usual gain requests (the
Auto-tune panel's Apply, and Revert to the gains the analysis started from). Replies::

    {"type": "analysis", "request": "identify", "controller": C, "result": {mass_kg, damping..., r_squared}}
    {"type": "analysis", "request": "bode", "controller": C, "result": {frequencies_hz, gain_db, phase_deg,
        model: {gain_db, phase_deg, margins...}, bandwidth_hz, resonance_hz, phase_minus_90_hz...}}
    {"type": "analysis", "request": "autotune", "controller": C, "result": {gains, previous_gains, model,
        robot: {step_overshoot_pct, bandwidth_hz...}}}
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from jointctl.scenario.spec import Scenario, parse_override
from jointctl.tuning.gains import PidGroup
from jointctl.tuning.requests import Analyse, RequestError

#: The Bode panel's sweep: 16 log-spaced frequencies over this band [Hz].
BODE_BAND_HZ = (0.5, 20.0)
BODE_POINTS = 16


def live_copy(tuner, overrides=()) -> Scenario:
    """The page's scenario with its live PID gains, gravity and pose (the joints' measured
    positions as initial positions), plus ``overrides`` (``controllers.NAME.pid.p=VALUE`` strings)."""
    scenario = tuner.scenario
    merged = dict(scenario.controller_overrides)
    for name, group in tuner.groups.items():
        if isinstance(group, PidGroup):
            values = group.values()
            for key in ("p", "i", "d"):
                merged[f"{name}.pid.{key}"] = values[key]
    for item in overrides:
        key, value = parse_override(item)
        merged[key.removeprefix("controllers.")] = value
    gravity = tuner._gravity_z()
    hardware = tuner.hardware
    pose = {**scenario.initial_positions, **dict(zip(hardware.joint_names, hardware.position))}
    changes: dict[str, Any] = {"controller_overrides": merged, "commands": {}, "objects": (),
                               "initial_positions": pose}
    if gravity is not None:
        changes["gravity_m_s2"] = (0.0, 0.0, gravity)
    return dataclasses.replace(scenario, **changes)


def run_analysis(tuner, request: Analyse) -> dict[str, Any]:
    """Run ``request`` on a simulated copy of the page's robot (see the module docstring)."""
    from jointctl.identification.autotune import autotune
    from jointctl.identification.frequency_response import bode
    from jointctl.identification.identify import identify_on_robot

    if tuner.sim is None:
        raise RequestError("analyses run on a simulated copy of the robot; this one is real hardware",
                           field="type", value=request.kind)
    controller = tuner.commandable.get(request.controller)
    if controller is None:
        raise RequestError(f"no joint controller of that name (controllers: {', '.join(tuner.commandable)})",
                           field="controller", value=request.controller)
    if request.kind == "identify":
        _, metrics = identify_on_robot(live_copy(tuner), controller.joint)
        result = metrics
    elif request.kind == "bode":
        frequencies = np.logspace(math.log10(BODE_BAND_HZ[0]), math.log10(BODE_BAND_HZ[1]), BODE_POINTS)
        result = bode(live_copy(tuner), request.controller, frequencies)
    else:
        result = autotune(lambda overrides: live_copy(tuner, overrides), request.controller,
                          bandwidth_hz=request.spec["bandwidth_hz"], zeta=request.spec["zeta"],
                          step=request.spec["step"])
    return {"type": "analysis", "request": request.kind, "controller": request.controller, "result": result}


__all__ = ["BODE_BAND_HZ", "BODE_POINTS", "live_copy", "run_analysis"]

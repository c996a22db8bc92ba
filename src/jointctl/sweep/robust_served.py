"""Robust autotune's check on a ros2_control robot (``autotune --robust ... --hardware ros2``).

The family is the simulated robot's (:mod:`jointctl.sweep.robust_design`): the robot's own robot folder or
built-in robot (its ``--controllers`` file, default ``ros2``: the simulated twin) varied by ``--robust``, its
pid_controller of the same name designed against every plant, each plant run on the simulated robot. The robot on
the graph is one plant of that family, not known which; so the design is then checked on it (:func:`check_served`):

- its pid_controller takes the robust gains as its parameters (``gains.<dof>.p|i|d``, with an integral
  ``i_clamp_max``, ``i_clamp_min``, ``antiwindup``: :func:`ros2_gains`);
- it holds the reference it held when the tool connected for :func:`served_hold_s`, then steps by the design's
  step (along its ramp), watched as the design was judged (:func:`~jointctl.identification.step_loop.step_figures`
  over :func:`~jointctl.identification.autotune.check_after_s` of the settling time), the user's limits guarded;
- it goes back to its reference with the new gains, then the gain parameters are set back as they were found.

What binds on the robot is judged as on each plant of the family
(:func:`~jointctl.sweep.robust_design.plant_binds`: overshoot within 3 points of the spec, settling within 15 %,
the rest within the 2 % band of the step).

**The integral a robot already holds.** control_toolbox's PID accumulates ``i_error += h·e`` whatever ``i`` is:
a robot that held a P loop's droop ``e`` for minutes holds a large ``i_error``. With the design's integral
(anti-windup: ``i_error`` clamped to the clamps over ``i``) the first cycle under the new gains brings the integral
term to its clamp, not to the load; the loop then unwinds it at the pace of its slowest mode. So the hold before
the step lasts until that mode has taken the largest such offset, ``(i_clamp + load)/p``, to a tenth of the settling
band (:func:`~jointctl.sweep.robust_design.integral_hold_s`, over the family's range of inertia and damping).
"""

from __future__ import annotations

import itertools
import math

from jointctl.identification.autotune import _step, check_after_s
from jointctl.identification.frequency_response import held_reference, servo_reference
from jointctl.identification.safety import Safety
from jointctl.identification.step_loop import JointLoop, StepFigures
from jointctl.sweep.robust_design import integral_hold_s, plant_binds, report_fields

#: The hold before the check's step without an integral [s] (autotune's check on a served robot holds 0.5 s).
HOLD_S = 1.0


def ros2_gains(result: dict, dof: str) -> dict:
    """The robust design's gains as pid_controller's parameters of ``dof`` (``{"p": ..., "i_clamp_max": ...}``,
    without the ``gains.<dof>.`` prefix)."""
    fields = report_fields({**result, "joint": dof})
    prefix = f"gains.{dof}."
    return {key[len(prefix):]: value for key, value in fields.items()}


def served_hold_s(result: dict) -> float:
    """How long the robot holds its reference under the robust gains before the step [s] (the module docstring):
    :data:`HOLD_S` without an integral; with one, until the slowest mode of the loop has taken ``(i_clamp +
    load)/p`` to :data:`~jointctl.sweep.robust_design.INTEGRAL_RESIDUE` of the step, over the corners of the
    family's inertia and damping."""
    gains = result["robust"]["gains"]
    if not gains.get("i"):
        return HOLD_S
    clamp = max(abs(float(gains["i_clamp"])), abs(float(gains.get("i_clamp_min", -gains["i_clamp"]))))
    offset = (clamp + float(result["family"]["gravity_load_max"])) / float(gains["p"])
    step = float(result["spec"]["step"])
    family = result["family"]
    holds = [integral_hold_s(JointLoop(mass, damping, 1.0, p=float(gains["p"]), i=float(gains["i"]),
                                       d=float(gains["d"])), offset, step)
             for mass, damping in itertools.product(family["inertia"], family["damping"])]
    return max(HOLD_S, *holds)


def check_served(session, controller_name: str, result: dict, *, safety: Safety | None = None) -> dict:
    """The robust design's step on the served robot (the module docstring): the figures of autotune's check
    (``step_overshoot_pct``, ``step_settling_s``, ``step_final_error``, ``step_peak_effort``, the saturation...),
    the ``hold_s`` before the step, the ``gains`` set, what ``binds`` and whether it ``meets_spec``; the gains
    found put back whatever happens."""
    hardware = session.hardware
    joint = hardware.joint_of(controller_name)
    gains = ros2_gains(result, hardware.loop.command_dof)
    spec, robust = result["spec"], result["robust"]
    step, settling = float(spec["step"]), float(spec["step_settling_s"])
    hold = served_hold_s(result)
    _, set_reference = servo_reference(hardware, joint)
    hardware.set_gains(controller_name, gains)
    try:
        figures = _step(session, joint, set_reference, "position", step, hold_s=hold, after_s=check_after_s(settling),
                        safety=safety, reference=held_reference(hardware, joint), ramp_s=float(robust["ramp_s"] or 0))
        # Back where it started, with the gains that moved it.
        set_reference(figures["step_reference"])
        with session:
            session.run(HOLD_S)
    finally:
        hardware.restore_gains()
    measured = StepFigures(_real(figures["step_overshoot_pct"]), _real(figures["step_settling_s"]),
                           figures["step_start"], figures["step_final"], figures["step_final_error"],
                           figures["step_peak_effort"], figures["saturation"]["step"]["share"])
    binds = plant_binds(measured, step, float(spec["overshoot_pct"]), settling)
    return {**figures, "hold_s": hold, "gains": gains, "binds": binds, "meets_spec": not binds}


def _real(value) -> float:
    return math.nan if value is None else float(value)


def served_warnings(result: dict) -> list[str]:
    """A sentence when the check on the served robot misses the spec, naming what binds with the figures."""
    robot = result.get("robot") or {}
    if not robot.get("binds"):
        return []
    spec = result["spec"]
    return [f"on the robot, the step of {spec['step']:g} misses the spec ({spec['overshoot_pct']:.3g} % within 3 "
            f"points, {spec['step_settling_s']:.3g} s within 15 %, the rest within the 2 % band): overshoot "
            f"{_real(robot['step_overshoot_pct']):.3g} %, settling {_real(robot['step_settling_s']):.3g} s, rest "
            f"{robot['step_final_error']:.3g} from the reference; binds: {', '.join(robot['binds'])} (the robot is "
            "outside the family, or the family misses the spec there too: see binds)."]


__all__ = ["HOLD_S", "check_served", "ros2_gains", "served_hold_s", "served_warnings"]

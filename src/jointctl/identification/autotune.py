"""``jointctl autotune``: gains for a damping ratio and a bandwidth, checked on the model and on the robot.

**Design.** The plant is the joint's mass (or inertia) ``m`` and viscous damping ``b`` (identified,
or the robot model's). A position loop gets a PD (``p``, ``d``). With the derivative on the measured
speed (``derivative: measurement``, jointctl's law with a position-only reference) the loop is
``p / (m s² + (b + d) s + p)``: ``ωn = sqrt(p/m)``, ``ζ = (b + d) / (2·sqrt(p·m))``, whose -3 dB
bandwidth is ``ωn·sqrt(1 - 2ζ² + sqrt(4ζ⁴ - 4ζ² + 2))`` and step overshoot ``exp(-πζ/sqrt(1-ζ²))``
(4.6 % at ζ = 0.7). With the derivative on the error (``derivative: error``, ros_controllers' law
for a plain position command, and the default) the loop is ``(d s + p) / (m s² + (b + d) s + p)``:
the zero makes the step overshoot more for the same gains (the measurement design of 10 % in 0.3 s
overshoots 14 % there), so the gains are solved on that loop's own sampled model; the ζ of the spec
then names the step's overshoot (``exp(-πζ/sqrt(1-ζ²))``), not the poles' damping. A velocity loop
gets a P (``p``), making ``p / (m s + p + b)`` with bandwidth
``(p + b)/m``. The continuous design is then corrected for the 1 kHz sample-and-hold: the sampled
loop's model (python-control, :class:`~jointctl.identification.frequency_response.LoopModel`) is
solved for the gains whose overshoot and -3 dB bandwidth meet the spec.

**The move that will run.** A position loop is designed for the step that will run: ``step`` [m or rad,
either way] from the reference the loop holds (``--step``; else the scenario's own step of that controller,
else :data:`DEFAULT_STEP`), along ``ramp_s`` [s] when given, on the loop as it runs there
(:class:`~jointctl.identification.step_loop.JointLoop`: the controller's law, whose derivative on the error
asks the kick ``d·step/period`` on the first cycle, clamped at the effort limit; the effort clamp; the gravity
load over the move; an integral, the gravity feed-forward; on the simulated robot its own integration). The
spec becomes the step's overshoot (ζ's, or ``--overshoot-pct``) and settling time (``--settling-s``, or the
ideal loop's); when the linear design does not meet them at that step the gains are searched on that loop
(:mod:`jointctl.identification.step_design`). A step whose motion would leave the joint's range (less the
guard's band) or ``--workspace``, move faster than the velocity limit or ``--max-velocity``, or ask more than
``--max-effort``, is refused before anything moves. A velocity loop keeps the linear design: a step of
``step`` [m/s or rad/s] asking more than the effort limit is refused, naming the bandwidth it allows.

**What binds.** When the check's step misses the spec (overshoot by 3 points, settling by 15 %, the rest
beyond the 2 % band), ``binds`` names why (gravity, effort, the clamped kick, ``--max-effort``, the plant's
damping) and each remedy that answers it (``--remedy``: integral, feedforward, measurement, ramp,
lower-bandwidth) is designed and its step run on the simulated robot (``alternatives``, and a warning each);
the user picks with ``--remedy``, and the controller file is written with it.

**Check.** Before they are offered, the gains run on the robot itself (the scenario with the new gains, from
where the loop rests: exactly the step designed for, and a stepped-sine sweep around the bandwidth, each sine
at most the step and inside the sweep's safe amplitude): the figures it prints as the robot's (``robot.step_*``)
are measured at the user's step; the model's (``model.*``) are the model's. The share of the check's cycles at
the actuator's effort or velocity limit is reported (``robot.saturation``); above the threshold the result
carries a warning (``warnings``), and a crossing of the user's limits stops the check and brings the joint back
(SafetyStop). The gains are written as the robot's controller YAML (the chapter's format), the tuned
controller's ``pid`` replaced (and its ``derivative`` and ``feedforward`` where a remedy changed them),
everything else as loaded.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import yaml
from scipy.optimize import fsolve

from jointctl.control.joint_controllers import derivative_law
from jointctl.control.position_loop import law_of
from jointctl.control.manager import read_yaml
from jointctl.identification.frequency_response import (LoopModel, _crossing, held_reference, loop_controller,
                                                         measure,
                                                         measure_servoed, model_plant, plant_friction, plant_of,
                                                         plant_source, servo_reference)
from jointctl.identification.plant_fit import IdentificationError
from jointctl.identification.gain_files import fields_of, setting_overrides, tuned_document
from jointctl.identification.step_design import (INTEGRAL_TIMES, OVERSHOOT_TOLERANCE_PCT, SETTLING_TOLERANCE,
                                                 StepDesign, binding, lowest_settling, ramp_for_kick, remedy_lacking,
                                                 solve_step, with_integral)
from jointctl.identification.step_loop import HoldingEffort, JointLoop, holding_effort, reference_step, step_figures
from jointctl.identification.safety import (DEFAULT, GUARD_FRACTION, Guard, Safety, SaturationMonitor, envelope_for,
                                            run_guarded, saturation_text)
from jointctl.recording.metrics_file import write_metrics
from jointctl.scenario.session import Session
from jointctl.scenario.spec import Scenario


def bandwidth_ratio(zeta: float) -> float:
    """-3 dB bandwidth over ωn of ``ωn² / (s² + 2ζωn s + ωn²)``."""
    return math.sqrt(1 - 2 * zeta**2 + math.sqrt(4 * zeta**4 - 4 * zeta**2 + 2))


def overshoot_of(zeta: float) -> float:
    """Step overshoot (a fraction) of an underdamped second-order loop."""
    return math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)) if zeta < 1 else 0.0


def zeta_of(overshoot: float) -> float:
    """The damping ratio of a second-order loop with step ``overshoot`` (a fraction; NaN if none)."""
    if not overshoot > 0:
        return math.nan
    log = math.log(overshoot)
    return -log / math.sqrt(math.pi**2 + log**2)


def design(mass: float, damping: float, *, loop: str, bandwidth_hz: float, zeta: float = 0.7,
           period_s: float = 0.001, derivative: str = "error") -> dict:
    """Gains ``{"p", "i", "d"}`` for the spec on the sampled loop (see the module docstring) whose
    position controller runs the ``derivative`` law ("error" or "measurement")."""
    wb = 2 * math.pi * bandwidth_hz
    if loop == "velocity":
        p0 = mass * wb - damping
        if p0 <= 0:
            raise IdentificationError(f"the plant alone is faster than {bandwidth_hz:g} Hz: no gain needed",
                                      field="bandwidth_hz", value=bandwidth_hz)

        def miss_v(x):
            model = LoopModel(mass, damping, x[0], 0.0, 0.0, period_s, "velocity")
            gain, _ = model.response([bandwidth_hz])
            dc, _ = model.response([1e-3])
            return [gain[0] - dc[0] + 3.0103]

        (p,) = fsolve(miss_v, [p0], xtol=1e-10)
        return {"p": float(p), "i": 0.0, "d": 0.0}
    if not 0 < zeta < 1:
        raise IdentificationError("must be in (0, 1) (an underdamped loop)", field="zeta", value=zeta)
    wn = wb / bandwidth_ratio(zeta)
    p0, d0 = mass * wn**2, 2 * zeta * wn * mass - damping
    if d0 < 0:
        raise IdentificationError(f"the plant's own damping exceeds ζ {zeta:g} at {bandwidth_hz:g} Hz; ask for a "
                                  "higher bandwidth or damping ratio", field="zeta", value=zeta)
    target_overshoot = overshoot_of(zeta)

    def solve(law: str, start) -> tuple[float, float]:
        def miss(x):
            model = LoopModel(mass, damping, x[0], 0.0, x[1], period_s, "position", law)
            gain, _ = model.response([bandwidth_hz])
            return [gain[0] + 3.0103, (_model_overshoot(model) - target_overshoot) * 100]

        with warnings.catch_warnings():  # "not making good progress": judged by the residual below
            warnings.simplefilter("ignore", RuntimeWarning)
            x = fsolve(miss, start, xtol=1e-10)
        if not np.all(np.isfinite(x)) or x[0] <= 0 or x[1] < 0 or max(map(abs, miss(x))) > 1e-3:
            raise IdentificationError(
                f"found no PD gains that give ζ {zeta:g} ({100 * target_overshoot:.3g} % overshoot) and {bandwidth_hz:g} Hz "
                f"with the derivative on the {law} (its zero keeps some overshoot); ask for a lower ζ (more "
                f"overshoot) or another bandwidth, or run the controller with derivative: measurement",
                field="zeta", value=zeta)
        return float(x[0]), float(x[1])

    # Derivative on measurement: the continuous design, corrected for the hold. Derivative on the
    # error adds the zero of p + d·s (its step overshoots more for the same gains): solved from there.
    p, d = solve("measurement", [p0, d0])
    if derivative == "error":
        # The zero lends bandwidth: the same spec needs less p (a half at 5 Hz on the 1-DOF robot, an
        # eighth at 20 Hz); started from the measurement design scaled down until one converges.
        p_m, d_m = p, d
        for scale in (1.0, 0.5, 0.25, 0.125, 0.0625):
            try:
                p, d = solve("error", [p_m * scale, d_m * math.sqrt(scale)])
                break
            except IdentificationError:
                if scale == 0.0625:
                    raise
    return {"p": p, "i": 0.0, "d": d}


#: The settling band of a step: within 2 % of the step from then on.
SETTLING_BAND = 0.02


def _model_step(model: LoopModel, seconds: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """(t, y): the loop model's unit step response (:meth:`LoopModel.step`)."""
    return model.step(seconds)


def _model_overshoot(model: LoopModel) -> float:
    _, y = _model_step(model)
    final = y[-1]
    return float((y.max() - final) / final)


def settling_time(t: np.ndarray, y: np.ndarray, start: float, final: float, band: float = SETTLING_BAND) -> float:
    """The time [s] from ``t[0]`` after which ``y`` stays within ``band`` of the step ``final - start``
    around ``final``; NaN when it never does."""
    outside = np.nonzero(np.abs(y - final) > band * abs(final - start))[0]
    if outside.size == 0:
        return 0.0
    if outside[-1] == y.size - 1:
        return math.nan
    return float(t[outside[-1] + 1] - t[0])


def spec_from_step(overshoot_pct: float, settling_s: float) -> tuple[float, float]:
    """(ζ, -3 dB bandwidth [Hz]) of the second-order loop whose step overshoots ``overshoot_pct`` and
    settles within 2 % in ``settling_s``: ζ from the overshoot, then ωn from the settling time of the
    unit second-order step with that ζ (computed, not the 4/(ζωn) rule of thumb, which is from 4 % short
    to 33 % long between ζ 0.4 and 0.8: the settling time jumps as each overshoot leaves the band)."""
    if not (isinstance(overshoot_pct, (int, float)) and 0 < overshoot_pct < 100):
        raise IdentificationError("must be between 0 and 100 (an underdamped step)", field="overshoot_pct",
                                  value=overshoot_pct)
    if not (isinstance(settling_s, (int, float)) and math.isfinite(settling_s) and settling_s > 0):
        raise IdentificationError("must be a positive number of seconds", field="settling_s", value=settling_s)
    zeta = zeta_of(overshoot_pct / 100)
    wd = math.sqrt(1 - zeta**2)
    t = np.linspace(0.0, 40.0 / zeta, 400_001)  # ωn = 1
    y = 1 - np.exp(-zeta * t) / wd * np.sin(wd * t + math.acos(zeta))
    wn = settling_time(t, y, 0.0, 1.0) / settling_s
    return zeta, wn * bandwidth_ratio(zeta) / (2 * math.pi)


#: The step autotune designs for when neither the user nor the scenario names one [m, rad, or per s].
DEFAULT_STEP = 0.1


def scenario_move(scenario: Scenario, controller_name: str) -> dict | None:
    """The move the scenario makes with ``controller_name``: ``{"from", "step", "ramp_s"}`` of its step source
    [m or rad; s], or None when its command is not a step."""
    config = (scenario.commands or {}).get(controller_name)
    if not isinstance(config, dict) or config.get("type") != "step":
        return None
    start, end = float(config["from"]), float(config["to"])
    return {"from": start, "step": end - start, "ramp_s": float(config.get("ramp_s", 0.0))}


def the_move(scenario: Scenario, controller_name: str, step: float | None,
             ramp_s: float | None) -> tuple[float, float | None, float | None]:
    """(step, the reference it starts from or None for the one the loop holds, ramp [s] or None): the user's
    ``step`` and ``ramp_s``, else the scenario's own step of ``controller_name`` (:func:`scenario_move`), else
    :data:`DEFAULT_STEP`."""
    move = scenario_move(scenario, controller_name)
    reference = None
    if step is None and move is not None:
        step, reference = move["step"], move["from"]
        ramp_s = move["ramp_s"] if ramp_s is None else ramp_s
    return (DEFAULT_STEP if step is None else step), reference, ramp_s


def autotune(scenario_for, controller_name: str, *, bandwidth_hz: float, zeta: float = 0.7,
             step: float | None = None, plant: dict | None = None, out_dir: str | Path | None = None,
             check_on_robot: bool = True, settling_s: float | None = None, safety: Safety | None = None,
             ramp_s: float | None = None, remedies: tuple[str, ...] = (), alternatives: bool = True) -> dict:
    """Tune ``controller_name`` of the scenario ``scenario_for(overrides)`` gives (see the module
    docstring); the metrics (gains, predicted and simulated figures). The move designed for and checked:
    ``step`` [m or rad] (along a ramp of ``ramp_s`` [s]), else the scenario's own step of that controller,
    else :data:`DEFAULT_STEP`, from the reference the controller holds. ``plant`` as for
    :func:`jointctl.identification.frequency_response.bode`; ``safety`` the user's limits and the fractions
    of :mod:`jointctl.identification.safety`; ``remedies`` (``--remedy``) change the loop designed. With
    ``alternatives``, a spec the loop misses at the step gets each remedy that answers what binds
    designed and checked on the simulated robot (``alternatives`` in the result)."""
    scenario: Scenario = scenario_for(())
    step, reference, ramp_s = the_move(scenario, controller_name, step, ramp_s)
    _check_spec(bandwidth_hz, step)
    session = Session(scenario)
    hardware = session.hardware
    controller, loop = loop_controller(session.manager, controller_name)
    joint = controller.joint
    hardware.read()
    pose = {name: hardware.position[k] for k, name in enumerate(hardware.joint_names)}
    if reference is None and loop == "position":
        reference = float(controller.reference_input[0])
    gravity = None if plant is not None else _gravity_load(session.robot, pose, joint, scenario.gravity_m_s2)
    gains = controller.pid.gains
    period_s = session.loop.period_s
    law = getattr(controller, "derivative", "error")
    kind = law_of(controller)  # ros_controllers' JointPositionController, or ros2_controllers' pid_controller
    for remedy in remedies:
        lacking = remedy_lacking(kind, remedy)
        if lacking is not None:
            session.close()
            raise IdentificationError(f"{controller_name} cannot take it: {lacking}", field="--remedy", value=remedy)
    robot = session.robot

    def design_with(remedy_set: tuple[str, ...]) -> dict:
        return tune(controller_name, joint, loop, period_s, plant, robot, pose, gravity, controller.effort_limit,
                    {"p": gains.p, "i": gains.i, "d": gains.d}, bandwidth_hz=bandwidth_hz, zeta=zeta, step=step,
                    settling_s=settling_s, derivative=law, safety=safety, gravity_m_s2=scenario.gravity_m_s2,
                    ramp_s=ramp_s or 0.0, reference=reference, remedies=remedy_set, integrator="euler",
                    feedforward="gravity" in getattr(controller, "feedforward_terms", ()), law=kind)

    result = design_with(tuple(remedies))
    session.close()
    if "max-effort" in (result.get("binds") or []):
        # The check would trip --max-effort: refused before anything moves, with what would not.
        found = _alternatives(result, design_with, scenario_for, controller_name, plant=plant, safety=safety) \
            if alternatives else {}
        result["alternatives"] = found
        raise IdentificationError(
            f"the step of {step:g} asks {result['step_plan']['peak_effort']:.4g} on the loop designed, beyond "
            f"--max-effort {result['effort_limit']:g}" + (f" ({result['note']})" if result.get("note") else "")
            + "; " + (" ".join(_binding_warnings(result)[1:]) or "ask a smaller --step or a lower bandwidth"),
            field="--max-effort", value=result["effort_limit"])
    if check_on_robot:
        result["robot"] = _check_on_robot(scenario_for, controller_name, result, loop, bandwidth_hz, plant=plant,
                                          safety=safety)
        _warn(result, safety)
        if loop == "position":
            result["binds"] = _robot_binds(result)
            if alternatives and result["binds"]:
                result["alternatives"] = _alternatives(result, design_with, scenario_for, controller_name,
                                                       plant=plant, safety=safety)
    result.setdefault("warnings", []).extend(spec_warnings(result))
    if loop == "position":
        result["warnings"].extend(_binding_warnings(result))
    if out_dir is not None:
        source = Path(scenario.controller_file)
        _write(out_dir, source.name, read_yaml(source), controller_name, result,
               overrides=scenario.controller_overrides)
    return result


def _robot_binds(result: dict) -> list[str]:
    """What keeps the check on the robot from the spec at the step (see
    :func:`~jointctl.identification.step_design.binding`), read off the robot's figures."""
    from jointctl.identification.step_design import binding
    from jointctl.identification.step_loop import StepFigures

    robot = result["robot"]
    figures = StepFigures(robot["step_overshoot_pct"], robot["step_settling_s"], robot["step_start"],
                          robot["step_final"], robot["step_final_error"], robot["step_peak_effort"],
                          robot["saturation"]["step"]["share"])
    reference = np.array([result["reference"], result["reference"] + result["step"]])
    gains = result["gains"]
    loop = JointLoop(result["mass"], result["damping"], 0.001, p=gains["p"], d=gains["d"])
    binds = list(binding(loop, figures, reference, result["spec"]["overshoot_pct"],
                         result["spec"]["step_settling_s"]))
    if binds == ["spec"] and result.get("binds"):
        binds = list(result["binds"])
    if "max-effort" in (result.get("binds") or []) and "max-effort" not in binds:
        binds.append("max-effort")
    if _kick_misses_bandwidth(result, robot.get("bandwidth_hz", result["model"]["bandwidth_hz"])):
        binds.append("kick")
    return binds


#: How far a bandwidth may miss the one asked (a share), as :mod:`jointctl.metrics.expectations` judges it.
BANDWIDTH_MARGIN = 0.05


def _kick_misses_bandwidth(result: dict, bandwidth_hz: float | None) -> bool:
    """Whether a spec that asked for a bandwidth misses it at ``bandwidth_hz`` because the step's derivative kick
    is clamped: the gains that give the step its overshoot then give the small moves another bandwidth."""
    asked = result["spec"].get("bandwidth_hz")
    if result["spec"].get("settling_s") is not None or not asked or bandwidth_hz is None:
        return False
    kicked = result.get("derivative") == "error" and not result.get("ramp_s") and "kick" in (result.get("note") or "")
    return kicked and math.isfinite(bandwidth_hz) and abs(bandwidth_hz / asked - 1) > BANDWIDTH_MARGIN


def _alternatives(result: dict, design_with, scenario_for, controller_name: str, *, plant, safety) -> dict:
    """Each remedy that answers what binds (:data:`~jointctl.identification.step_design.REMEDIES`) added to
    those applied, designed and its step checked on the simulated robot: {remedy: {gains, robot figures,
    meets}} (a design the remedy cannot make: {error})."""
    from jointctl.identification.step_design import REMEDIES

    applied = tuple(result.get("remedies") or ())
    wanted: list[str] = []
    for bind in result["binds"]:
        for remedy in REMEDIES.get("effort" if bind in ("max-effort", "spec") else bind, ()):
            if remedy in applied or remedy in wanted or remedy_lacking(result.get("law", "ros_control"), remedy):
                continue
            if remedy == "measurement" and result["derivative"] == "measurement":
                continue
            if remedy == "feedforward" and "gravity" in (result.get("feedforward") or ()):
                continue
            if remedy == "ramp" and (result.get("ramp_s") or result["derivative"] == "measurement"):
                continue
            wanted.append(remedy)
    found = {}
    for remedy in wanted:
        try:
            trial = design_with((*applied, remedy))
            if "max-effort" in trial["binds"]:
                found[remedy] = {"error": f"it still asks {trial['step_plan']['peak_effort']:.4g}, beyond "
                                          f"--max-effort {trial['effort_limit']:g}"}
                continue
            trial["robot"] = _check_on_robot(scenario_for, controller_name, trial, "position", None, plant=plant,
                                             safety=safety, sweep=False)
            trial["binds"] = _robot_binds(trial)
        except IdentificationError as exc:
            found[remedy] = {"error": str(exc)}
            continue
        robot = trial["robot"]
        # The step measured on the robot; a bandwidth asked for, on the model (no sweep run for each remedy).
        model_bandwidth = trial["model"]["bandwidth_hz"]
        if _kick_misses_bandwidth(trial, model_bandwidth) and "kick" not in trial["binds"]:
            trial["binds"].append("kick")
        found[remedy] = {"gains": trial["gains"], "derivative": trial["derivative"], "ramp_s": trial["ramp_s"],
                         "feedforward": trial["feedforward"], "meets": not trial["binds"], "binds": trial["binds"],
                         "model_bandwidth_hz": model_bandwidth,
                         **{k: robot[k] for k in ("step_overshoot_pct", "step_settling_s", "step_final_error",
                                                  "step_peak_effort")}}
    return found


def _binding_warnings(result: dict) -> list[str]:
    """A sentence for each constraint that keeps the step on the robot from the spec, with the remedies
    checked on the simulated robot."""
    binds = result.get("binds") or []
    if not binds:
        return []
    robot = result.get("robot") or {}
    what = {"gravity": f"the gravity load: the joint rests {robot.get('step_final_error', math.nan):.3g} from its "
                       f"reference (beyond the 2 % band of the step)",
            "effort": f"the effort limit {result['effort_limit']:g}: the step saturates the actuator",
            "max-effort": f"--max-effort {result['effort_limit']:g}: the step asks "
                          f"{robot.get('step_peak_effort', math.nan):.4g}",
            "damping": "the plant's own damping: even d = 0 overshoots less than asked",
            "kick": f"the derivative kick d·step/period, clamped at the effort limit {result['effort_limit']:g}: the "
                    f"gains that give this step its overshoot give small moves "
                    f"{robot.get('bandwidth_hz') or result['model']['bandwidth_hz']:.3g} Hz, not "
                    f"{result['spec']['bandwidth_hz']:g}",
            "spec": "the spec itself at this step"}
    lines = [f"at the step of {result['step']:g} the spec is not met; binds: "
             + "; ".join(what.get(b, b) for b in binds) + "."]
    for remedy, alt in (result.get("alternatives") or {}).items():
        if "error" in alt:
            lines.append(f"--remedy {remedy}: not possible ({alt['error']}).")
            continue
        lines.append(f"--remedy {remedy}: overshoot {alt['step_overshoot_pct']:.3g} %, settling "
                     f"{alt['step_settling_s']:.3g} s, rest {alt['step_final_error']:.3g} from the reference, peak "
                     f"effort {alt['step_peak_effort']:.4g} on the simulated robot, bandwidth "
                     f"{alt['model_bandwidth_hz']:.3g} Hz on the model"
                     + (" (meets the spec)" if alt["meets"] else f" (still binds: {', '.join(alt['binds'])})") + ".")
    return lines


def _check_spec(bandwidth_hz, step) -> None:
    """A positive bandwidth [Hz]; a finite step other than 0 [m, rad, or per s] (its sign the move's way)."""
    if not (isinstance(bandwidth_hz, (int, float)) and math.isfinite(bandwidth_hz) and bandwidth_hz > 0):
        raise IdentificationError("must be a positive number", field="bandwidth_hz", value=bandwidth_hz)
    if not (isinstance(step, (int, float)) and math.isfinite(step) and step != 0):
        raise IdentificationError("must be a number other than 0 (its sign is the move's way)", field="step",
                                  value=step)


def tune(controller_name: str, joint: str, loop: str, period_s: float, plant: dict | None, robot, pose: dict,
         gravity: float | None, effort_limit: float, previous_gains: dict, *, bandwidth_hz: float, zeta: float,
         step: float, settling_s: float | None = None, derivative: str = "error", safety: Safety | None = None,
         gravity_m_s2=(0.0, 0.0, -9.81), ramp_s: float = 0.0, reference: float | None = None,
         remedies: tuple[str, ...] = (), integrator: str = "hold", feedforward: bool = False,
         law: str = "ros_control") -> dict:
    """Design the gains for the spec and predict them on the models (no robot involved): the plant from
    ``plant`` (an identification's metrics, its ``gravity_load_n`` the load) or else ``robot``'s model at
    ``pose`` with ``gravity`` [N or N·m, magnitude] as the load. ``settling_s`` is recorded in the spec when
    the spec was given as overshoot and settling time (:func:`spec_from_step` made ``zeta`` and
    ``bandwidth_hz`` of it). ``derivative`` is the law the position controller runs ("error",
    ros_controllers', or "measurement"). ``safety``'s ``--max-effort`` lowers ``effort_limit`` [N or N·m].

    A position loop is designed for the move that will run (:func:`_design_position`): a step of ``step``
    from the ``reference`` it holds (default: where the joint is), along a ramp of ``ramp_s`` [s], on the
    loop as it runs (the law, the effort clamp, the gravity load over the move); ``remedies`` (of
    :data:`~jointctl.identification.step_design.REMEDY_NAMES`) change the loop designed; ``integrator`` is how
    the joint moves over a period (:class:`~jointctl.identification.step_loop.JointLoop`: "euler" for the
    simulated robot, "hold" for a real one); ``feedforward``: the controller already adds the model's gravity
    effort (its ``feedforward: {gravity: true}``); ``law`` the controller whose PID runs it (JointLoop's: "ros_control", or "control_toolbox" for
    ros2_controllers' pid_controller; the result's ``law``, which says how its gains are written). A velocity
    loop is refused when a step of ``step`` would exceed ``effort_limit``, naming the bandwidth it allows."""
    safety = safety or DEFAULT
    user_effort = safety.limits.max_effort
    effort_flag = "effort limit"
    if user_effort is not None and user_effort < effort_limit:
        effort_limit, effort_flag = user_effort, "--max-effort"
    if plant is not None:
        mass, damping = plant_of(plant)
        gravity = abs(float(plant.get("gravity_load_n", 0.0)))
        source = plant_source(plant)
    else:
        mass, damping = model_plant(robot, joint, pose)
        source = "robot model"
    common = {"controller": controller_name, "joint": joint, "loop": loop, "plant_source": source, "mass": mass,
              "damping": damping, "gravity_load": gravity, "effort_limit": effort_limit, "step": step,
              "previous_gains": dict(previous_gains), "law": law}
    if loop == "position":
        return {**common, **_design_position(
            mass, damping, period_s, plant, robot, joint, pose, effort_limit, effort_flag,
            bandwidth_hz=bandwidth_hz, zeta=zeta, step=step, settling_s=settling_s, derivative=derivative,
            safety=safety, gravity_m_s2=gravity_m_s2, ramp_s=ramp_s, reference=reference, remedies=remedies,
            integrator=integrator, feedforward=feedforward, law=law)}
    step = abs(step)  # a velocity loop's check steps up: the bandwidth is the same both ways
    gains = design(mass, damping, loop=loop, bandwidth_hz=bandwidth_hz, zeta=zeta, period_s=period_s)
    need = gains["p"] * step + gravity
    if need > effort_limit:
        achievable = _achievable_hz(mass, damping, loop, zeta, (effort_limit - gravity) / step)
        raise IdentificationError(
            f"a step of {step:g} would ask {need:.4g} of the joint's {effort_flag} {effort_limit:g} (p {gains['p']:.4g}"
            f" and a gravity load of {gravity:.4g}); the most this step allows is {achievable:.3g} Hz",
            field="bandwidth_hz", value=bandwidth_hz)
    model = LoopModel(mass, damping, gains["p"], gains["i"], gains["d"], period_s, loop, derivative)
    check_step, note, step_plan = _bounded_step(model, robot, joint, pose, safety, gravity_m_s2, plant, loop,
                                                step, step, None, effort_limit, gravity)
    return {**common, "derivative": None, "check_step": check_step, **({"note": note} if note else {}),
            "step_plan": step_plan, "spec": {"bandwidth_hz": bandwidth_hz, "zeta": None, "overshoot_pct": None,
                                             "settling_s": settling_s},
            "gains": gains, "model": {"bandwidth_hz": _model_bandwidth(model, bandwidth_hz)}}


def _hold_profile(plant: dict | None, robot, joint: str, pose: dict, gravity_m_s2):
    """``τ_hold(q)`` [N or N·m] for the step model: an identified plant's constant ``gravity_load_n``, else
    the robot model's over the joint's range (:func:`~jointctl.identification.step_loop.holding_effort`)."""
    if plant is not None:
        load = float(plant.get("gravity_load_n", 0.0))
        return HoldingEffort.constant(load) if load else None
    return holding_effort(robot, joint, pose, gravity_m_s2)


def _design_position(mass: float, damping: float, period_s: float, plant, robot, joint: str, pose: dict,
                     effort_limit: float, effort_flag: str, *, bandwidth_hz: float, zeta: float, step: float,
                     settling_s: float | None, derivative: str, safety: Safety, gravity_m_s2, ramp_s: float,
                     reference: float | None, remedies: tuple[str, ...], integrator: str = "hold",
                     feedforward: bool = False, law: str = "ros_control") -> dict:
    """A position loop's gains for the move that will run (see :func:`tune` and
    :mod:`jointctl.identification.step_design`): the linear design for ``zeta`` and ``bandwidth_hz`` first;
    its step overshoot (``exp(-πζ/√(1-ζ²))``) and settling time (``settling_s``, else the linear loop's) are
    then met on the loop as it runs at the step, when the linear design does not already meet them there."""
    kind, law = law, "measurement" if "measurement" in remedies else derivative
    feedforward = feedforward or "feedforward" in remedies
    hold = _hold_profile(plant, robot, joint, pose, gravity_m_s2)
    start = float(pose.get(joint, 0.0)) if reference is None else float(reference)
    controller_limit = effort_limit if effort_flag == "effort limit" else _urdf_effort(robot, joint)
    try:
        linear = design(mass, damping, loop="position", bandwidth_hz=bandwidth_hz, zeta=zeta, period_s=period_s,
                        derivative=law)
    except IdentificationError as exc:
        if "own damping" not in exc.message:
            raise
        linear = undamped_design(mass, damping, bandwidth_hz, period_s)
    linear_model = LoopModel(mass, damping, linear["p"], 0.0, linear["d"], period_s, "position", law)
    t, y = _model_step(linear_model, seconds=max(3.0, 3.0 * (settling_s or 0.0)))
    target_overshoot = 100 * overshoot_of(zeta)
    target_settling = settling_s if settling_s is not None else settling_time(t, y, 0.0, float(y[-1]))
    asked_ramp = ramp_s
    base = JointLoop(mass, damping, period_s, controller_limit, hold, p=linear["p"], d=linear["d"], derivative=law,
                     feedforward=feedforward, integrator=integrator, law=kind)
    clamp = _integral_clamp(base, start, step, controller_limit) if "integral" in remedies else None
    if clamp is not None:
        base = with_integral(base, target_settling, clamp, INTEGRAL_TIMES[0])

    def reference_for(ts: float) -> np.ndarray:
        return reference_step(start, step, hold_s=0.05, ramp_s=ramp_s, after_s=check_after_s(ts), period_s=period_s)

    for _ in range(3):
        if "ramp" in remedies and not asked_ramp:
            # The ramp whose kick fits the gains designed with it (a few rounds: the gains follow the ramp).
            ramp_s = max(ramp_s, ramp_for_kick(base.with_gains(effort_limit=effort_limit), step, start=start))
        moves = reference_for(target_settling)
        first = base.step(moves)
        close = (abs(_finite(first.overshoot_pct) - target_overshoot) <= OVERSHOOT_TOLERANCE_PCT
                 and math.isfinite(first.settling_s)
                 and abs(first.settling_s / target_settling - 1) <= SETTLING_TOLERANCE)
        if close:
            binds = binding(base, first, moves, target_overshoot, target_settling)
            found = StepDesign(base, first, not binds, binds)
        else:
            found = solve_step(base, moves, overshoot_pct=target_overshoot, settling_s=target_settling,
                               integral_clamp=clamp)
        if "ramp" not in remedies or asked_ramp or ramp_for_kick(
                found.loop.with_gains(effort_limit=effort_limit), step, start=start) <= ramp_s:
            break
        base = found.loop
    promised_settling = target_settling
    cap = effort_limit if effort_flag == "--max-effort" else math.inf
    if "lower-bandwidth" in remedies and (not found.met and "effort" in found.binds
                                          or found.figures.peak_effort > cap):
        promised_settling, found = lowest_settling(base, reference_for, overshoot_pct=target_overshoot,
                                                   settling_s=target_settling, integral_clamp=clamp, effort_cap=cap)
        moves = reference_for(promised_settling)
    figures = found.figures
    gains = found.loop.gains
    q, v, u = found.loop.run(moves)
    binds = list(found.binds) if not found.met else []
    if law == "error" and not ramp_s and found.loop.d * abs(step) / period_s > controller_limit:
        kick = f"the derivative kick d·step/period {found.loop.d * abs(step) / period_s:.4g} is clamped at the " \
               f"effort limit {controller_limit:g} (designed for)"
    else:
        kick = None
    peak_effort = float(np.abs(u).max())
    if effort_flag == "--max-effort" and peak_effort > effort_limit:
        binds.append("max-effort")
    step_plan = _step_plan(robot, joint, pose, safety, q, v, u, start, step, effort_limit, effort_flag,
                           ramp_s)
    model = LoopModel(mass, damping, gains["p"], gains["i"], gains["d"], period_s, "position", law)
    predicted = {"bandwidth_hz": _model_bandwidth(model, bandwidth_hz), **figures.as_dict()}
    notes = [n for n in (kick, step_plan.pop("note", None)) if n]
    if promised_settling != target_settling:
        notes.append(f"settling relaxed from {target_settling:.3g} s to {promised_settling:.3g} s: the most the "
                     f"{effort_flag} allows at this step (--remedy lower-bandwidth)")
    return {"derivative": law, "feedforward": ["gravity"] if feedforward else [], "ramp_s": ramp_s,
            "reference": start, "model_rest": found.loop.rest(start)[0], "model_integral": found.loop.rest(start)[1],
            "check_step": step, **({"note": "; ".join(notes)} if notes else {}),
            "step_plan": step_plan, "remedies": list(remedies), "binds": binds,
            "spec": {"bandwidth_hz": bandwidth_hz, "zeta": zeta, "overshoot_pct": target_overshoot,
                     "settling_s": settling_s, "step_settling_s": promised_settling},
            "gains": gains, "model": predicted, "linear_gains": linear}


def check_after_s(settling_s: float) -> float:
    """How long a step is watched [s], on the model and on the robot alike (the final value is the mean of
    its last 0.2 s): 3 s, or five settling times."""
    return max(3.0, 5 * settling_s)


def _finite(value: float) -> float:
    return value if math.isfinite(value) else 0.0


def _urdf_effort(robot, joint: str) -> float:
    spec = robot.joint(joint)
    return spec.limits.effort if spec.limits is not None and spec.limits.effort > 0 else math.inf


def _integral_clamp(loop: JointLoop, start: float, step: float, limit: float) -> float:
    """The integral's clamp [N or N·m] for a loaded joint: twice the largest load over the move, within the
    effort limit (the integral must hold the load, and no more than that is its job)."""
    load = max(abs(loop.load(start)), abs(loop.load(start + step)))
    clamp = 2.0 * load if load > 0 else 0.1 * limit
    return float(min(clamp, limit)) if math.isfinite(limit) else float(clamp)


def undamped_design(mass: float, damping: float, bandwidth_hz: float, period_s: float) -> dict:
    """Gains ``{"p", "i", "d"}`` for a plant whose own damping exceeds the ζ asked at ``bandwidth_hz``: d = 0,
    and the p whose sampled loop has that -3 dB bandwidth (the loop is then better damped than asked)."""
    wb = 2 * math.pi * bandwidth_hz

    def miss(x):
        model = LoopModel(mass, damping, x[0], 0.0, 0.0, period_s, "position", "measurement")
        gain, _ = model.response([bandwidth_hz])
        return [gain[0] + 3.0103]

    # An overdamped loop's bandwidth is about p/b: the start.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        (p,) = fsolve(miss, [max(damping * wb, mass * wb**2)], xtol=1e-10)
    return {"p": float(p), "i": 0.0, "d": 0.0}


def loop_zeta(mass: float, damping: float, p: float, d: float = 0.0) -> float:
    """The damping ratio ``(b + d)/(2·√(p·m))`` of the mass-damper loop."""
    return (damping + d) / (2 * math.sqrt(p * mass)) if p > 0 and mass > 0 else math.nan


def _step_plan(robot, joint: str, pose: dict, safety: Safety, q, v, u, start: float, step: float,
               effort_limit: float, effort_flag: str, ramp_s: float) -> dict:
    """The step's predicted peaks beside their limits: refused (IdentificationError naming the limit) when
    its motion leaves the joint's range or ``--workspace``, or moves faster than the velocity limit or
    ``--max-velocity``; what binds ("step": the step asked fits)."""
    envelope = envelope_for(robot, joint, start, safety, pose=pose)
    lower, upper = envelope.window
    # The guard stops a move that comes within its band of the URDF range's ends: so must the plan.
    band = GUARD_FRACTION * (envelope.upper - envelope.lower) if math.isfinite(envelope.upper - envelope.lower) else 0
    lower, upper = max(lower, envelope.lower + band), min(upper, envelope.upper - band)
    low, high = float(min(q.min(), start, start + step)), float(max(q.max(), start, start + step))
    unit = envelope.unit
    names = envelope.limit_names()
    if low < lower or high > upper:
        beyond = low if low < lower else high
        raise IdentificationError(f"a step of {step:g} {unit} from {start:.4g} would reach {beyond:.4g} {unit}, "
                                  f"beyond {names['position']} [{envelope.window[0]:g}, {envelope.window[1]:g}] "
                                  f"less the guard's {band:.3g} {unit} at each end of the range: ask a smaller --step",
                                  field="--step", value=step)
    speed = float(np.abs(v).max())
    if speed > envelope.velocity_max:
        raise IdentificationError(f"a step of {step:g} {unit} would move at {speed:.3g} {unit}/s, beyond "
                                  f"{names['velocity']} {envelope.velocity_max:g}: ask a smaller --step, or a ramp "
                                  "(--ramp-s)", field="--step", value=step)
    return {"step": step, "ramp_s": ramp_s, "binds": "step", "peak_position": high if step >= 0 else low,
            "peak_velocity": speed, "peak_effort": float(np.abs(u).max()), "effort_limit": effort_limit,
            "effort_flag": effort_flag, "velocity_limit": envelope.velocity_max, "window": [lower, upper],
            "room": envelope.room}


def _bounded_step(model: LoopModel, robot, joint: str, pose: dict, safety: Safety, gravity_m_s2, plant, loop: str,
                  asked: float, check_step: float, note: str | None, effort_limit: float, gravity: float):
    """(check step, note, its plan): ``check_step`` (``asked``, or less for the effort) made no larger
    than what keeps the model's step response within the position and speed budgets of ``safety``
    (the robot at ``pose``); the plan holds the step's predicted peaks beside their limits and what
    binds: "position", "velocity", "effort" or "step" (the step asked fits)."""
    n = int(round(3.0 / model.period_s))
    q, v, u = model.simulate(np.ones(n))
    # Per unit step: the swing (a position loop's reference counts too), the speed and the effort.
    per_unit = {"position": max(1.0 if loop == "position" else 0.0, float(np.abs(q).max())),
                "velocity": float(np.abs(v).max()), "effort": float(np.abs(u).max())}
    envelope = envelope_for(robot, joint, float(pose.get(joint, 0.0)), safety, pose=pose, gravity_m_s2=gravity_m_s2,
                            friction=plant_friction(plant))
    budgets = envelope.budgets()
    limits = {k: budgets[k] / per_unit[k] if per_unit[k] > 0 else math.inf for k in ("position", "velocity")}
    binds = min(limits, key=limits.get)
    if limits[binds] < check_step:
        unit = envelope.unit + ("/s" if loop == "velocity" else "")
        names = envelope.limit_names()
        extra = (f"the check steps by {limits[binds]:.3g} {unit}, not {check_step:g}: its response would "
                 f"{'swing' if binds == 'position' else 'move at'} {per_unit[binds] * check_step:.3g} "
                 f"{envelope.unit}{'/s' if binds == 'velocity' else ''}, beyond "
                 f"{safety.range_fraction if binds == 'position' else safety.speed_fraction:g} of "
                 f"{names[binds]} ({budgets[binds]:.3g})")
        note = f"{note}; {extra}" if note else extra
        check_step = limits[binds]
    binds = binds if limits[binds] <= check_step * (1 + 1e-9) else "effort" if check_step < asked else "step"
    plan = {"step": check_step, "binds": binds,
            "peak_position": per_unit["position"] * check_step, "peak_velocity": per_unit["velocity"] * check_step,
            "peak_effort": per_unit["effort"] * check_step + gravity, "effort_limit": effort_limit,
            "velocity_limit": envelope.velocity_max, "window": list(envelope.window), "room": envelope.room,
            "budgets": budgets}
    return check_step, note, plan


def _warn(result: dict, safety: Safety | None) -> None:
    """Add a warning to ``result``'s ``warnings`` for each part of the check on the robot whose share of
    cycles at the actuator's limits was above the threshold."""
    safety = safety or DEFAULT
    robot = result.get("robot") or {}
    saturation = robot.get("saturation") or {}
    warnings_ = []
    step = saturation.get("step")
    if step and step["share"] > safety.saturation_share:
        warnings_.append(f"the check step saturated the actuator: {step['text']}; the step figures are not the "
                         "linear loop's")
    sweep = saturation.get("sweep_share") or []
    hit = [f for f, share in zip(saturation.get("sweep_hz") or [], sweep) if share > safety.saturation_share]
    if hit:
        warnings_.append(f"the check sweep saturated the actuator at {', '.join(f'{f:.3g}' for f in hit)} Hz; the "
                         "measured bandwidth is not the linear loop's")
    result.setdefault("warnings", []).extend(warnings_)


def autotune_servoed(session: Session, controller_name: str, *, bandwidth_hz: float, zeta: float = 0.7,
                     step: float | None = None, plant: dict | None = None, gravity_m_s2=(0.0, 0.0, -9.81),
                     out_dir: str | Path | None = None, check_on_robot: bool = True,
                     settling_s: float | None = None, safety: Safety | None = None) -> dict:
    """Tune a loop that runs on a served robot (``session.hardware`` a
    :class:`~jointctl.ros.served_hardware.ServedRobotHardware`: the served node's controller, its
    gains through dynamic_reconfigure; or a ros2_control robot's
    :class:`~jointctl.ros2.served_hardware.ServedRos2Hardware`, its gains the controller's parameters).
    The design is :func:`tune`'s; the check sets the new gains on the robot, steps and sweeps it
    through the command topic, and puts the previous gains back whatever happens; the YAML is the
    robot's controller parameters with the new gains (the hardware's ``tuned_parameters`` when it has
    one: a ros2_control parameters file)."""
    step = DEFAULT_STEP if step is None else step
    _check_spec(bandwidth_hz, step)
    hardware = session.hardware
    joint = hardware.joint_of(controller_name)
    loop = hardware.controllers[joint][0]
    hardware.read()
    pose = {name: hardware.position[k] for k, name in enumerate(hardware.joint_names)}
    spec = session.robot.joint(joint)
    effort_limit = spec.limits.effort if spec.limits is not None and spec.limits.effort > 0 else math.inf
    gravity = None if plant is not None else _gravity_load(session.robot, pose, joint, gravity_m_s2)
    previous = hardware.gains(controller_name)
    # The law the served controller runs: its parameters' ``derivative``, else ros_controllers' (error).
    law = derivative_law(hardware.controller_parameters().get(controller_name.rsplit("/", 1)[-1], {}))
    result = tune(controller_name, joint, loop, session.loop.period_s, plant, session.robot, pose, gravity,
                  effort_limit, previous, bandwidth_hz=bandwidth_hz, zeta=zeta, step=step, settling_s=settling_s,
                  derivative=law, safety=safety, gravity_m_s2=gravity_m_s2,
                  reference=held_reference(hardware, joint) if loop == "position" else None)
    if check_on_robot:
        hardware.set_gains(controller_name, result["gains"])
        try:
            result["robot"] = _check_servoed(session, joint, loop, result["check_step"], bandwidth_hz,
                                             gains=result["gains"], derivative=law, plant=plant, safety=safety)
        finally:
            hardware.set_gains(controller_name, previous)
        result["gains_restored"] = hardware.gains(controller_name)
        _warn(result, safety)
    result.setdefault("warnings", []).extend(spec_warnings(result))
    if out_dir is not None:
        tuned = getattr(hardware, "tuned_parameters", None)
        if tuned is not None:
            _write_document(out_dir, *tuned(controller_name, result["gains"]), controller_name, result)
        else:
            namespace = hardware.namespace
            _write(out_dir, f"{namespace}_tuned_params.yaml", {namespace: hardware.controller_parameters()},
                   controller_name, result)
    return result


def spec_warnings(result: dict) -> list[str]:
    """A sentence for each figure of the model's prediction and of the check on the robot that misses
    the spec by more than its margin (:mod:`jointctl.metrics.expectations`: bandwidth 5 %, step
    overshoot 3 points, settling time 10 %, the latter when the spec gave one), or that was not
    measured at all (a step that never settled)."""
    from jointctl.metrics.expectations import expectation_warnings

    spec = result["spec"]
    # A spec given as overshoot and settling time asks for no bandwidth (its bandwidth is the ideal loop's).
    asked = ("overshoot_pct", "settling_s") if spec.get("settling_s") is not None else (
        "bandwidth_hz", "overshoot_pct", "settling_s")
    wanted = {key: spec.get(key) for key in asked}
    wanted = {key: float(value) for key, value in wanted.items() if value is not None}
    found = []
    for where, figures in (("the model", result.get("model")), ("the robot", result.get("robot"))):
        if not figures:
            continue
        # The robot's step figures carry a step_ prefix.
        measured = {key: figures.get(key, figures.get(f"step_{key}")) for key in wanted}
        why = {"settling_s": " (the step did not settle in the record)",
               "bandwidth_hz": " (the gain never fell 3 dB in the sweep)"}
        for key, value in measured.items():
            if (key in figures or f"step_{key}" in figures) and (value is None or not math.isfinite(value)):
                found.append(f"on {where}, {key}: not measured{why.get(key, '')}, spec {wanted[key]:.4g}.")
        found += [f"on {where}, {sentence}" for sentence in expectation_warnings(measured, wanted, against="spec")]
    return found


def _gravity_load(robot, pose: dict, joint: str, gravity_m_s2) -> float:
    """|gravity effort| [N or N·m] on ``joint`` at ``pose`` (joint name -> position), from the robot model."""
    from jointctl.model.dynamics import RobotDynamics

    dynamics = RobotDynamics(robot, gravity_m_s2=gravity_m_s2)
    names = [j.name for j in robot.movable_joints]
    dynamics.set_pose([float(pose.get(n, 0.0)) for n in names])
    return float(abs(dynamics.gravity_at_pose()[names.index(joint)]))


def _achievable_hz(mass: float, damping: float, loop: str, zeta: float, p_max: float) -> float:
    if p_max <= 0:
        return 0.0
    if loop == "velocity":
        return (p_max + damping) / mass / (2 * math.pi)
    return math.sqrt(p_max / mass) * bandwidth_ratio(zeta) / (2 * math.pi)


def _model_bandwidth(model: LoopModel, around_hz: float) -> float:
    f = np.logspace(math.log10(around_hz / 10), math.log10(min(around_hz * 10, 0.45 / model.period_s)), 400)
    gain, _ = model.response(f)
    dc, _ = model.response([around_hz / 1000])
    return _crossing(f, gain - dc[0], -3.0103)


def design_fields(result: dict) -> dict:
    """The controller file's fields that run ``result``'s loop (:func:`~jointctl.identification.gain_files.fields_of`):
    its PID gains (the integral's clamp and anti-windup with an integral), its derivative law and gravity
    feed-forward when a remedy changed them; ros_control's names, or pid_controller's ``gains.<joint>.*``."""
    return fields_of(result["gains"], law=result.get("law", "ros_control"), joint=result.get("joint"),
                     derivative=result.get("derivative"), feedforward="gravity" in (result.get("feedforward") or ()))


def _overrides(controller_name: str, result: dict) -> list[str]:
    """The scenario overrides that run ``result``'s loop (:func:`design_fields`)."""
    return setting_overrides(controller_name, design_fields(result))


def _rest_override(result: dict) -> list[str]:
    """The joint placed where the designed loop rests holding its reference (the model's rest): a check that
    starts there does not begin with the droop's own transient."""
    if result.get("loop") != "position" or result.get("reference") is None:
        return []
    return [f"initial_positions.{result['joint']}={result['model_rest']!r}"] if "model_rest" in result else []


def _check_on_robot(scenario_for, controller_name: str, result: dict, loop: str, bandwidth_hz: float | None, *,
                    plant: dict | None = None, safety: Safety | None = None, sweep: bool = True) -> dict:
    """The simulated robot with ``result``'s loop: the move designed for (a step of ``check_step`` from the
    reference, along ``ramp_s``) from rest, and (``sweep``) a sweep around the bandwidth (each sine at most the
    step, inside the safe amplitude); the saturation of both."""
    scenario = scenario_for([*_overrides(controller_name, result), *_rest_override(result)])
    session = Session(scenario)
    controller, _ = loop_controller(session.manager, controller_name, result["joint"] if loop == "position" else None)
    if result.get("model_integral"):
        # As on a robot that has held its pose: the integral holds the load it carries there.
        controller.pid.i_state = float(result["model_integral"])
    step = result["check_step"]
    figures = _step(session, controller.joint, controller.set_reference, loop, step, safety=safety,
                    effort_limit=controller.effort_limit,
                    after_s=check_after_s(result["spec"].get("step_settling_s") or 0.0),
                    reference=result.get("reference", controller.reference_input[0]) if loop == "position" else None,
                    ramp_s=result.get("ramp_s") or 0.0)
    if not sweep:
        session.close()
        return figures
    frequencies = np.logspace(math.log10(bandwidth_hz / 2.5), math.log10(bandwidth_hz * 2.5), 15)
    points, _ = measure(scenario, controller_name, frequencies, amplitude_cap=step, plant=plant, safety=safety)
    low, _ = measure(scenario, controller_name, [bandwidth_hz / 20], amplitude_cap=step, plant=plant, safety=safety)
    figures["bandwidth_hz"] = _crossing(frequencies, np.array([p.gain_db for p in points]) - low[0].gain_db,
                                        -3.0103)
    _sweep_saturation(figures, [*low, *points])
    return figures


def _sweep_saturation(figures: dict, points) -> None:
    """The check sweep's amplitudes and shares of saturated cycles, per frequency, into ``figures['saturation']``."""
    saturation = figures.setdefault("saturation", {})
    saturation["sweep_hz"] = [p.frequency_hz for p in points]
    saturation["sweep_amplitude"] = [p.amplitude for p in points]
    saturation["sweep_share"] = [p.saturation for p in points]


def _check_servoed(session: Session, joint: str, loop: str, step: float, bandwidth_hz: float, *,
                   gains: dict | None = None, derivative: str = "error", plant: dict | None = None,
                   safety: Safety | None = None) -> dict:
    """The served robot with the new gains: a step from rest and a shorter sweep (real time), the
    sweep's gain taken relative to a fifth of the bandwidth."""
    _, set_reference = servo_reference(session.hardware, joint)
    frequencies = [bandwidth_hz / 5, *np.logspace(math.log10(bandwidth_hz / 2), math.log10(bandwidth_hz * 2), 7)]
    points, context = measure_servoed(session, joint, frequencies, amplitude_cap=step, settle_s=0.5,
                                      measure_periods=3, measure_s=0.5, gains=gains, derivative=derivative,
                                      plant=plant, safety=safety)
    gain = np.array([p.gain_db for p in points[1:]])
    figures = _step(session, joint, set_reference, loop, step, hold_s=0.5, after_s=2.0, safety=safety,
                    reference=context["rest"] if loop == "position" else None)
    figures["bandwidth_hz"] = _crossing(np.array(frequencies[1:]), gain - points[0].gain_db, -3.0103)
    _sweep_saturation(figures, points)
    # Back where it started: the reference it held (a step as planned, the other way).
    set_reference(figures["step_reference"] if loop == "position" else 0.0)
    with session:
        session.run(1.0)
    return figures


def _step(session: Session, joint: str, set_reference, loop: str, step: float, *, hold_s: float = 1.0,
          after_s: float = 3.0, safety: Safety | None = None, effort_limit: float | None = None,
          reference: float | None = None, ramp_s: float = 0.0) -> dict:
    """A step of ``step`` from rest after ``hold_s``, along a ramp of ``ramp_s`` [s], watched for ``after_s``:
    the figures of :func:`~jointctl.identification.step_loop.step_figures` (overshoot [%], 2 % settling time,
    start, final value and its distance to the reference, peak effort), the damping ratio the overshoot
    implies (a position loop), and the share of its cycles at the actuator's limits; the user's limits
    guarded (SafetyStop, the joint brought back). A position loop's reference steps from ``reference``, the
    one it holds (default: where the joint is; a loop under gravity rests below its reference, and stepping
    from there would step the reference by less than ``step``, or backwards, the derivative on the error
    kicking accordingly)."""
    safety = safety or DEFAULT
    hardware = session.hardware
    index = hardware.joint_index(joint)
    measured = hardware.position if loop == "position" else hardware.velocity
    samples: list[tuple[float, float, float]] = []
    start: dict = {}
    began = session.loop.time_s
    hardware.read()
    lower, upper, _ = session.robot.joint(joint).range_and_speed()
    held = hardware.position[index] if reference is None or loop != "position" else float(reference)
    envelope = envelope_for(session.robot, joint, held, safety, effort_limit=effort_limit,
                            pose=dict(zip(hardware.joint_names, hardware.position)))
    guard = Guard(hardware, index, envelope, loop=loop, start=held if loop == "position" else 0.0,
                  band=GUARD_FRACTION * (upper - lower) if math.isfinite(upper - lower) else math.inf)
    monitor = SaturationMonitor(hardware, index, envelope.effort_limit, envelope.velocity_limit,
                                safety.saturation_margin)
    origin = held if loop == "position" else 0.0

    def target(time_s: float) -> float:
        moved = time_s - began - hold_s
        if moved < 0:
            return origin
        return origin + step * (min(1.0, moved / ramp_s) if ramp_s > 0 else 1.0)

    def drive(time_s: float) -> None:
        # The reference held from the first cycle (the controller started holding where the joint was).
        value = guard.reference(time_s, target(time_s))
        if time_s - began >= hold_s and "value" not in start:
            start["value"] = measured[index]
            start["reference"] = origin
        set_reference(value)

    def record(time_s: float) -> None:
        if time_s - began >= hold_s - session.loop.period_s / 2:
            samples.append((measured[index], target(time_s), hardware.effort[index]))

    session.loop.add_input(drive)
    watchers = (record, monitor, guard.observe)  # bound once: removal compares identity
    for hook in watchers:
        session.loop.add_observer(hook)
    try:
        run_guarded(session, hold_s + after_s, guard)
    finally:
        session.loop.remove_input(drive)
        for hook in watchers:
            session.loop.remove_observer(hook)
    if guard.trip is not None:
        raise guard.error("the check step")
    y, r, u = (np.array(column) for column in zip(*samples))
    figures = step_figures(np.arange(y.size) * session.loop.period_s, y, r, u)
    overshoot = figures.overshoot_pct
    share = monitor.share(began + hold_s - 1e-9)
    position = loop == "position"
    return {"step_overshoot_pct": float(overshoot) if position else None,
            "step_zeta": zeta_of(overshoot / 100) if position else None,
            "step_settling_s": figures.settling_s, "step_final": figures.final, "step_start": figures.start,
            "step_final_error": figures.final_error, "step_peak_effort": figures.peak_effort,
            "step_reference": start.get("reference", origin),
            "saturation": {**monitor.describe(), "threshold": safety.saturation_share,
                           "step": {**share, "text": saturation_text(share, monitor, envelope.unit)}}}


def _write(out_dir, file_name: str, document: dict, controller_name: str, result: dict, *,
           overrides: dict | None = None) -> None:
    """The controller ``document`` (a ros_control file's tree, or a ROS 2 parameters file's) with what ``--set``
    changed of the controller (``overrides``, a scenario's ``controller_overrides``) and the tuned gains
    (:func:`design_fields`: with a remedy's derivative law and gravity feed-forward), as ``file_name`` in
    ``out_dir``, and ``metrics.json`` (strict JSON: a figure not measured or unbounded is null)."""
    tuned = tuned_document(document, controller_name, design_fields(result), file_name, overrides=overrides)
    _write_document(out_dir, file_name, tuned, controller_name, result)


def _write_document(out_dir, file_name: str, tuned: dict, controller_name: str, result: dict) -> None:
    """``tuned`` (a controller file with ``controller_name``'s tuned gains in) as ``file_name`` in ``out_dir``
    under a header naming the spec, and ``metrics.json``; ``result["yaml"]`` the file's path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    header = (f"# {file_name} with {controller_name} tuned by jointctl autotune for "
              f"{result['spec']['bandwidth_hz']:g} Hz" + (f", damping ratio {result['spec']['zeta']:g}"
                                                         if result["loop"] == "position" else "") + ".\n")
    path = out / file_name
    path.write_text(header + yaml.safe_dump(tuned, sort_keys=False))
    result["yaml"] = str(path)
    write_metrics(out, result)  # strict JSON: a figure not measured or unbounded is null


__all__ = ["DEFAULT_STEP", "autotune", "autotune_servoed", "bandwidth_ratio", "design", "loop_zeta", "overshoot_of",
           "scenario_move", "settling_time", "spec_from_step", "spec_warnings", "the_move", "tune", "undamped_design",
           "zeta_of"]

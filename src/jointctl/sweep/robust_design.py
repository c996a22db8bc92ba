"""Robust autotune: PD gains that meet a step spec on every plant of a family, checked by a sweep.

``jointctl autotune ... --robust payload_kg=0:5 --robust model.joint1.damping=7:13`` designs a joint's
position loop against the plants a real robot may be (SI units throughout):

1. **The family.** Each ``FIELD=a:b`` is a range of what the robot leaves uncertain: ``payload_kg`` (a point
   mass at the payload link, :mod:`jointctl.scenario.plant`) or ``model.<link|joint>.<field>`` (link masses and
   inertias, joint damping, friction, armature). The family's plants: every corner of the ranges, their centre,
   and ``samples`` uniform draws inside them (a generator seeded with ``seed``). For each, the joint's inertia
   ``m_k`` (the varied model's mass-matrix diagonal at the scenario's pose), its damping ``b_k`` and gravity
   load ``g_k``.
2. **The design.** The sampled loop of :class:`~jointctl.identification.frequency_response.LoopModel` (the
   controller's derivative law, the loop period) with gains ``(p, d)`` gives each plant a model step response:
   its overshoot [%], 2 % settling time [s] and -3 dB bandwidth [Hz]. The gains minimise, by Nelder-Mead on
   ``(ln p, ln d)`` from the nominal design and from the design for the family's heaviest plant,
   ``J = 10·(Σ_spec terms max(0, worst normalised miss over the plants) + effort miss) + 1e-3·p/p_nominal``:
   the worst case over the family first, the softest loop among those that meet the spec second (aiming 5 %
   inside the spec: ``DESIGN_MARGIN``). Every plant's step must end at the reference (0.1 %) and the loop hold the
   heaviest gravity load within half the step (``p ≥ max g_k / (0.5·step)``, as ``jointctl init``). The effort
   miss counts ``p·step + max g_k`` beyond the joint's effort limit (autotune's rule).
3. **The check.** A sweep on the simulated robot (:func:`jointctl.sweep.sweep.run_sweep`: the engine, in this
   process unless a cluster is named) of a step on the joint over each range's three levels, once with the
   nominal gains and once with the robust ones, both judged against the spec. The sweep runs without gravity:
   a constant load only shifts where a prismatic joint rests, and a payload's sag would still ring when the
   step came (its steady state is the design's effort check's business). The report puts the nominal design's
   worst case beside the robust one's, on the model and on the robot.

Theory on the 1-DOF robot (derivative on the measurement, ``ωn = sqrt(p/m)``, ``ζ = (b + d)/(2 sqrt(p m))``):
the nominal design for 1.01 kg rings with a 5 kg payload (ζ falls as 1/sqrt(m)); the robust one damps the
heaviest plant enough and stiffens the lightest.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from jointctl.errors import ConfigError
from jointctl.identification.autotune import _model_bandwidth, autotune, design, settling_time
from jointctl.identification.frequency_response import LoopModel
from jointctl.model.dynamics import RobotDynamics
from jointctl.model.loader import load_robot_model
from jointctl.scenario.spec import Scenario
from jointctl.scenario.plant import check_model_value, check_payload, model_target, payload_link, varied_plant
from jointctl.sweep.variations import MODEL_PREFIX, PAYLOAD

#: Length of the model step each plant's figures are read from [s]: five settling times asked, at least 1 s.
STEP_SECONDS = 1.0
#: Weight of the softness term: small beside any miss of the spec.
SOFTNESS = 1e-3
#: How far from the reference a plant's model step may end (a share of the step).
FINAL_ERROR = 1e-3
#: The design aims this much inside the spec (settling time 5 % shorter, bandwidth 5 % higher, overshoot 5 %
#: lower): the simulated robot's figures are read off a record, not the model's grid, and a design right on the
#: edge of the spec fails it there by the rounding (0.3015 s for a 0.3 s settling time on the 1-DOF robot).
DESIGN_MARGIN = 0.05


@dataclass(frozen=True)
class Range:
    """``field`` uncertain between ``low`` and ``high`` (SI units of the field)."""

    field: str
    low: float
    high: float


@dataclass(frozen=True)
class Plant:
    """One plant of the family: the varied values, the joint's inertia [kg or kg·m²], damping [N·s/m or
    N·m·s/rad] and gravity load [N or N·m]."""

    values: dict
    inertia: float
    damping: float
    gravity_load: float


def parse_range(item: str) -> Range:
    """``"payload_kg=0:5"`` -> Range; a ConfigError naming ``--robust`` and the item otherwise."""
    field, sep, text = item.partition("=")
    field = field.strip()
    parts = text.split(":")
    if not sep or not field or len(parts) != 2:
        raise ConfigError("expected FIELD=LOW:HIGH (payload_kg or model.<link|joint>.<field>)", field="--robust",
                          value=item)
    try:
        low, high = (float(p) for p in parts)
    except ValueError:
        raise ConfigError("LOW and HIGH must be numbers", field="--robust", value=item) from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise ConfigError("must be finite with LOW below HIGH", field="--robust", value=item)
    if field != PAYLOAD and not field.startswith(MODEL_PREFIX):
        raise ConfigError("a design's family varies the plant: payload_kg or model.<link|joint>.<field>",
                          field="--robust", value=item)
    return Range(field, low, high)


def family(scenario: Scenario, joint: str, ranges: Sequence[Range], *, samples: int = 8,
           seed: int = 0) -> list[Plant]:
    """The family of the module docstring for ``joint`` of the scenario's robot, at its initial pose."""
    if not ranges:
        raise ConfigError("needs at least one FIELD=LOW:HIGH", field="--robust")
    if not (isinstance(samples, int) and samples >= 0):
        raise ConfigError("must be a whole number, 0 or more", field="--robust-samples", value=samples)
    robot = load_robot_model(scenario.robot.description)
    for r in ranges:  # every field and value checked before anything is computed
        if r.field == PAYLOAD:
            check_payload(r.low)
        else:
            _, _, attribute = model_target(robot, r.field)
            check_model_value(r.field, attribute, r.low)
    link = payload_link(robot, scenario.robot.extras, scenario.source) if any(r.field == PAYLOAD for r in ranges) \
        else None
    lows, highs = np.array([r.low for r in ranges]), np.array([r.high for r in ranges])
    corners = [np.where(np.array(bits), highs, lows) for bits in np.ndindex(*(2,) * len(ranges))]
    rng = np.random.default_rng(seed)
    draws = [lows + (highs - lows) * rng.random(len(ranges)) for _ in range(samples)]
    points = [*corners, 0.5 * (lows + highs), *draws]
    names = [j.name for j in robot.movable_joints]
    pose = [float(scenario.initial_positions.get(n, 0.0)) for n in names]
    plants = []
    for point in points:
        values = {r.field: float(v) for r, v in zip(ranges, point)}
        payload = values.get(PAYLOAD, 0.0)
        varied = varied_plant(robot, {k: v for k, v in values.items() if k != PAYLOAD}, payload, link)
        dynamics = RobotDynamics(varied, gravity_m_s2=scenario.gravity_m_s2)
        dynamics.set_pose(pose)
        k = names.index(joint)
        plants.append(Plant(values, float(dynamics.mass_matrix()[k, k]), float(varied.joint(joint).damping),
                            abs(float(dynamics.gravity_at_pose()[k]))))
    return plants


def plant_figures(plant: Plant, gains: dict, period_s: float, derivative: str, *, bandwidth: bool = False,
                  seconds: float = STEP_SECONDS) -> dict:
    """The model step's overshoot [%] and settling time [s] (NaN when it does not settle within ``seconds``) of
    ``plant`` under ``gains`` (and its -3 dB bandwidth [Hz] and phase margin [deg] with ``bandwidth``)."""
    model = LoopModel(plant.inertia, plant.damping, gains["p"], 0.0, gains["d"], period_s, "position", derivative)
    t, y = model.step(seconds)
    final = float(y[-1])
    out = {"overshoot_pct": 100 * float((y.max() - final) / final) if math.isfinite(final) and final else math.nan,
           "settling_time_s": settling_time(t, y, 0.0, final) if math.isfinite(final) else math.nan,
           "final_error": abs(1.0 - final) if math.isfinite(final) else math.inf}
    if bandwidth:
        out["bandwidth_hz"] = _model_bandwidth(model, max(math.sqrt(gains["p"] / plant.inertia) / (2 * math.pi), 0.1))
        out["phase_margin_deg"] = model.margins()["phase_margin_deg"]
    return out


def worst_case(plants: Sequence[Plant], gains: dict, period_s: float, derivative: str, *,
               bandwidth: bool = False, seconds: float = 3.0) -> dict:
    """Over the family: the largest overshoot, settling time and final error, the smallest bandwidth and phase
    margin (python-control's, on the sampled loop), and which plant."""
    rows = [plant_figures(p, gains, period_s, derivative, bandwidth=bandwidth, seconds=seconds) for p in plants]
    out = {}
    for key, worse in (("overshoot_pct", max), ("settling_time_s", max), ("final_error", max),
                       ("bandwidth_hz", min), ("phase_margin_deg", min)):
        if key not in rows[0]:
            continue
        values = [math.inf if not math.isfinite(r[key]) and worse is max else r[key] for r in rows]
        k = values.index(worse(values))
        out[key] = rows[k][key] if math.isfinite(rows[k][key]) else None
        out[f"{key}_at"] = plants[k].values
    return out


def robust_gains(plants: Sequence[Plant], nominal_gains: dict, *, period_s: float, derivative: str,
                 overshoot_pct: float, settling_s: float | None, bandwidth_hz: float | None, step: float,
                 effort_limit: float) -> tuple[dict, float]:
    """(gains, J) minimising the module docstring's J over the family."""
    gravity = max(p.gravity_load for p in plants)
    heaviest = max(plants, key=lambda p: p.inertia)
    seconds = max(STEP_SECONDS, 5 * settling_s) if settling_s is not None else 3.0
    stiffness = gravity / (0.5 * step)  # the least p that holds the load within half the step [N/m or N·m/rad]

    def cost(x) -> float:
        if not (-20 < x[0] < 30 and -20 < x[1] < 30):  # gains beyond any joint's
            return 1e6
        gains = {"p": math.exp(x[0]), "i": 0.0, "d": math.exp(x[1])}
        misses = []
        figures = [plant_figures(p, gains, period_s, derivative, bandwidth=bandwidth_hz is not None, seconds=seconds)
                   for p in plants]
        overshoot = max(f["overshoot_pct"] for f in figures)
        aim = overshoot_pct * (1 - DESIGN_MARGIN)
        misses.append(max(0.0, (overshoot - aim) / max(aim, 1.0)) if math.isfinite(overshoot) else 10.0)
        # The step must end at the reference (a loop without p ends where its derivative kick left it), and the
        # loop hold the heaviest gravity load within half the step (the stiffness jointctl init asks for too).
        misses.append(max(0.0, max(f["final_error"] for f in figures) / FINAL_ERROR - 1.0))
        misses.append(max(0.0, stiffness / gains["p"] - 1.0))
        if settling_s is not None:
            settle = max((f["settling_time_s"] if math.isfinite(f["settling_time_s"]) else 10 * STEP_SECONDS)
                         for f in figures)
            misses.append(max(0.0, settle / (settling_s * (1 - DESIGN_MARGIN)) - 1.0))
        if bandwidth_hz is not None:
            slowest = min(f["bandwidth_hz"] for f in figures)
            misses.append(max(0.0, 1.0 - slowest / (bandwidth_hz * (1 + DESIGN_MARGIN))) if math.isfinite(slowest)
                          else 10.0)
        effort = max(0.0, (gains["p"] * step + gravity) / effort_limit - 1.0) if math.isfinite(effort_limit) else 0.0
        return 10.0 * (sum(misses) + effort) + SOFTNESS * gains["p"] / nominal_gains["p"]

    starts = [nominal_gains]
    try:
        starts.append(design(heaviest.inertia, heaviest.damping, loop="position",
                             bandwidth_hz=bandwidth_hz or _bandwidth_of(nominal_gains, plants[0]),
                             zeta=_zeta_of(overshoot_pct), period_s=period_s, derivative=derivative))
    except Exception:  # noqa: BLE001 - a start that cannot be designed is only one start fewer
        pass
    best = None
    for start in starts:
        x0 = [math.log(max(start["p"], 1e-6)), math.log(max(start["d"], 1e-3 * max(start["p"], 1e-6)))]
        found = minimize(cost, x0, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-5, "maxiter": 300})
        if best is None or found.fun < best.fun:
            best = found
    return {"p": float(math.exp(best.x[0])), "i": 0.0, "d": float(math.exp(best.x[1]))}, float(best.fun)


def _zeta_of(overshoot_pct: float) -> float:
    from jointctl.identification.autotune import zeta_of

    zeta = zeta_of(overshoot_pct / 100)
    return zeta if math.isfinite(zeta) else 0.9


def _bandwidth_of(gains: dict, plant: Plant) -> float:
    return max(math.sqrt(gains["p"] / plant.inertia) / (2 * math.pi), 0.1)


def robust_autotune(scenario_for: Callable, controller_name: str, ranges: Iterable[str | Range], *,
                    overshoot_pct: float, settling_s: float | None, zeta: float, bandwidth_hz: float, step: float,
                    target: str, controllers: str | None = None, overrides: Sequence[str] = (), samples: int = 8,
                    seed: int = 0, scheduler: str | None = None, workers: int | None = None,
                    verify: bool = True) -> dict:
    """The nominal design (:func:`~jointctl.identification.autotune.autotune`, no check on the robot), the
    robust one against the family, each one's worst case on the model and, with ``verify``, on the simulated
    robot by a sweep of ``target`` (see the module docstring). ``scenario_for(overrides)`` gives the loop's
    scenario, as for autotune."""
    ranges = [r if isinstance(r, Range) else parse_range(r) for r in ranges]
    nominal = autotune(scenario_for, controller_name, bandwidth_hz=bandwidth_hz, zeta=zeta, step=step,
                       check_on_robot=False, settling_s=settling_s)
    if nominal["loop"] != "position":
        raise ConfigError("a robust design is for a position loop", field="--controller", value=controller_name)
    scenario = scenario_for(())
    joint, law = nominal["joint"], nominal["derivative"]
    period_s = scenario.loop_period_s
    plants = family(scenario, joint, ranges, samples=samples, seed=seed)
    by_bandwidth = settling_s is None
    gains, cost = robust_gains(plants, nominal["gains"], period_s=period_s, derivative=law,
                               overshoot_pct=nominal["spec"]["overshoot_pct"], settling_s=settling_s,
                               bandwidth_hz=bandwidth_hz if by_bandwidth else None, step=step,
                               effort_limit=nominal["effort_limit"])
    spec = {"overshoot_pct": nominal["spec"]["overshoot_pct"], "settling_s": settling_s,
            "bandwidth_hz": bandwidth_hz if by_bandwidth else None}
    gravity = max(p.gravity_load for p in plants)
    result = {
        "controller": controller_name, "joint": joint, "derivative": law, "spec": spec,
        "family": {"ranges": [r.__dict__ for r in ranges], "plants": len(plants), "samples": samples, "seed": seed,
                   "inertia": [min(p.inertia for p in plants), max(p.inertia for p in plants)],
                   "damping": [min(p.damping for p in plants), max(p.damping for p in plants)],
                   "gravity_load_max": gravity},
        "nominal": {"gains": nominal["gains"],
                    "model_worst": worst_case(plants, nominal["gains"], period_s, law, bandwidth=True)},
        "robust": {"gains": gains, "cost": cost,
                   "model_worst": worst_case(plants, gains, period_s, law, bandwidth=True),
                   "effort_at_step": gains["p"] * step + gravity, "effort_limit": nominal["effort_limit"]},
    }
    result["meets_spec_on_model"] = _meets(result["robust"]["model_worst"], spec)
    if verify:
        rest = float(scenario.initial_positions.get(joint, 0.0))
        for name in ("nominal", "robust"):
            gains_ = result[name]["gains"]
            # With the derivative on the error a step's first cycle asks d·step/period too: the check steps
            # by the most that fits the effort limit then (autotune's rule), so the loop stays linear.
            kick = gains_["d"] / period_s if law == "error" else 0.0
            check_step = min(step, (nominal["effort_limit"] - gravity) / (gains_["p"] + kick)) \
                if math.isfinite(nominal["effort_limit"]) else step
            result[name]["check_step"] = check_step
            result[name]["robot_worst"] = _verify(target, controllers, overrides, controller_name, joint, rest,
                                                  check_step, gains_, ranges, spec, scheduler, workers)
    return result


def write_robust(out_dir, scenario: Scenario, controller_name: str, result: dict) -> Path:
    """The scenario's controller file with the robust gains (as autotune writes its design) and
    ``metrics.json`` into ``out_dir``; the YAML's path (also ``result["yaml"]``)."""
    import copy

    import yaml

    from jointctl.control.manager import read_yaml, set_dotted
    from jointctl.recording.metrics_file import write_metrics

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    source = Path(scenario.controller_file)
    document = copy.deepcopy(read_yaml(source))
    body = next(iter(document.values())) if len(document) == 1 and controller_name not in document else document
    if controller_name not in body:
        raise ConfigError("the controller is not in its file", source=str(source), field=controller_name)
    for key, value in scenario.controller_overrides.items():  # what --set changed of it runs in the design too
        if key.startswith(f"{controller_name}."):
            set_dotted(body[controller_name], key[len(controller_name) + 1:], value, source="--set")
    body[controller_name].setdefault("pid", {}).update({k: round(v, 6) for k, v in result["robust"]["gains"].items()})
    ranges = ", ".join(f"{r['field']} {r['low']:g} to {r['high']:g}" for r in result["family"]["ranges"])
    path = out / source.name
    path.write_text(f"# {source.name} with {controller_name} tuned by jointctl autotune --robust: the spec on every "
                    f"plant of {ranges}.\n" + yaml.safe_dump(document, sort_keys=False))
    result["yaml"] = str(path)
    write_metrics(out, result)
    return path


def _meets(worst: dict, spec: dict) -> bool:
    ok = worst.get("overshoot_pct") is not None and worst["overshoot_pct"] <= spec["overshoot_pct"] + 1e-6
    if spec.get("settling_s") is not None:
        ok = ok and worst.get("settling_time_s") is not None and worst["settling_time_s"] <= spec["settling_s"]
    return ok


def _verify(target, controllers, overrides, controller_name, joint, rest, step, gains, ranges, spec, scheduler,
            workers) -> dict:
    """The worst case of a step sweep over the ranges' three levels on the simulated robot with ``gains``."""
    from jointctl.sweep.engine import Engine
    from jointctl.sweep.sweep import run_sweep

    terms = [f"overshoot_pct<={spec['overshoot_pct']:.6g}"]
    if spec.get("settling_s") is not None:
        terms.append(f"settling_time_s<={spec['settling_s']:.6g}")
    step_overrides = [
        *overrides, "gravity=0", "duration_s=3",
        f"commands.{controller_name}={{type: step, from: {rest!r}, to: {rest + step!r}, at: 0.5}}",
        f"analysis={{type: step_response, joint: {joint}}}",
        *(f"controllers.{controller_name}.pid.{k}={v!r}" for k, v in gains.items()),
    ]
    variations = [f"{r.field}={r.low!r}:{r.high!r}:3" for r in ranges]
    with Engine(scheduler=scheduler, workers=workers, in_process=scheduler is None and workers is None) as engine:
        swept = run_sweep(target, variations, controllers=controllers, overrides=step_overrides,
                          spec=",".join(terms), engine=engine, nominal=False, figures=False)
    out = {"runs": len(swept.rows), "passed": len(swept.passed), "failed": len(swept.failed),
           "errors": [row.error for row in swept.errors]}
    for metric in ("overshoot_pct", "settling_time_s"):
        value, row = swept.worst(metric)
        out[metric] = value
        out[f"{metric}_at"] = row.values if row is not None else None
    return out


__all__ = ["Plant", "Range", "family", "parse_range", "plant_figures", "robust_autotune", "robust_gains",
           "worst_case", "write_robust"]

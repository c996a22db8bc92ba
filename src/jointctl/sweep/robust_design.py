"""Robust autotune: gains that meet a step spec at the user's step on every plant of a family, checked plant by
plant on the simulated robot.

``jointctl autotune ... --robust payload_kg=0:5 --robust model.joint1.damping=7:13`` designs a joint's
position loop against the plants a real robot may be (SI units throughout):

1. **The family.** Each ``FIELD=a:b`` is a range of what the robot leaves uncertain: ``payload_kg`` (a point
   mass at the payload link, :mod:`jointctl.scenario.plant`) or ``model.<link|joint>.<field>`` (link masses and
   inertias, joint damping, friction, armature). The family's plants: every corner of the ranges, their centre,
   and ``samples`` uniform draws inside them (a generator seeded with ``seed``). For each, the joint's inertia
   ``m_k`` (the varied model's mass-matrix diagonal at the scenario's pose), its damping ``b_k`` and the effort
   ``τ_k(q)`` holding it against gravity over the joint's range (a payload adds to both the mass and the load).
2. **The move.** The step that will run: ``step`` (``--step``), else the scenario's own step of the controller,
   else autotune's default, from the reference the controller holds, along the scenario's or ``--ramp-s``'s ramp.
3. **The design.** Each plant's loop as it runs at that step
   (:class:`~jointctl.identification.step_loop.JointLoop`: the controller's own derivative law with its clamped
   kick, the effort clamp, the plant's gravity load over the move, MuJoCo's integration; with ``--remedy
   feedforward`` the controller's gravity feed-forward, which knows the nominal model only: a payload's weight
   stays the loop's to hold). For a trial stiffness ``p`` the damping ``d`` whose largest overshoot over the
   plants is the one asked (Brent's method: each plant's overshoot falls as ``d`` grows), and ``p`` scaled
   until the longest settling time is the one asked (a loop's time scale goes as ``1/√p``), as
   :mod:`jointctl.identification.step_design` does for one plant. The search runs on the plants found worst so
   far (the heaviest, the lightest and the most loaded to begin with): after each search every plant is run,
   and the worst overshoot and the worst settling join the searched ones until they are among them.
4. **What binds.** Each plant is judged at the step: its overshoot at most 3 points above the one asked, its
   settling at most 15 % longer, its rest within the 2 % settling band of the step; and the worst plant lands on
   the spec (within 3 points and 15 % either way). A plant that misses says why (autotune's words,
   :func:`~jointctl.identification.step_design.binding`): "gravity" (it rests beyond the band from its
   reference), "effort" (it misses with the actuator at its limit), "damping" (even ``d = 0`` overshoots less
   than asked), "spec" (none of these). For each, the ``--remedy`` that answers it
   (:data:`~jointctl.identification.step_design.REMEDIES`) is designed against the family too and checked on the
   simulated robot; the user picks one by the flag.
5. **The check.** Each plant of the family runs on the simulated robot (one ordinary run per plant,
   :class:`~jointctl.sweep.engine.Engine`: in this process unless a cluster is named), with gravity, at the
   step: the joint placed where the loop rests holding its start reference (the integral, which a run starts
   empty, given the time to take up its load before the step), the figures read off the run's trace as autotune
   reads its own check (:func:`~jointctl.identification.step_loop.step_figures`). The nominal design (autotune's
   for the scenario's own plant, at the same step) is run the same way beside it. The figures the report
   presents as what the user gets are these measurements (``robot_worst``); the model's are ``model_worst``.

Theory on the 1-DOF robot (a vertical piston, 1.01 kg, damping 10 N·s/m, under gravity): a P loop rests
``(m + payload)·g/p`` below its reference; a 5 kg payload on a loop of 10 % in 0.3 s for the bare piston rests
further off than the 2 % band of a 0.3 m step (``p ≥ 59 N / 6 mm ≈ 9800 N/m`` would be needed, ``p·step`` 2.9 kN
beyond the 1000 N limit): gravity binds, and the integral holds the load.
"""

from __future__ import annotations

import math
import uuid
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from jointctl.errors import ConfigError
from jointctl.identification.autotune import autotune, check_after_s, scenario_move, settling_time
from jointctl.identification.frequency_response import LoopModel
from jointctl.identification.gain_files import fields_of, setting_overrides, tuned_document
from jointctl.identification.plant_fit import IdentificationError
from jointctl.identification.step_design import (INTEGRAL_TIMES, OVERSHOOT_TOLERANCE_PCT, REMEDIES,
                                                 SATURATION_SHARE, SETTLING_TOLERANCE, overshoot_at, ramp_for_kick,
                                                 remedy_lacking, with_integral)
from jointctl.identification.step_loop import (SETTLING_BAND, JointLoop, StepFigures, holding_effort,
                                               reference_step, step_figures)
from jointctl.model.dynamics import RobotDynamics
from jointctl.model.loader import load_robot_model
from jointctl.scenario.plant import check_model_value, check_payload, model_target, payload_link, varied_plant
from jointctl.scenario.spec import Scenario
from jointctl.sweep.variations import MODEL_PREFIX, PAYLOAD

#: The spec's tolerances (autotune's): overshoot within this many percentage points of the one asked ...
OVERSHOOT_POINTS = 3.0
#: ... and settling within this share of the time asked.
SETTLING_SHARE = 0.15
#: How long a check run holds its start reference before the step [s] (the joint placed where the loop rests).
HOLD_S = 0.5
#: With an integral, which a run starts empty: the hold lasts until its slowest mode has brought the joint this
#: share of the step from its reference (a tenth of the settling band) ...
INTEGRAL_RESIDUE = 0.002
#: ... but no longer than this [s].
LONGEST_HOLD_S = 60.0
#: The searches on the worst plants found so far: at most this many rounds.
ROUNDS = 4


@dataclass(frozen=True)
class Range:
    """``field`` uncertain between ``low`` and ``high`` (SI units of the field)."""

    field: str
    low: float
    high: float


@dataclass(frozen=True)
class Plant:
    """One plant of the family: the varied values, the joint's inertia [kg or kg·m²], damping [N·s/m or
    N·m·s/rad], the gravity load at the scenario's pose [N or N·m, magnitude] and ``hold``, the effort holding
    the joint against gravity at a position (:func:`~jointctl.identification.step_loop.holding_effort`; None:
    no load)."""

    values: dict
    inertia: float
    damping: float
    gravity_load: float
    hold: Callable[[float], float] | None = field(default=None, compare=False, repr=False)


def parse_range(item: str) -> Range:
    """``"payload_kg=0:5"`` -> Range; a ConfigError naming ``--robust`` and the item otherwise."""
    field_, sep, text = item.partition("=")
    field_ = field_.strip()
    parts = text.split(":")
    if not sep or not field_ or len(parts) != 2:
        raise ConfigError("expected FIELD=LOW:HIGH (payload_kg or model.<link|joint>.<field>)", field="--robust",
                          value=item)
    try:
        low, high = (float(p) for p in parts)
    except ValueError:
        raise ConfigError("LOW and HIGH must be numbers", field="--robust", value=item) from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise ConfigError("must be finite with LOW below HIGH", field="--robust", value=item)
    if field_ != PAYLOAD and not field_.startswith(MODEL_PREFIX):
        raise ConfigError("a design's family varies the plant: payload_kg or model.<link|joint>.<field>",
                          field="--robust", value=item)
    return Range(field_, low, high)


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
    pose = {n: float(scenario.initial_positions.get(n, 0.0)) for n in names}
    k = names.index(joint)
    plants = []
    for point in points:
        values = {r.field: float(v) for r, v in zip(ranges, point)}
        payload = values.get(PAYLOAD, 0.0)
        varied = varied_plant(robot, {k_: v for k_, v in values.items() if k_ != PAYLOAD}, payload, link)
        dynamics = RobotDynamics(varied, gravity_m_s2=scenario.gravity_m_s2)
        dynamics.set_pose([pose[n] for n in names])
        plants.append(Plant(values, float(dynamics.mass_matrix()[k, k]), float(varied.joint(joint).damping),
                            abs(float(dynamics.gravity_at_pose()[k])),
                            holding_effort(varied, joint, pose, scenario.gravity_m_s2)))
    return plants


def member(loop: JointLoop, plant: Plant) -> JointLoop:
    """``loop`` (its gains, law, clamp, feed-forward) closed around ``plant``."""
    return replace(loop, mass=plant.inertia, damping=plant.damping, hold=plant.hold)


@dataclass(frozen=True)
class FamilyDesign:
    """A design against the family: ``loop`` (the gains, law, feed-forward; its plant the nominal one), each
    plant's ``figures`` at the step and what ``binds`` there (empty where the plant meets the spec), ``met``
    when no plant binds; ``settling_s`` the settling time designed for [s] (the one asked, or longer with
    ``--remedy lower-bandwidth``), ``ramp_s`` the step's ramp [s]."""

    loop: JointLoop
    figures: tuple[StepFigures, ...]
    binds: tuple[tuple[str, ...], ...]
    met: bool
    settling_s: float
    ramp_s: float


def plant_binds(figures: StepFigures, move: float, overshoot_pct: float, settling_s: float) -> list[str]:
    """What keeps one plant's ``figures`` at a step of ``move`` from the spec (one-sided: a plant of the family
    may do better than asked; the module docstring's words)."""
    binds = []
    if abs(figures.final_error) > SETTLING_BAND * abs(move):
        binds.append("gravity")
    overshoot = figures.overshoot_pct if math.isfinite(figures.overshoot_pct) else 0.0
    ok = overshoot <= overshoot_pct + OVERSHOOT_POINTS and math.isfinite(figures.settling_s) \
        and figures.settling_s <= settling_s * (1 + SETTLING_SHARE)
    if not ok and figures.saturated_share > SATURATION_SHARE:
        binds.append("effort")
    if not ok and not binds:
        binds.append("spec")
    return binds


def family_binds(figures: Sequence[StepFigures], d: float, move: float, overshoot_pct: float,
                 settling_s: float) -> tuple[tuple[str, ...], ...]:
    """:func:`plant_binds` of every plant, and the worst plant held to the spec from below too (within 3 points
    and 15 %): a worst overshoot below the spec with ``d = 0`` binds as "damping"."""
    binds = [plant_binds(f, move, overshoot_pct, settling_s) for f in figures]
    overshoots = [f.overshoot_pct if math.isfinite(f.overshoot_pct) else 0.0 for f in figures]
    k = int(np.argmax(overshoots))
    if overshoots[k] < overshoot_pct - OVERSHOOT_POINTS:
        binds[k].append("damping" if d == 0.0 else "spec")
    settlings = [f.settling_s if math.isfinite(f.settling_s) else math.inf for f in figures]
    k = int(np.argmax(settlings))
    if settlings[k] < settling_s * (1 - SETTLING_SHARE):
        binds[k].append("spec")
    return tuple(tuple(dict.fromkeys(b)) for b in binds)


def family_damping(loop: JointLoop, plants: Sequence[Plant], reference: np.ndarray,
                   overshoot_pct: float) -> JointLoop:
    """``loop`` with the ``d`` whose largest overshoot over ``plants`` answering ``reference`` is
    ``overshoot_pct`` (Brent's method; each plant's overshoot falls as ``d`` grows); ``d = 0`` when even that
    overshoots less."""
    loops = [member(loop, p) for p in plants]

    def miss(d: float) -> float:
        return max(overshoot_at(m.with_gains(d=d), reference) for m in loops) - overshoot_pct

    if miss(0.0) <= 0:
        return loop.with_gains(d=0.0)
    low = 0.0
    high = max(2 * math.sqrt(loop.p * max(p.inertia for p in plants)), 1e-6)
    for _ in range(40):
        if miss(high) < 0:
            break
        low, high = high, 2 * high
    else:
        return loop.with_gains(d=high)
    d = brentq(miss, low, high, xtol=1e-9 * high, rtol=1e-4, maxiter=60)
    return loop.with_gains(d=float(d))


def _search(loop: JointLoop, plants: Sequence[Plant], reference: np.ndarray, overshoot_pct: float,
            settling_s: float, integral: tuple[float, float] | None, iterations: int) -> JointLoop:
    """The gains on ``plants`` (the worst so far): for each trial ``p`` the ``d`` of :func:`family_damping`,
    ``p`` scaled until the longest settling is ``settling_s``; the closest found."""
    best: tuple[float, JointLoop, float] | None = None
    p = loop.p
    previous = None
    for _ in range(iterations):
        trial = loop.with_gains(p=p)
        if integral is not None:
            trial = with_integral(trial, settling_s, *integral)
        trial = family_damping(trial, plants, reference, overshoot_pct)
        figures = [member(trial, plant).step(reference) for plant in plants]
        settling = max(f.settling_s if math.isfinite(f.settling_s) else 10 * settling_s for f in figures)
        miss = abs(settling / settling_s - 1)
        overshoot = max(_finite(f.overshoot_pct) for f in figures)
        if best is None or miss < best[0]:
            best = (miss, trial, overshoot)
        if miss < SETTLING_TOLERANCE:
            break
        if previous is not None and settling > settling_s and settling > 0.98 * previous:
            break  # a stiffer loop settles no sooner: the effort limit sets the pace
        previous = settling if settling > settling_s else None
        p *= min(16.0, max(1 / 16.0, (settling / settling_s) ** 2))
    _, found, overshoot = best
    # The search reads each overshoot to the first peak past the rest it expects; the whole record's can differ
    # a little (an integral's slow tail): once, aim off by what that costs.
    off = overshoot - overshoot_pct
    if abs(off) > OVERSHOOT_TOLERANCE_PCT:
        trial = family_damping(found, plants, reference, overshoot_pct - off)
        again = max(_finite(member(trial, plant).step(reference).overshoot_pct) for plant in plants)
        if abs(again - overshoot_pct) < abs(off):
            found = trial
    return found


def _first_worst(plants: Sequence[Plant]) -> list[int]:
    """The plants searched first: the heaviest, the lightest, the most loaded and the least damped."""
    keys = (lambda k: plants[k].inertia, lambda k: -plants[k].inertia, lambda k: plants[k].gravity_load,
            lambda k: -plants[k].damping)
    return sorted({max(range(len(plants)), key=key) for key in keys})


def solve_family(loop: JointLoop, plants: Sequence[Plant], reference: np.ndarray, *, overshoot_pct: float,
                 settling_s: float, integral_clamp: float | None = None, iterations: int = 14,
                 ramp_s: float = 0.0) -> FamilyDesign:
    """The gains of ``loop`` (its law, clamp and feed-forward kept; ``p`` the starting guess) that meet the spec
    on every plant answering ``reference`` (module docstring, 3 and 4); with ``integral_clamp`` [N or N·m], an
    integral as :func:`~jointctl.identification.step_design.with_integral` makes it, of the time constants of
    :data:`~jointctl.identification.step_design.INTEGRAL_TIMES` that meet the spec the one needing the least
    ``p``."""
    if integral_clamp is None:
        return _solve_family(loop, plants, reference, overshoot_pct, settling_s, None, iterations, ramp_s)
    found = [_solve_family(loop, plants, reference, overshoot_pct, settling_s, (integral_clamp, times), iterations,
                           ramp_s) for times in INTEGRAL_TIMES]
    met = [design for design in found if design.met]
    return min(met, key=lambda design: design.loop.p) if met else min(found, key=_shortfall)


def _shortfall(design: FamilyDesign) -> tuple[int, float]:
    """How far a design is from the spec: the plants that bind, then the worst rest [m or rad]."""
    return sum(1 for b in design.binds if b), max(abs(f.final_error) for f in design.figures)


def _solve_family(loop: JointLoop, plants: Sequence[Plant], reference: np.ndarray, overshoot_pct: float,
                  settling_s: float, integral: tuple[float, float] | None, iterations: int,
                  ramp_s: float) -> FamilyDesign:
    active = _first_worst(plants)
    for _ in range(ROUNDS):
        found = _search(loop, [plants[k] for k in active], reference, overshoot_pct, settling_s, integral,
                        iterations)
        figures = [member(found, plant).step(reference) for plant in plants]
        worst = {int(np.argmax([_finite(f.overshoot_pct) for f in figures])),
                 int(np.argmax([f.settling_s if math.isfinite(f.settling_s) else math.inf for f in figures]))}
        if worst <= set(active):
            break
        active = sorted(set(active) | worst)
        loop = loop.with_gains(p=found.p)
    move = float(reference[-1] - reference[0])
    binds = family_binds(figures, found.d, move, overshoot_pct, settling_s)
    return FamilyDesign(found, tuple(figures), binds, not any(binds), settling_s, ramp_s)


def _finite(value: float) -> float:
    return value if math.isfinite(value) else 0.0


def integral_clamp(loop: JointLoop, plants: Sequence[Plant], start: float, step: float) -> float:
    """The integral's clamp [N or N·m] against a family: twice the largest load over the move that the
    feed-forward leaves it (autotune's rule, the heaviest plant's), within the effort limit."""
    load = max(abs(member(loop, plant).load(q) - member(loop, plant).feedforward_effort(q))
               for plant in plants for q in (start, start + step))
    clamp = 2.0 * load if load > 0 else 0.1 * loop.effort_limit
    return float(min(clamp, loop.effort_limit)) if math.isfinite(loop.effort_limit) else float(clamp)


def design_family(base: JointLoop, plants: Sequence[Plant], start: float, step: float, *, overshoot_pct: float,
                  settling_s: float, remedies: Sequence[str] = (), ramp_s: float = 0.0) -> FamilyDesign:
    """Gains for the family at a step of ``step`` from ``start`` [m or rad] along ``ramp_s`` [s], on ``base``
    (the controller's law and limit, ``p`` the start; ``remedies`` as autotune's ``--remedy``: "measurement"
    and "feedforward" are ``base``'s, "integral" adds one, "ramp" ramps the step so that every plant's kick
    fits, "lower-bandwidth" the shortest settling, from ``settling_s`` up to ten times it, that every plant
    meets)."""
    period = base.period_s
    asked_ramp = ramp_s
    clamp = integral_clamp(base, plants, start, step) if "integral" in remedies else None

    def reference_for(ts: float) -> np.ndarray:
        return reference_step(start, step, hold_s=0.05, ramp_s=ramp_s, after_s=check_after_s(ts), period_s=period)

    def kick_ramp(loop: JointLoop) -> float:
        return max(ramp_for_kick(member(loop, plant), step) for plant in plants)

    for _ in range(3):
        if "ramp" in remedies and not asked_ramp:
            ramp_s = max(ramp_s, kick_ramp(base))  # the ramp whose kick fits the gains designed with it
        found = solve_family(base, plants, reference_for(settling_s), overshoot_pct=overshoot_pct,
                             settling_s=settling_s, integral_clamp=clamp, ramp_s=ramp_s)
        if "ramp" not in remedies or asked_ramp or kick_ramp(found.loop) <= ramp_s:
            break
        base = found.loop
    if "lower-bandwidth" in remedies and not found.met and any("effort" in b or "spec" in b for b in found.binds):
        found = _lowest_settling(base, plants, reference_for, overshoot_pct, settling_s, clamp, ramp_s)
    return found


def _lowest_settling(base: JointLoop, plants, reference_for, overshoot_pct: float, settling_s: float, clamp,
                     ramp_s: float, widest: float = 10.0) -> FamilyDesign:
    """The family's design for the shortest settling time, from ``settling_s`` up to ``widest`` times it, that
    every plant meets (bisection on the time, as
    :func:`~jointctl.identification.step_design.lowest_settling`); the one at ``widest`` times when none does."""
    def attempt(ts: float) -> FamilyDesign:
        return solve_family(base, plants, reference_for(ts), overshoot_pct=overshoot_pct, settling_s=ts,
                            integral_clamp=clamp, ramp_s=ramp_s)

    high = widest * settling_s
    found = attempt(high)
    if not found.met:
        return found
    low = settling_s
    for _ in range(8):
        middle = math.sqrt(low * high)
        trial = attempt(middle)
        if trial.met:
            high, found = middle, trial
        else:
            low = middle
        if high / low < 1.03:
            break
    return found


def robust_autotune(scenario_for: Callable, controller_name: str, ranges: Iterable[str | Range], *,
                    overshoot_pct: float, settling_s: float | None, zeta: float, bandwidth_hz: float,
                    step: float | None, target: str, controllers: str | None = None, overrides: Sequence[str] = (),
                    samples: int = 8, seed: int = 0, scheduler: str | None = None, workers: int | None = None,
                    verify: bool = True, remedies: Sequence[str] = (), ramp_s: float | None = None,
                    alternatives: bool = True) -> dict:
    """The nominal design (:func:`~jointctl.identification.autotune.autotune` at the step, no check on the
    robot), the robust one against the family at the same step, each one's figures per plant on the model and,
    with ``verify``, on the simulated robot (module docstring). ``scenario_for(overrides)`` gives the loop's
    scenario, as for autotune; ``step`` and ``ramp_s`` as autotune takes them; ``remedies`` autotune's
    ``--remedy``. With ``alternatives``, a spec missed on some plant gets each remedy that answers what binds
    designed against the family and checked on the simulated robot."""
    ranges = [r if isinstance(r, Range) else parse_range(r) for r in ranges]
    remedies = tuple(remedies)
    nominal = autotune(scenario_for, controller_name, bandwidth_hz=bandwidth_hz, zeta=zeta, step=step,
                       check_on_robot=False, settling_s=settling_s, ramp_s=ramp_s, remedies=remedies,
                       alternatives=False)
    if nominal["loop"] != "position":
        raise ConfigError("a robust design is for a position loop", field="--controller", value=controller_name)
    scenario = scenario_for(())
    joint = nominal["joint"]
    move = scenario_move(scenario, controller_name)  # the ramp asked: --ramp-s, else the scenario's with its step
    asked_ramp = ramp_s if ramp_s is not None else (move["ramp_s"] if move is not None and step is None else 0.0)
    step, start = float(nominal["step"]), float(nominal["reference"])
    plants = family(scenario, joint, ranges, samples=samples, seed=seed)
    robot = load_robot_model(scenario.robot.description)
    pose = {j.name: float(scenario.initial_positions.get(j.name, 0.0)) for j in robot.movable_joints}
    nominal_hold = holding_effort(robot, joint, pose, scenario.gravity_m_s2)
    target_overshoot = float(overshoot_pct)
    target_settling = settling_s if settling_s is not None else _linear_settling(nominal, scenario.loop_period_s)
    own_law = nominal["derivative"]  # the controller's own law, unless the remedies make it the measurement's
    own_feedforward = _gravity_feedforward(scenario, controller_name)
    limit = float(nominal["effort_limit"])
    spec = {"overshoot_pct": target_overshoot, "settling_s": target_settling, "step": step, "reference": start,
            "overshoot_points": OVERSHOOT_POINTS, "settling_share": SETTLING_SHARE, "rest_band": SETTLING_BAND,
            "bandwidth_hz": None if settling_s is not None else bandwidth_hz}

    def base_loop(remedy_set: Sequence[str]) -> JointLoop:
        law = "measurement" if "measurement" in remedy_set else own_law
        return JointLoop(plants[0].inertia, plants[0].damping, scenario.loop_period_s, limit, None,
                         p=nominal["gains"]["p"], d=nominal["gains"]["d"], derivative=law,
                         feedforward=own_feedforward or "feedforward" in remedy_set, integrator="euler",
                         feedforward_hold=nominal_hold, law=nominal["law"])

    def design_with(remedy_set: Sequence[str]) -> FamilyDesign:
        found = design_family(base_loop(remedy_set), plants, start, step, overshoot_pct=target_overshoot,
                              settling_s=target_settling, remedies=remedy_set, ramp_s=asked_ramp)
        check_limits(found, plants, robot, joint, pose, start, step)
        return found

    def check(design: FamilyDesign) -> list[dict]:
        return check_on_robot(target, controllers, overrides, controller_name, joint, design, plants, start, step,
                              target_overshoot, scheduler=scheduler, workers=workers)

    gravity = max(p.gravity_load for p in plants)
    nominal_loop = replace(base_loop(remedies), **_loop_gains(nominal))
    nominal_design = _judge(nominal_loop, plants, start, step, float(nominal["ramp_s"] or 0.0), target_overshoot,
                            float(nominal["spec"]["step_settling_s"]))
    robust = design_with(remedies)
    result = {
        "controller": controller_name, "joint": joint, "spec": spec, "remedies": list(remedies),
        "family": {"ranges": [r.__dict__ for r in ranges], "plants": len(plants), "samples": samples, "seed": seed,
                   "inertia": [min(p.inertia for p in plants), max(p.inertia for p in plants)],
                   "damping": [min(p.damping for p in plants), max(p.damping for p in plants)],
                   "gravity_load_max": gravity},
        "nominal": {**_design_report(nominal_design, plants), "designed_for": "the scenario's own plant"},
        "robust": _design_report(robust, plants),
        "effort_limit": limit,
    }
    result["spec"]["step_settling_s"] = robust.settling_s
    result["meets_spec_on_model"] = robust.met
    if verify:
        result["nominal"]["robot"] = check(nominal_design)
        result["robust"]["robot"] = check(robust)
        result["nominal"]["robot_worst"] = _worst_rows(result["nominal"]["robot"])
        result["robust"]["robot_worst"] = _worst_rows(result["robust"]["robot"])
        result["meets_spec"] = not any(row["binds"] for row in result["robust"]["robot"])
    binds = _binds_by_constraint(result["robust"], verify)
    result["binds"] = binds
    if alternatives and binds:
        result["alternatives"] = _alternatives(result, binds, design_with, check if verify else None, plants,
                                               remedies)
    result["warnings"] = robust_warnings(result)
    return result


def _gravity_feedforward(scenario: Scenario, controller_name: str) -> bool:
    """Whether the controller, as configured, adds its model's gravity effort (``feedforward: {gravity:
    true}``, as the arm's controllers do)."""
    from jointctl.scenario.session import Session

    with Session(scenario) as session:
        return "gravity" in getattr(session.manager.controller(controller_name), "feedforward_terms", ())


def check_limits(design: FamilyDesign, plants: Sequence[Plant], robot, joint: str, pose: dict, start: float,
                 step: float) -> None:
    """Refuse (IdentificationError naming the plant) a design whose step would take some plant of the family
    out of the joint's range or faster than its velocity limit (autotune's step plan, its budgets), before
    anything moves."""
    from jointctl.identification.autotune import _step_plan
    from jointctl.identification.safety import DEFAULT

    reference = reference_step(start, step, hold_s=0.05, ramp_s=design.ramp_s,
                               after_s=check_after_s(design.settling_s), period_s=design.loop.period_s)
    for plant in plants:
        q, v, u = member(design.loop, plant).run(reference)
        try:
            _step_plan(robot, joint, pose, DEFAULT, q, v, u, start, step, design.loop.effort_limit, "effort limit",
                       design.ramp_s)
        except IdentificationError as exc:
            where = ", ".join(f"{k} {v:.4g}" for k, v in plant.values.items())
            raise IdentificationError(f"at {where}: {exc.message}", field=exc.field, value=exc.value) from None


def _linear_settling(nominal: dict, period_s: float) -> float:
    """The settling time [s] of the linear design for the bandwidth and ζ asked (the spec given as those):
    the one autotune designs for."""
    gains = nominal["linear_gains"]
    model = LoopModel(nominal["mass"], nominal["damping"], gains["p"], 0.0, gains["d"], period_s, "position",
                      nominal["derivative"])
    t, y = model.step(3.0)
    return settling_time(t, y, 0.0, float(y[-1]))


def _loop_gains(result: dict) -> dict:
    """The JointLoop fields of a design's ``gains`` (ros_control's names)."""
    gains = result["gains"]
    out = {"p": gains["p"], "i": gains.get("i", 0.0), "d": gains["d"]}
    if gains.get("i"):
        out.update(i_clamp=gains["i_clamp"], antiwindup=bool(gains.get("antiwindup", False)))
    return out


def _judge(loop: JointLoop, plants: Sequence[Plant], start: float, step: float, ramp_s: float,
           overshoot_pct: float, settling_s: float) -> FamilyDesign:
    """Given gains (``loop``), each plant's figures at the step and what binds there."""
    reference = reference_step(start, step, hold_s=0.05, ramp_s=ramp_s, after_s=check_after_s(settling_s),
                               period_s=loop.period_s)
    figures = tuple(member(loop, plant).step(reference) for plant in plants)
    binds = family_binds(figures, loop.d, step, overshoot_pct, settling_s)
    return FamilyDesign(loop, figures, binds, not any(binds), settling_s, ramp_s)


def _design_report(design: FamilyDesign, plants: Sequence[Plant]) -> dict:
    """A design's gains, law, feed-forward and ramp, and its figures per plant on the model with their worst."""
    loop = design.loop
    rows = [{"values": plant.values, "overshoot_pct": f.overshoot_pct, "settling_s": f.settling_s,
             "final_error": f.final_error, "peak_effort": f.peak_effort, "saturated_share": f.saturated_share,
             "binds": list(b)} for plant, f, b in zip(plants, design.figures, design.binds)]
    return {"gains": {k: (bool(v) if isinstance(v, bool) else float(v)) for k, v in loop.gains.items()},
            "law": loop.law, "derivative": loop.derivative, "feedforward": ["gravity"] if loop.feedforward else [],
            "ramp_s": design.ramp_s, "settling_s": design.settling_s, "meets_spec_on_model": design.met,
            "model": rows, "model_worst": _worst_rows(rows)}


def _worst_rows(rows: Sequence[dict]) -> dict:
    """The largest overshoot, settling time (None when a plant did not settle) and rest error over ``rows``,
    each with the plant's values; how many rows there are, met the spec, and failed to run."""
    ran = [r for r in rows if not r.get("error")]
    out = {"plants": len(rows), "passed": sum(1 for r in ran if not r["binds"]),
           "errors": [r["error"] for r in rows if r.get("error")]}
    for key, size in (("overshoot_pct", _finite), ("settling_s", lambda v: v if math.isfinite(v) else math.inf),
                      ("final_error", abs)):
        if not ran:
            out[key] = out[f"{key}_at"] = None
            continue
        worst = max(ran, key=lambda r: size(_number(r[key])))
        value = _number(worst[key])
        out[key] = value if math.isfinite(value) else None
        out[f"{key}_at"] = worst["values"]
    return out


def _number(value) -> float:
    return math.nan if value is None else float(value)


def _binds_by_constraint(report: dict, verify: bool) -> dict:
    """{constraint: [plant values, ...]}: where the robust design misses the spec, on the robot when it was
    checked there (else on the model)."""
    rows = report["robot"] if verify else report["model"]
    found: dict[str, list] = {}
    for row in rows:
        for bind in row["binds"]:
            found.setdefault(bind, []).append(row["values"])
    return found


def _alternatives(result: dict, binds: dict, design_with, check, plants: Sequence[Plant],
                  applied: Sequence[str]) -> dict:
    """Each remedy that answers what binds, added to those applied, designed against the family and (with
    ``check``) run on the simulated robot: {remedy: {gains, law, feed-forward, ramp, meets, worst figures}}."""
    robust = result["robust"]
    wanted: list[str] = []
    for bind in binds:
        for remedy in REMEDIES.get("effort" if bind == "spec" else bind, ()):
            if remedy in applied or remedy in wanted or remedy_lacking(robust["law"], remedy):
                continue
            if remedy == "measurement" and robust["derivative"] == "measurement":
                continue
            if remedy == "ramp" and (robust["ramp_s"] or robust["derivative"] == "measurement"):
                continue
            if remedy == "feedforward" and robust["feedforward"]:
                continue
            wanted.append(remedy)
    found = {}
    for remedy in wanted:
        try:
            design = design_with((*applied, remedy))
        except IdentificationError as exc:
            found[remedy] = {"error": str(exc)}
            continue
        report = _design_report(design, plants)
        entry = {k: report[k] for k in ("gains", "derivative", "feedforward", "ramp_s", "settling_s",
                                         "meets_spec_on_model", "model_worst")}
        if check is not None:
            rows = check(design)
            entry["robot_worst"] = _worst_rows(rows)
            entry["meets_spec"] = not any(row["binds"] for row in rows)
            entry["binds"] = sorted({b for row in rows for b in row["binds"]})
        else:
            entry["binds"] = sorted({bind for plant in design.binds for bind in plant})
        found[remedy] = entry
    return found


def integral_hold_s(loop: JointLoop, offset: float, step: float) -> float:
    """How long a run whose integral starts empty holds its start reference [s]: until the slowest mode of
    ``loop`` (the roots of ``m s³ + (b + d) s² + p s + i``, the PID loop's characteristic polynomial with either
    derivative law) has taken ``offset`` [m or rad] (where the P term alone holds the load) to
    :data:`INTEGRAL_RESIDUE` of ``step``; at least :data:`HOLD_S`, at most :data:`LONGEST_HOLD_S`."""
    if not loop.i or not offset:
        return HOLD_S
    roots = np.roots([loop.mass, loop.damping + loop.d, loop.p, loop.i])
    rate = float(np.min(-roots.real))
    if not rate > 0:
        return LONGEST_HOLD_S
    hold = math.log(max(abs(offset) / (INTEGRAL_RESIDUE * abs(step)), 1.0)) / rate
    return float(min(LONGEST_HOLD_S, max(HOLD_S, HOLD_S + hold)))


def check_on_robot(target: str, controllers: str | None, overrides: Sequence[str], controller_name: str, joint: str,
                   design: FamilyDesign, plants: Sequence[Plant], start: float, step: float, overshoot_pct: float,
                   *, scheduler: str | None = None, workers: int | None = None) -> list[dict]:
    """Each plant of ``design``'s family run on the simulated robot at the step (module docstring, 5): per plant
    its values, the figures read off its trace (overshoot [%], 2 % settling [s], rest error [m or rad], share of
    cycles at the effort limit), whether it was still moving when the step came, what binds (or the run's
    error)."""
    from jointctl.sweep.engine import Engine
    from jointctl.sweep.runner import RunTask

    loop = design.loop
    after = check_after_s(design.settling_s)
    reuse = uuid.uuid4().hex  # the plants' runs keep the robot's model (each plant is a world of its own)
    common = [*overrides, *setting_overrides(controller_name, loop_fields(loop, joint))]
    tasks, holds = [], []
    for k, plant in enumerate(plants):
        closed = member(loop, plant)
        if loop.i:  # a run starts with the integral empty, where the P term alone holds the load
            begin = closed.with_gains(i=0.0).rest(start)[0]
            hold = integral_hold_s(closed, start - begin, step)
        else:
            begin, hold = closed.rest(start)[0], HOLD_S
        command = f"{{type: step, from: {start!r}, to: {start + step!r}, at: {hold!r}" + (
            f", ramp_s: {design.ramp_s!r}}}" if design.ramp_s else "}")
        # The step analysis's final value is its record's last tenth, which must come after the step: a long hold
        # runs longer after the step too (the figures are read over ``after``, as on the model).
        items = [*common, f"duration_s={hold + max(after, hold / 8)!r}", f"initial_positions.{joint}={begin!r}",
                 f"commands.{controller_name}={command}",
                 # The step analysis reads a step, not a ramp: its figures (the saturation) only for a step.
                 "analysis=null" if design.ramp_s else f"analysis={{type: step_response, joint: {joint}}}"]
        tasks.append(RunTask(k, target, dict(plant.values), 0, controllers, tuple(items), trace_points=10**9,
                             reuse=reuse))
        holds.append(hold)
    with Engine(scheduler=scheduler, workers=workers, in_process=scheduler is None and workers is None) as engine:
        rows, _ = engine.run(tasks)
    out = []
    for row in rows:
        entry = {"values": row.values, "hold_s": holds[row.index]}
        if row.error is not None or row.trace is None:
            out.append({**entry, "error": row.error or "no trace", "binds": ["error"]})
            continue
        trace = row.trace
        t = np.asarray(trace["time_s"]) - trace["time_s"][0]
        kept = t <= holds[row.index] + after + 1e-9
        figures = step_figures(t[kept], np.asarray(trace["position"])[kept], np.asarray(trace["reference"])[kept])
        saturated = row.metrics.get("effort_saturated_share_after_step")
        figures = replace(figures, saturated_share=float(saturated) if saturated is not None else 0.0)
        entry.update(overshoot_pct=figures.overshoot_pct, settling_s=figures.settling_s,
                     final_error=figures.final_error, start=figures.start, final=figures.final,
                     saturated_share=figures.saturated_share, moving_at_step=row.metrics.get("moving_at_step"),
                     binds=plant_binds(figures, step, overshoot_pct, design.settling_s))
        out.append(entry)
    ran = [r for r in out if "error" not in r]
    if ran:  # the worst plant held to the spec from below too, as on the model
        figures = [StepFigures(r["overshoot_pct"], r["settling_s"], r["start"], r["final"], r["final_error"], 0.0,
                               r["saturated_share"]) for r in ran]
        for r, b in zip(ran, family_binds(figures, loop.d, step, overshoot_pct, design.settling_s)):
            r["binds"] = list(b)
    return out


def loop_fields(loop: JointLoop, joint: str) -> dict:
    """The controller file's fields that run ``loop``'s gains, derivative law and feed-forward on ``joint``
    (:func:`~jointctl.identification.gain_files.fields_of`: ros_control's names, or pid_controller's)."""
    return fields_of(loop.gains, law=loop.law, joint=joint, derivative=loop.derivative, feedforward=loop.feedforward)


def report_fields(result: dict) -> dict:
    """:func:`loop_fields` of a result's robust design (its report's ``gains``, ``law``, ``derivative``,
    ``feedforward``)."""
    robust = result["robust"]
    return fields_of(robust["gains"], law=robust.get("law", "ros_control"), joint=result["joint"],
                     derivative=robust["derivative"], feedforward=bool(robust["feedforward"]))


def robust_warnings(result: dict) -> list[str]:
    """The sentences the report needs beside it: where the robust design misses the spec (on which plant, for
    which reason, with the figure measured) and each remedy checked."""
    binds = result.get("binds") or {}
    if not binds:
        return []
    robust = result["robust"]
    rows = robust.get("robot") or robust["model"]
    where = "on the simulated robot" if robust.get("robot") else "on the model"
    spec = result["spec"]
    step = spec["step"]

    def plant(values: dict) -> str:
        return ", ".join(f"{k} {v:.4g}" for k, v in values.items())

    words = []
    for bind, plants in binds.items():
        at = [r for r in rows if r["values"] in plants]
        if bind == "gravity":
            worst = max(at, key=lambda r: abs(r.get("final_error") or 0.0))
            words.append(f"the gravity load at {plant(worst['values'])}: the joint rests {worst['final_error']:.3g} "
                         f"from its reference, beyond the 2 % band of the step ({SETTLING_BAND * abs(step):.3g})"
                         + (f", and on {len(at) - 1} other plant{'s' if len(at) > 2 else ''}" if len(at) > 1 else ""))
        elif bind == "effort":
            words.append(f"the effort limit {result['effort_limit']:g} at {plant(at[0]['values'])}: the step "
                         "saturates the actuator")
        elif bind == "damping":
            words.append("the plants' own damping: even d = 0 overshoots less than asked")
        elif bind == "error":
            words.append(f"a run that failed at {plant(at[0]['values'])} ({at[0]['error']})")
        else:
            worst = max(at, key=lambda r: _finite(_number(r.get("settling_s"))))
            words.append(f"the spec itself at {plant(worst['values'])} (overshoot "
                         f"{_number(worst.get('overshoot_pct')):.3g} %, settling {_number(worst.get('settling_s')):.3g}"
                         f" s)")
    lines = [f"at the step of {step:g} the spec ({spec['overshoot_pct']:.3g} % within {OVERSHOOT_POINTS:g} points, "
             f"{spec['step_settling_s']:.3g} s within {100 * SETTLING_SHARE:g} %, the rest within the 2 % band) is "
             f"not met on every plant {where}; binds: " + "; ".join(words) + "."]
    for remedy, alt in (result.get("alternatives") or {}).items():
        if "error" in alt:
            lines.append(f"--remedy {remedy}: not possible ({alt['error']}).")
            continue
        worst = alt.get("robot_worst") or alt["model_worst"]
        meets = alt.get("meets_spec", alt["meets_spec_on_model"])
        lines.append(f"--remedy {remedy}: worst overshoot {_number(worst['overshoot_pct']):.3g} %, settling "
                     f"{_number(worst['settling_s']):.3g} s, rest {_number(worst['final_error']):.3g} from the "
                     f"reference {'on the simulated robot' if 'robot_worst' in alt else 'on the model'}"
                     + (" (meets the spec on every plant)" if meets else f" (still binds: {', '.join(alt['binds'])})")
                     + ".")
    return lines


def write_robust(out_dir, scenario: Scenario, controller_name: str, result: dict, *,
                 document: tuple[str, dict] | None = None) -> Path:
    """The scenario's controller file with the robust design (as autotune writes its design: the gains, and the
    derivative law and gravity feed-forward when a remedy changed them; a pid_controller's as its ROS 2
    parameters) and ``metrics.json`` into ``out_dir``; the YAML's path (also ``result["yaml"]``). ``document``:
    (file name, tree) to write instead, the design's fields already in (a served robot's own parameters)."""
    import yaml

    from jointctl.control.manager import read_yaml
    from jointctl.recording.metrics_file import write_metrics

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    robust = result["robust"]
    if document is None:
        source = Path(scenario.controller_file)
        # What --set changed of the controller runs in the design too.
        name, tuned = source.name, tuned_document(read_yaml(source), controller_name, report_fields(result),
                                                  str(source), overrides=scenario.controller_overrides)
    else:
        name, tuned = document
    ranges = ", ".join(f"{r['field']} {r['low']:g} to {r['high']:g}" for r in result["family"]["ranges"])
    ramp = f" along a ramp of {robust['ramp_s']:g} s" if robust["ramp_s"] else ""
    path = out / name
    path.write_text(f"# {name} with {controller_name} tuned by jointctl autotune --robust for a step of "
                    f"{result['spec']['step']:g}{ramp} on every plant of {ranges}.\n"
                    + yaml.safe_dump(tuned, sort_keys=False))
    result["yaml"] = str(path)
    write_metrics(out, result)
    return path


__all__ = ["FamilyDesign", "Plant", "Range", "check_limits", "check_on_robot", "design_family", "family",
           "family_binds", "family_damping", "integral_hold_s", "loop_fields", "member", "parse_range", "plant_binds",
           "report_fields", "robust_autotune", "robust_warnings", "solve_family", "write_robust"]

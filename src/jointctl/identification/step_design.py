"""Gains for the move that will run: a position loop's step overshoot and settling time met at the user's step,
on the loop as it really runs (:class:`~jointctl.identification.step_loop.JointLoop`: the controller's law, the
effort clamp, the gravity load).

The linear design (:func:`jointctl.identification.autotune.design`) is exact for small moves. At a real step,
with the derivative on the error, the first cycle's kick ``d·Δr/h`` is clamped by the effort limit and the
step overshoots less than designed (10 % at a 0.02 rad step, 4 % at 0.1 rad on a small arm); a large step
saturates for longer and settles later. :func:`solve_step` therefore searches the gains on the saturating
loop itself: for a trial stiffness ``p`` the damping ``d`` that gives the overshoot asked (regula falsi: the
overshoot falls as ``d`` grows), and ``p`` scaled until the settling time is the one asked (the time scale of
a loop goes as ``1/√p``). An integral (a gain in proportion to ``p``, its clamp given) and the gravity
feed-forward are part of the loop searched, when asked for.

When no gains meet the spec at that step, the search ends on the closest and says which constraint binds
(:func:`binding`): the effort limit (the step asks more than the actuator gives for the settling asked), the
gravity load (the loop rests short of its reference by more than the settling band), the plant's own
damping (even ``d = 0`` overshoots less than asked).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointctl.identification.step_loop import SETTLING_BAND, JointLoop, StepFigures

#: How close the search brings the overshoot [percentage points] and the settling time [share].
OVERSHOOT_TOLERANCE_PCT = 0.1
SETTLING_TOLERANCE = 0.03
#: The most cycles the saturation may take of the move before the effort counts as binding.
SATURATION_SHARE = 0.01


@dataclass(frozen=True)
class StepDesign:
    """The search's outcome: ``loop`` (its gains), its ``figures`` at the step, ``met`` whether they meet the
    spec (overshoot within 3 points, settling within 15 %, the rest within the settling band), and the
    constraints that bind (``binds``: "effort", "gravity", "damping"; empty when met)."""

    loop: JointLoop
    figures: StepFigures
    met: bool
    binds: tuple[str, ...]


def overshoot_at(loop: JointLoop, reference: np.ndarray) -> float:
    """The step overshoot [%] of ``loop`` answering ``reference``: its first peak past where it rests holding
    the reference's last value, as a share of the way there (0 when it does not overshoot). Run only to that
    peak: the search's many trials stay cheap."""
    q, _, _ = loop.run(reference, until_peak=True)
    final = loop.rest(float(reference[-1]))[0]
    begin = q[0]
    rise = final - begin
    if not rise:
        return 0.0
    return max(0.0, 100 * float(((q - final) * math.copysign(1.0, rise)).max()) / abs(rise))


def damping_for_overshoot(loop: JointLoop, reference: np.ndarray, overshoot_pct: float) -> JointLoop:
    """``loop`` with the ``d`` [N·s/m or N·m·s/rad] whose step overshoots ``overshoot_pct`` (regula falsi,
    Illinois: the overshoot falls as ``d`` grows); ``d = 0`` when even that overshoots less (the plant's own
    damping is enough)."""
    def miss(d: float) -> float:
        return overshoot_at(loop.with_gains(d=d), reference) - overshoot_pct

    low, f_low = 0.0, miss(0.0)
    if f_low <= 0:
        return loop.with_gains(d=0.0)
    high = max(2 * math.sqrt(loop.p * loop.mass), 1e-6)
    f_high = miss(high)
    for _ in range(40):
        if f_high < 0:
            break
        low, f_low = high, f_high
        high *= 2
        f_high = miss(high)
    side = 0
    d = high
    for _ in range(40):
        d = (low * f_high - high * f_low) / (f_high - f_low)
        f = miss(d)
        if abs(f) < 0.02 or high - low < 1e-6 * high:
            break
        if f > 0:
            low, f_low = d, f
            if side == -1:
                f_high /= 2
            side = -1
        else:
            high, f_high = d, f
            if side == 1:
                f_low /= 2
            side = 1
    return loop.with_gains(d=float(d))


#: The integral's time constants ``p/i`` tried, in settling times asked: the fastest that meets the spec wins
#: (a faster integral takes a sag out sooner; a slower one disturbs the step less: its slow tail stays inside
#: the settling band).
INTEGRAL_TIMES = (4.0, 8.0, 16.0)


def with_integral(loop: JointLoop, settling_s: float, i_clamp: float, times: float = 4.0) -> JointLoop:
    """``loop`` with an integral whose time constant ``p/i`` is ``times`` the settling time asked, its term
    clamped to ±``i_clamp`` [N or N·m] with anti-windup (ros_controllers' ``i_clamp``, ``antiwindup``)."""
    return loop.with_gains(i=loop.p / (times * settling_s), i_clamp=i_clamp, antiwindup=True)


def solve_step(loop: JointLoop, reference: np.ndarray, *, overshoot_pct: float, settling_s: float,
               integral_clamp: float | None = None, iterations: int = 14) -> StepDesign:
    """The gains of ``loop`` (its law, clamp, load and feed-forward kept; ``p`` the starting guess) whose
    response to ``reference`` overshoots ``overshoot_pct`` and settles in ``settling_s`` [s]; with
    ``integral_clamp`` [N or N·m], an integral as :func:`with_integral` makes it, of the time constants of
    :data:`INTEGRAL_TIMES` that meet the spec the one that needs the least ``p`` (a fast integral's tail is
    kept inside the settling band only by a stiff loop), the fastest of them on a tie (see the module
    docstring)."""
    if integral_clamp is None:
        return _solve(loop, reference, overshoot_pct, settling_s, None, iterations)
    found = [_solve(loop, reference, overshoot_pct, settling_s, (integral_clamp, times), iterations)
             for times in INTEGRAL_TIMES]
    met = [design for design in found if design.met]
    return min(met, key=lambda design: design.loop.p) if met else found[0]


def _solve(loop: JointLoop, reference: np.ndarray, overshoot_pct: float, settling_s: float,
           integral: tuple[float, float] | None, iterations: int) -> StepDesign:
    best: tuple[float, JointLoop, StepFigures] | None = None
    p = loop.p
    previous = None
    for _ in range(iterations):
        trial = loop.with_gains(p=p)
        if integral is not None:
            trial = with_integral(trial, settling_s, *integral)
        trial = damping_for_overshoot(trial, reference, overshoot_pct)
        figures = trial.step(reference)
        settling = figures.settling_s if math.isfinite(figures.settling_s) else 10 * settling_s
        miss = abs(settling / settling_s - 1)
        if best is None or miss < best[0]:
            best = (miss, trial, figures)
        if miss < SETTLING_TOLERANCE:
            break
        if previous is not None and settling > settling_s and settling > 0.98 * previous:
            break  # a stiffer loop settles no sooner: the effort limit sets the pace
        previous = settling if settling > settling_s else None
        # The time scale goes as 1/√p: scale p by the square of the settling's ratio (limited per step).
        p *= min(16.0, max(1 / 16.0, (settling / settling_s) ** 2))
    _, found, figures = best
    # The search reads the overshoot to the first peak past the rest it expects; the whole record's final value
    # can differ a little (an integral's slow tail): once, aim off by what that costs.
    off = _finite(figures.overshoot_pct) - overshoot_pct
    if abs(off) > OVERSHOOT_TOLERANCE_PCT:
        trial = damping_for_overshoot(found, reference, overshoot_pct - off)
        trial_figures = trial.step(reference)
        if abs(_finite(trial_figures.overshoot_pct) - overshoot_pct) < abs(off):
            found, figures = trial, trial_figures
    binds = binding(found, figures, reference, overshoot_pct, settling_s)
    return StepDesign(found, figures, not binds, binds)


def _finite(value: float) -> float:
    return value if math.isfinite(value) else 0.0


def binding(loop: JointLoop, figures: StepFigures, reference: np.ndarray, overshoot_pct: float,
            settling_s: float) -> tuple[str, ...]:
    """The constraints that keep ``figures`` (``loop``'s answer to ``reference``) from the spec: "gravity"
    when it rests further than the settling band from its reference, "damping" when it overshoots less than
    asked with ``d = 0``, "effort" when it settles later than asked (or overshoots otherwise than asked)
    with the effort at its limit in more than :data:`SATURATION_SHARE` of the cycles, else "spec" for a
    spec missed for none of these reasons."""
    move = abs(float(reference[-1] - reference[0]))
    binds = []
    if abs(figures.final_error) > SETTLING_BAND * move:
        binds.append("gravity")
    overshoot = figures.overshoot_pct if math.isfinite(figures.overshoot_pct) else 0.0
    settling_ok = math.isfinite(figures.settling_s) and abs(figures.settling_s / settling_s - 1) <= 0.15
    overshoot_ok = abs(overshoot - overshoot_pct) <= 3.0
    if not overshoot_ok and loop.d == 0.0 and overshoot < overshoot_pct:
        binds.append("damping")
    if not (settling_ok and overshoot_ok) and figures.saturated_share > SATURATION_SHARE:
        binds.append("effort")
    if not (settling_ok and overshoot_ok) and not binds:
        binds.append("spec")
    return tuple(binds)




#: What a control engineer does about each binding constraint: the ``--remedy`` that answers it.
REMEDIES = {"gravity": ("feedforward", "integral"), "effort": ("lower-bandwidth", "ramp", "measurement"),
            "kick": ("measurement", "ramp")}
#: Every remedy, as ``--remedy`` names it.
REMEDY_NAMES = ("measurement", "ramp", "integral", "feedforward", "lower-bandwidth")
#: The remedies ros2_controllers' pid_controller (JointLoop's law "control_toolbox") has no parameter for, and why.
TOOLBOX_LACKS = {
    "measurement": "pid_controller differentiates the error of a plain position reference; its derivative acts on "
                   "the measured speed only when each reference carries values_dot, which is the sender's choice, not "
                   "a parameter of its file (--remedy ramp keeps the kick inside the limit)",
    "feedforward": "pid_controller adds no model's gravity (its feedforward_gain multiplies values_dot; --remedy "
                   "integral holds the load)",
}


def remedy_lacking(law: str, remedy: str) -> str | None:
    """Why the controller of ``law`` (JointLoop's) cannot be given ``remedy``; None when it can."""
    return TOOLBOX_LACKS.get(remedy) if law == "control_toolbox" else None


def ramp_for_kick(loop: JointLoop, step: float, *, share: float = 0.5, start: float = 0.0) -> float:
    """The shortest ramp [s] (whole periods) over which ``step`` [m or rad] from ``start`` asks at most ``share``
    of the effort left beside the load of ``loop``'s derivative on the error: ``d·|step|/ramp_s ≤
    share·(limit - |load|)``, the load the larger at either end; 0 when the loop has no such derivative or no
    limit."""
    if loop.derivative != "error" or not loop.d or not math.isfinite(loop.effort_limit):
        return 0.0
    load = max(abs(loop.load(start)), abs(loop.load(start + step)))
    room = share * max(loop.effort_limit - load, 1e-9 * loop.effort_limit)
    return loop.period_s * math.ceil(loop.d * abs(step) / room / loop.period_s)


def lowest_settling(loop: JointLoop, reference_for, *, overshoot_pct: float, settling_s: float,
                    integral_clamp: float | None = None, widest: float = 10.0,
                    effort_cap: float = math.inf) -> tuple[float, StepDesign]:
    """(settling time [s], design): the shortest settling time, from ``settling_s`` up to ``widest`` times it,
    for which a design meets the spec at the move ``reference_for(settling)`` gives, asking at most
    ``effort_cap`` [N or N·m] (bisection on the time; a longer settling asks less effort). The design at
    ``widest`` times when none does."""
    def attempt(ts: float) -> StepDesign:
        return solve_step(loop, reference_for(ts), overshoot_pct=overshoot_pct, settling_s=ts,
                          integral_clamp=integral_clamp)

    def fits(design: StepDesign) -> bool:
        return design.met and design.figures.peak_effort <= effort_cap

    high = widest * settling_s
    found = attempt(high)
    if not fits(found):
        return high, found
    low = settling_s
    for _ in range(8):
        middle = math.sqrt(low * high)
        trial = attempt(middle)
        if fits(trial):
            high, found = middle, trial
        else:
            low = middle
        if high / low < 1.03:
            break
    return high, found


__all__ = ["INTEGRAL_TIMES", "REMEDIES", "REMEDY_NAMES", "TOOLBOX_LACKS", "StepDesign", "binding", "damping_for_overshoot",
           "lowest_settling",
           "ramp_for_kick", "remedy_lacking", "solve_step", "with_integral"]

"""What a position loop's step should do, and where that theory stops.

**The loop as it runs.** The figures a run is compared with -- overshoot, 2 % settling time, steady-state
error, peak effort, and ωn and ζ where the linear loops below do not give them -- are read off the joint's
loop as it runs (:mod:`jointctl.scenario.analyses.step_model`: the controller's law with its derivative kick,
the effort clamp, gravity over the move, the feed-forward, the integral, the latency, MuJoCo's integration,
from where the run started) exactly as the run's own are read
(:func:`~jointctl.metrics.response.step_response`). It is the loop autotune designs on: for the same gains
and step its figures read as autotune reads them (``model_step``) are autotune's ``model``.

**Signs.** The robot moves as ``M(q)·q̈ + b·q̇ + τ_hold(q) = τ``: ``τ_hold(q)`` is the effort that
holds the pose still against gravity (MuJoCo's inverse dynamics at rest, the bias force;
:meth:`~jointctl.model.dynamics.RobotDynamics.gravity_at_pose`), i.e. minus the torque (force)
gravity applies to the joint, ``τ_g = -τ_hold``. The loop gives ``τ = Kp·(r - q) - Kd·q̇`` (a
derivative on the measured speed; on the error it is the same after the step's first cycle, which
adds the kick ``Kd·Δr/h``); gravity feed-forward adds ``τ_hold(q)`` of the measured pose.

**Rest.** The analysed joint ``j`` rests, with the other joints at the pose they end the run in,
where the P loop balances the holding effort::

    Kp·(r - q*) = τ_hold(q*)        (0 on the right with gravity feed-forward)

The robot is the one simulated (the session's ``plant``: a scenario's payload and model changes); gravity
feed-forward is computed from the controllers' model, so on a changed robot it leaves the difference
``τ_hold(q*) - τ_hold,model(q*)`` (a payload's weight) on the right, and in the stiffness below.

solved numerically (a bracketing root search over half a turn each side of ``r`` for a revolute
joint, Newton's method for a prismatic one, whose holding effort does not change with its own
position). The steady-state error is ``e_ss = r - q* = τ_hold(q*)/Kp``: positive when the joint
must push towards +q to hold (the 1-DOF piston under gravity, ``m·g/Kp``), negative when gravity
pulls it past its reference. (The loop as it runs finds the same rest, and an integral's.)

**About the rest.** With ``q = q* + x``, ``I·ẍ = -Kp·x - (b + Kd)·ẋ - (∂τ_hold/∂q)·x``: the loop is a
spring-damper of stiffness ``k = Kp + ∂τ_hold/∂q = Kp - ∂τ_g/∂q`` [N/m or N·m/rad], inertia
``I = M_jj(q*)`` and damping ``b + Kd``, so ``ωn = √(k/I)`` and ``ζ = (b + Kd)/(2·√(k·I))``
(``held_*``: the other joints held rigidly). The other joints are held by loops of their own,
coupled to this one through ``M`` and gravity: all of them are linearised together
(:func:`jointctl.metrics.linear_loops.linear_step`: ``K = diag(Kp) + ∂τ_hold/∂q``, a row without
gravity for a joint with gravity feed-forward, ``D = diag(b + Kd)``), and the expected ωn and ζ are
those of the mode that dominates the analysed joint's response, where these loops describe the run:
the effort limit never shaped the step (the loop as it runs answers as it would without it), no
other joint's effort sat at its limit, the controller does not integrate, the dominant mode
oscillates and no other carries more than :data:`MODE_SHARE_LIMIT` of the response. With one joint,
or stiff enough neighbours, that is ``√(k/I)``. The inertia is ``M_jj`` without the ``h·b`` that
MuJoCo's implicit damping adds to it: the effort held over each loop period takes about half of that
back, and the sampled loop's ωn is that of ``M_jj + h·b/2`` to 0.05 % (0.25 % below the continuous
figure on the 1-DOF robot), well inside the ωn margin.

**The joint alone.** The loop as it runs holds the other joints where they end. How much their loops
move the joint's own mode is the linear loops' answer: the dominant mode against the joint's held
alone (``coupling``: the relative changes of its ωn and ζ). Within :data:`ALONE_SHARE` the joint is
alone, and every figure is the loop as it runs' (ωn and ζ too, read off it as the run's are fitted:
to the last digits where the model is exact). Beyond, ωn and ζ are the linear loops' where these
describe the run, and not applicable where they do not (a fit of the joint alone's response would
carry the neighbours' share); beyond the ωn and ζ margins (5 %, 10 %) the model of the joint alone
does not describe its step, and its transient figures and peak effort are not applicable either. The
steady-state error, a matter of statics with the others where they end, stands.

**Not applicable.** Expectations are None, with the reason, where the theory does not describe the
run: the joint's loop is not a position loop, the rest lies beyond the joint's range or needs more
than its effort limit, the effort is at its limit at the end of the run, the linearised loops have
no stable rest, the neighbours' loops move the joint's mode beyond the margins, or the model's own
response has no such figure (it does not settle within the record, or does not overshoot: no ωn and
ζ to fit). Not modelled, and not detected: friction the URDF lacks, the other joints' integrators
(their slow action left out of the linear loops), the joint's range limits reached on the way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq

from jointctl.control.joint_controllers import DERIVATIVE_ERROR, JointVelocityController
from jointctl.control.position_loop import position_loop
from jointctl.hardware.interface import EFFORT
from jointctl.metrics.expectations import DAMPING_RATIO_MARGIN, NATURAL_FREQUENCY_MARGIN, saturation_share
from jointctl.metrics.linear_loops import LinearStep, linear_step
from jointctl.metrics.response import AnalysisError, step_response
from jointctl.model.dynamics import RobotDynamics
from jointctl.recording.trace import Trace
from jointctl.scenario.analyses.step_model import StepModel, step_model
from jointctl.scenario.session import Session

#: Another mode whose RMS part of the joint's response exceeds this share of the dominant mode's
#: makes the response two damped sinusoids, which a fit of one describes by neither.
MODE_SHARE_LIMIT = 0.25
#: Step of the central differences of the holding efforts [m or rad]: the efforts are smooth
#: (sinusoids of the angles), so the difference's error is ~1e-12 of the derivative.
DIFFERENCE_STEP = 1e-6
#: Points of the search for the rest of a revolute joint over half a turn each side of its reference.
REST_SEARCH_POINTS = 721
#: The final pose of every joint: the mean of the last 10 % of the record, as the step analysis'
#: final value.
FINAL_SHARE = 0.1

#: The neighbours' loops move the joint's mode by less than this share (ωn, ζ): the joint is alone, and every
#: figure is the loop as it runs. A tenth of a percent: under what the sampling itself moves ωn from the
#: continuous loop's (h·b/(4·I): 0.25 % on the 1-DOF robot at 1 kHz).
ALONE_SHARE = 1e-3

MODE = ("natural_frequency_rad_s", "damping_ratio")
TRANSIENT = (*MODE, "overshoot_pct", "settling_time_s")
STEADY = "steady_state_error"
PEAK = "peak_effort"
EXPECTED = (*TRANSIENT, STEADY, PEAK)


@dataclass
class StepTheory:
    """Expected step figures of one joint (None where not applicable, ``not_applicable`` saying
    why) and how they were reached: ``model`` the loop as it runs' figures read as the run's are,
    ``model_step`` read as autotune reads a step (:class:`~jointctl.metrics.step_loop.StepFigures`),
    ``rest_position`` q* [m or rad], ``holding_effort`` τ_hold(q*) [N or N·m], ``gravity_stiffness``
    ∂τ_hold/∂q at q* [N/m or N·m/rad], ``stiffness`` k, ``inertia`` M_jj(q*) [kg or kg·m²],
    ``held_*`` the figures with the other joints held rigidly, ``modes`` the coupled loops' modes (ωn
    [rad/s], ζ, share of the joint's response), dominant first, ``coupling`` how far they move the
    joint's own, ``mode_source`` where ωn and ζ come from, ``saturated_share_after_step`` of the
    cycles after the step at the effort limit. ``loop`` is the loop as it runs and its response
    (:class:`~jointctl.scenario.analyses.step_model.StepModel`; None for no position loop), for
    :meth:`response`."""

    expected: dict[str, float | None] = field(default_factory=dict)
    not_applicable: dict[str, str] = field(default_factory=dict)
    details: dict = field(default_factory=dict)
    loop: StepModel | None = None

    def response(self, time_s) -> np.ndarray | None:
        """The joint's position [m or rad] at the loop times ``time_s`` [s] as the loop as it runs moves it
        (from where the run started); None without one."""
        return None if self.loop is None else self.loop.position_at(time_s)

    def skip(self, keys, reason: str) -> None:
        """Mark ``keys`` not applicable for ``reason`` (the first reason given stays)."""
        for key in keys:
            self.expected[key] = None
            self.not_applicable.setdefault(key, reason)


def loop_controller(session: Session, joint: str):
    """The running controller that writes ``joint``'s effort, or None; a position loop as
    :func:`~jointctl.control.position_loop.position_loop` gives it (a pid_controller's dof as a joint position
    controller)."""
    found = next((c for c in session.manager.active if (joint, EFFORT) in c.claimed_interfaces()), None)
    return position_loop(found, joint) or found


def final_pose(session: Session, trace: Trace) -> np.ndarray:
    """Every hardware joint's mean position over the last :data:`FINAL_SHARE` of the record."""
    n_tail = max(1, int(math.ceil(FINAL_SHARE * trace.time_s.size)))
    return np.array([float(np.mean(trace.joint(j, "position")[-n_tail:])) for j in session.hardware.joint_names])


def step_theory(session: Session, trace: Trace, joint: str, step_time_s: float,
                settle_band: float = 0.02, ramp_s: float = 0.0) -> StepTheory:
    """The expected ωn, ζ, overshoot, settling time (within ±``settle_band`` of the step), steady-state
    error and peak effort of ``joint``'s step at ``step_time_s`` (along a ramp of ``ramp_s`` [s], a step
    source's; see the module docstring), with the reasons where they do not apply."""
    theory = StepTheory(dict.fromkeys(EXPECTED))
    spec = session.robot.joint(joint)
    unit = "N" if spec.is_prismatic else "N·m"
    limit = spec.limits.effort if spec.limits is not None and spec.limits.effort > 0 else math.inf
    t = trace.time_s
    effort = trace.joint(joint, "effort")
    n_tail = max(1, int(math.ceil(FINAL_SHARE * t.size)))
    share_after = saturation_share(effort[t >= step_time_s], limit)
    share_end = saturation_share(effort[-n_tail:], limit)
    theory.details["saturated_share_after_step"] = share_after
    controller = loop_controller(session, joint)
    if position_loop(controller, joint) is None:
        what = ("a velocity loop" if isinstance(controller, JointVelocityController)
                else "no loop" if controller is None else type(controller).__name__)
        theory.skip(EXPECTED, f"{joint} is driven by {what}, not a position loop")
        return theory
    gains = controller.pid.gains
    names = session.hardware.joint_names
    j = names.index(joint)
    reference = trace.joint(joint, "reference")
    r = float(reference[-1])
    before = np.flatnonzero(t < step_time_s)
    r0 = float(reference[before[-1]]) if before.size else r
    pose = final_pose(session, trace)

    # The loop as it runs, read as the run is.
    theory.loop = model = step_model(session, trace, joint, controller, dict(zip(names, pose)))
    theory.details["model_step"] = model.figures().as_dict()
    figures = _model_figures(theory, model, t, reference, step_time_s, settle_band, ramp_s)

    # The linearised loops about the rest: where the loop rests, and how the neighbours' loops move its mode.
    dynamics = session.dynamics(session.plant, names)
    feedforward = "gravity" in controller.feedforward_terms
    model_dynamics = _controllers_model(session, names)

    def holding(q: float) -> float:
        pose[j] = q
        if feedforward and model_dynamics is None:
            return 0.0
        dynamics.set_pose(pose, inertia=False)
        hold = float(dynamics.gravity_at_pose()[j])
        if feedforward:
            model_dynamics.set_pose(pose, inertia=False)
            hold -= float(model_dynamics.gravity_at_pose()[j])
        return hold

    kp = gains.p
    try:
        rest = _rest(lambda q: kp * (r - q) - holding(q), r, spec.is_prismatic,
                     lambda q: (holding(q + DIFFERENCE_STEP) - holding(q - DIFFERENCE_STEP)) / (2 * DIFFERENCE_STEP)
                     + kp)
    except ValueError as exc:
        theory.skip(EXPECTED, str(exc))
        return theory
    hold = holding(rest)
    theory.details.update(rest_position=rest, holding_effort=hold)
    lower = spec.limits.lower if spec.limits is not None and spec.limits.lower is not None else -math.inf
    upper = spec.limits.upper if spec.limits is not None and spec.limits.upper is not None else math.inf
    if spec.type != "continuous" and not lower <= rest <= upper:
        theory.skip(EXPECTED, f"the loop would rest at {rest:.4g}, beyond the joint's range [{lower:g}, {upper:g}]: "
                              "it rests on its limit")
    elif abs(hold) >= limit:
        theory.skip(EXPECTED, f"holding the rest takes {abs(hold):.4g} {unit}, more than the joint's {limit:g} {unit} "
                              "limit")
    if share_end > 0:
        theory.skip((STEADY,), f"the effort is at its {limit:g} {unit} limit at the end of the run: the loop "
                               "does not hold a rest")

    pose[j] = rest
    dynamics.set_pose(pose)
    mass = dynamics.mass_matrix()
    stiffness, damping = _loops(session, dynamics, pose, model_dynamics)
    gravity_stiffness = float(stiffness[j, j] - kp)
    inertia = float(mass[j, j])
    k = kp + gravity_stiffness
    c = float(damping[j, j])
    theory.details.update(gravity_stiffness=gravity_stiffness, stiffness=k, inertia=inertia,
                          damping=c, kp=kp, kd=gains.d, step=r - r0)
    if k > 0:
        theory.details.update(held_natural_frequency_rad_s=math.sqrt(k / inertia),
                              held_damping_ratio=c / (2 * math.sqrt(k * inertia)))
    kick = gains.d if controller.derivative == DERIVATIVE_ERROR else 0.0
    try:
        response = linear_step(mass, stiffness, damping, j, kp, kick)
        held = linear_step(mass[j:j + 1, j:j + 1], stiffness[j:j + 1, j:j + 1], damping[j:j + 1, j:j + 1], 0, kp,
                           kick)
    except ValueError as exc:
        response = held = None
        linear = f"about the rest pose: {exc}"
    else:
        theory.details["modes"] = [{"natural_frequency_rad_s": m.natural_frequency_rad_s,
                                    "damping_ratio": m.damping_ratio, "share": m.share} for m in response.modes]
        linear = _linear_reason(session, trace, joint, step_time_s, controller, model, response)

    # The joint alone, or its neighbours' loops moving its mode.
    shift = (0.0, 0.0) if len(names) == 1 else _shift(response, held)
    moved = None
    if shift is None:
        moved = "the linearised loops have no mode to compare the joint alone with"
    else:
        theory.details["coupling"] = {"natural_frequency": shift[0], "damping_ratio": shift[1]}
        if shift[0] > NATURAL_FREQUENCY_MARGIN.value or shift[1] > DAMPING_RATIO_MARGIN.value:
            moved = (f"the other joints' loops move {joint}'s mode from ωn {held.natural_frequency_rad_s:.4g} rad/s, "
                     f"ζ {held.damping_ratio:.3g} (the joint alone) to ωn {response.natural_frequency_rad_s:.4g} "
                     f"rad/s, ζ {response.damping_ratio:.3g}: the model of the joint alone does not describe its step")
    alone = shift is not None and max(shift) <= ALONE_SHARE
    for key in (*TRANSIENT[2:], PEAK):
        _expect(theory, key, figures, moved)
    _expect(theory, STEADY, figures, None)
    if not alone and linear is None:
        theory.details["mode_source"] = "coupled loops"
        for key, value in zip(MODE, (response.natural_frequency_rad_s, response.damping_ratio)):
            if key not in theory.not_applicable:
                theory.expected[key] = float(value)
    elif alone:
        theory.details["mode_source"] = "loop as it runs"
        for key in MODE:
            _expect(theory, key, figures, None)
    else:
        coupled = moved or (f"the other joints' loops move {joint}'s mode by {100 * shift[0]:.2g} % in ωn and "
                            f"{100 * shift[1]:.2g} % in ζ, which the loop as it runs (the joint alone) leaves out")
        theory.skip(MODE, f"{linear}; and {coupled}")
    return theory


def _model_figures(theory: StepTheory, model: StepModel, t: np.ndarray, reference: np.ndarray, step_time_s: float,
                   settle_band: float, ramp_s: float = 0.0) -> dict[str, float | None] | str:
    """The loop as it runs' figures at the trace's times ``t``, read as the run's are (:data:`EXPECTED`; None
    where the reading has none, with its reason under ``"notes"``), also kept in ``theory.details["model"]``
    (with its rise time and final value); or the reason it has none."""
    try:
        read = step_response(t, reference, model.position_at(t), step_time_s=step_time_s, settle_band=settle_band,
                             ramp_s=ramp_s)
    except AnalysisError as exc:
        return f"the loop as it runs gives no step to read: {exc.message}"
    # The peak effort as the trace records it (what acted over the period before each sample: a trace recorded
    # every few cycles may miss a one-cycle kick, and so does this).
    after = model.measured_effort_at(t[t >= step_time_s])
    peak = float(np.max(np.abs(after))) if after.size else None
    values = read.as_dict()
    found = {key: values.get(key) for key in (*TRANSIENT, STEADY)}
    found = {key: (None if value is None or not math.isfinite(value) else float(value)) for key, value in found.items()}
    found[PEAK] = peak
    theory.details["model"] = {**found, "rise_time_s": values.get("rise_time_s"),
                               "final_value": values.get("final_value")}
    notes = {}
    for key in found:
        if found[key] is None:
            notes[key] = (f"the loop as it runs has none: {read.fit_note}" if key in MODE and read.fit_note
                          else f"the loop as it runs has none: {read.not_settled}" if read.not_settled
                          else "the loop as it runs has none")
    found["notes"] = notes
    return found


def _expect(theory: StepTheory, key: str, figures, reason: str | None) -> None:
    """``key`` expected from the loop as it runs' ``figures``, unless ``reason`` (or the figures) say otherwise."""
    if reason is not None:
        theory.skip((key,), reason)
    elif isinstance(figures, str):
        theory.skip((key,), figures)
    elif figures.get(key) is None:
        theory.skip((key,), figures["notes"].get(key, "the loop as it runs has none"))
    elif key not in theory.not_applicable:
        theory.expected[key] = figures[key]


def _linear_reason(session: Session, trace: Trace, joint: str, step_time_s: float, controller, model: StepModel,
                   response: LinearStep) -> str | None:
    """Why the linearised loops do not describe the step's ωn and ζ (None when they do): an integral, the
    effort limit shaping the step (the loop as it runs answers otherwise without it), another joint's effort at
    its limit, no oscillation, two modes."""
    gains = controller.pid.gains
    if gains.i > 0:
        return (f"the controller integrates the error (i = {gains.i:g}): the loop is third order and rests at its "
                "reference once the integral has caught up")
    if model.limit_acted():
        return "the effort limit shaped the step: the loop was not linear"
    t = trace.time_s
    for other in session.hardware.joint_names:  # the other joints' loops are part of the linear model
        limits = session.robot.joint(other).limits
        other_limit = limits.effort if limits is not None and limits.effort > 0 else math.inf
        other_share = saturation_share(trace.joint(other, "effort")[t >= step_time_s], other_limit)
        if other != joint and other_share > 0:
            other_unit = "N" if session.robot.joint(other).is_prismatic else "N·m"
            return (f"{other}'s effort sat at its {other_limit:g} {other_unit} limit in {100 * other_share:.3g} % of "
                    "the cycles after the step: the coupled loops were not linear")
    if not response.oscillating:
        return "the joint's response is overdamped: no oscillation to fit an ωn and ζ to"
    if response.second_share > MODE_SHARE_LIMIT:
        return (f"a second mode carries {100 * response.second_share:.3g} % of the joint's response (more than "
                f"{100 * MODE_SHARE_LIMIT:g} %): no single ωn and ζ")
    return None


def _shift(coupled: LinearStep | None, alone: LinearStep | None) -> tuple[float, float] | None:
    """The relative changes [-] of the joint's dominant mode's ωn and ζ from the joint alone (the others held) to
    the coupled loops; None without both."""
    if coupled is None or alone is None:
        return None
    zeta = abs(coupled.damping_ratio / alone.damping_ratio - 1) if alone.damping_ratio else 0.0
    return abs(coupled.natural_frequency_rad_s / alone.natural_frequency_rad_s - 1), zeta


def _rest(residual, reference: float, prismatic: bool, slope) -> float:
    """The q where ``residual(q) = Kp·(r - q) - τ_hold(q)`` vanishes nearest the reference, with a
    positive stiffness ``slope(q)`` (a stable rest): Newton's method for a prismatic joint, a
    bracketing search over half a turn each side of the reference for a revolute one."""
    if prismatic:
        q = reference
        for _ in range(20):
            k = slope(q)
            if not k > 0:
                break
            step = residual(q) / k
            q += step
            if abs(step) <= 1e-14 * max(1.0, abs(q)):
                return q
        raise ValueError("the position loop finds no stable rest (its gain does not exceed the change of the "
                         "holding effort)")
    grid = np.linspace(reference - math.pi, reference + math.pi, REST_SEARCH_POINTS)
    values = np.array([residual(q) for q in grid])
    # Stable rests: the residual falls through zero (the stiffness -d(residual)/dq is positive).
    crossings = np.flatnonzero((values[:-1] > 0) & (values[1:] <= 0))
    if crossings.size == 0:
        raise ValueError("the position loop finds no stable rest within half a turn of its reference (its "
                         "gain does not exceed the change of the holding effort)")
    roots = [brentq(residual, grid[i], grid[i + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps)
             if values[i + 1] != 0 else float(grid[i + 1]) for i in crossings]
    return float(min(roots, key=lambda q: abs(q - reference)))


def _controllers_model(session: Session, names) -> RobotDynamics | None:
    """The dynamics of the controllers' model (what their gravity feed-forward computes) when the simulated robot
    differs from it; None when it is the robot simulated."""
    if session.plant is session.robot:
        return None
    return session.dynamics(session.robot, names)


def _gravity_gradient(dynamics: RobotDynamics, pose: np.ndarray) -> np.ndarray:
    """``∂τ_hold/∂q`` (n x n) at ``pose`` by central differences; ``dynamics`` left at ``pose``."""
    n = pose.size
    gradient = np.zeros((n, n))
    for col in range(n):
        shifted = pose.copy()
        shifted[col] += DIFFERENCE_STEP
        dynamics.set_pose(shifted, inertia=False)
        up = dynamics.gravity_at_pose().copy()
        shifted[col] -= 2 * DIFFERENCE_STEP
        dynamics.set_pose(shifted, inertia=False)
        gradient[:, col] = (up - dynamics.gravity_at_pose()) / (2 * DIFFERENCE_STEP)
    dynamics.set_pose(pose)
    return gradient


def _loops(session: Session, dynamics: RobotDynamics, pose: np.ndarray,
           model: RobotDynamics | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness ``K`` and damping ``D`` (n x n) of every joint's loop at ``pose``: a position loop
    gives ``Kp`` and ``Kd`` (an integral's slow action left out), a velocity loop its gain as
    damping, no loop nothing; ``K`` adds ``∂τ_hold/∂q`` (central differences), but for the rows of
    joints with gravity feed-forward, where only what the controllers' ``model`` (when it is not the robot
    simulated) leaves of it remains."""
    names = session.hardware.joint_names
    n = len(names)
    gravity = _gravity_gradient(dynamics, pose)
    compensated = _gravity_gradient(model, pose) if model is not None else gravity
    kp, kd = np.zeros(n), dynamics.damping.copy()
    for i, name in enumerate(names):
        controller = loop_controller(session, name)
        if position_loop(controller, name) is not None:
            kp[i] = controller.pid.gains.p
            kd[i] += controller.pid.gains.d
            if "gravity" in controller.feedforward_terms:
                gravity[i, :] -= compensated[i, :]
        elif isinstance(controller, JointVelocityController):
            kd[i] += controller.pid.gains.p
    return np.diag(kp) + gravity, np.diag(kd)

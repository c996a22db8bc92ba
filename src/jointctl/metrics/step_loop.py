"""A joint's position loop on the move that will run: the sampled plant, the controller's own law, the effort
clamp and the gravity load, simulated cycle by cycle.

The linear loop model (:class:`~jointctl.identification.frequency_response.LoopModel`) answers for small
moves. A real step is not small: with the derivative on the error (ros_controllers' law for a plain position
command) its first cycle asks the kick ``d·Δr/h``, which the effort limit clamps; a large step asks ``p·Δr`` on
top of the load and saturates for longer; a P loop under gravity rests short of its reference. This module
runs the same loop as :class:`~jointctl.control.joint_controllers.JointPositionController` and
:class:`~jointctl.control.pid.Pid` compute it, one control period ``h`` at a time:

- the plant ``m·q̈ + b·q̇ = u - τ_hold(q)``, held over each period (zero-order hold, exact for the linear
  part: the matrices of ``LoopModel``); ``τ_hold(q)`` [N or N·m] is the effort that holds the joint against
  gravity at ``q`` (the other joints where they are: :func:`holding_effort` reads it off the robot model over
  the joint's range);
- the error ``e = r - q``; its rate, by the ``derivative`` law: ``(e - e_last)/h`` ("error"), or ``-q̇``
  ("measurement"), or ``ṙ - q̇`` for a reference that carries its rate ``ṙ`` (``reference_rate``: a
  ros_control reference with a velocity, a pid_controller reference with ``values_dot``); the integral
  ``i·h·e`` accumulated and clamped to ``[i_clamp_min, i_clamp]`` (the term, or with ``antiwindup`` the
  state itself: control_toolbox's clamps of ``i·i_error`` and of ``i_error``, the same for a constant
  ``i``), the command ``p·e + i_term + d·rate`` clamped to the effort limit, then, with ``feedforward``
  gravity, ``τ_hold(q)`` of the measured pose added and the sum clamped again;
- the actuator delivers at most the effort limit (as MuJoCo's actuator range and a real drive do);
- with ``delay_cycles`` the command computed in cycle ``k`` reaches the joint in cycle ``k + delay_cycles``
  (a scenario's ``latency_cycles``: :class:`~jointctl.hardware.imperfect.ImperfectHardware`).

Two controllers run this law (``law``):

- ``"ros_control"``: jointctl's :class:`~jointctl.control.joint_controllers.JointPositionController`
  (ros_controllers' ``effort_controllers/JointPositionController``): its output clamped to the effort limit;
  its first rate after a start 0;
- ``"control_toolbox"``: ros2_controllers' ``pid_controller/PidController`` commanding an effort
  (:class:`~jointctl.control.pid_controller.PidController`, control_toolbox 3.4.0's PID): no output limit
  (the actuator clamps what reaches the joint: the same motion, and the effort reported is what the joint
  gets), and its PID, configured with a last error of 0, differentiates its first error from 0: started off
  its reference by ``e₀`` it asks the kick ``d·e₀/h`` on its first cycle.

Before the move the loop rests at its start reference: where ``p·e + i_term = τ_hold - τ_ff`` (the P loop short
of its reference by the droop ``τ_hold/p``; an integral or the feed-forward ``τ_ff`` holding the load at the
reference). Or it starts where a run starts (``start``): at a position and speed, its controller just started
(integral 0, the commands on their way 0, its first rate the law's).
The response is read with the figures the robot's check reads (:func:`step_figures`): overshoot [%] of the
rise to the final value, 2 % settling time, the final value and its distance to the reference (the sag),
the peak effort and the share of cycles at the effort limit.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

#: The settling band: within this share of the move of the final value, from then on.
SETTLING_BAND = 0.02
#: A cycle counts as saturated when the command is within this share of the effort limit.
SATURATION_MARGIN = 0.02
#: The controllers whose law :class:`JointLoop` runs (see the module docstring).
LAWS = ("ros_control", "control_toolbox")


@dataclass(frozen=True)
class JointLoop:
    """One joint's plant and its position controller: ``mass`` [kg or kg·m²], ``damping`` [N·s/m or N·m·s/rad],
    ``period_s`` the control period [s], ``effort_limit`` [N or N·m] (inf: none), ``hold`` the effort [N or
    N·m] holding the joint against gravity at a position [m or rad] (None: no load); the gains ``p`` [N/m or
    N·m/rad], ``i`` [N/(m·s) or N·m/(rad·s)], ``d`` [N·s/m or N·m·s/rad], the integral's clamp ``i_clamp`` [N
    or N·m] (the integral term stays within ±``i_clamp``, or within [``i_clamp_min``, ``i_clamp``] when
    ``i_clamp_min`` is given; inf: none; 0: no integral) and ``antiwindup``;
    ``derivative`` "error" or "measurement"; ``feedforward`` whether the model's gravity effort is added;
    ``integrator`` how the plant moves over a period: "hold" (exactly, the effort held: a real joint) or
    "euler" (as the simulated robot does: MuJoCo's semi-implicit Euler, damping implicit, ``v⁺ = (v +
    h·f/m)/(1 + h·b/m)``, ``q⁺ = q + h·v⁺``; ahead of the exact motion by about ``h·v/2``), in ``substeps``
    physics steps of ``period_s/substeps`` each (the effort held over them); ``feedforward_hold`` the effort
    [N or N·m] the feed-forward adds at a position when the controller's model differs from the plant (None:
    ``hold``, the model is the plant); ``delay_cycles`` the control cycles a command takes to reach the joint
    (0: the next physics step); ``law`` the controller that runs it, "ros_control" or "control_toolbox" (see
    the module docstring)."""

    mass: float
    damping: float
    period_s: float
    effort_limit: float = math.inf
    hold: Callable[[float], float] | None = None
    p: float = 0.0
    i: float = 0.0
    d: float = 0.0
    i_clamp: float = math.inf
    antiwindup: bool = False
    derivative: str = "error"
    feedforward: bool = False
    integrator: str = "hold"
    substeps: int = 1
    feedforward_hold: Callable[[float], float] | None = None
    delay_cycles: int = 0
    i_clamp_min: float | None = None
    law: str = "ros_control"

    def __post_init__(self) -> None:
        if self.law not in LAWS:
            raise ValueError(f"law must be one of {', '.join(LAWS)}, not {self.law!r}")

    @property
    def integral_bounds(self) -> tuple[float, float]:
        """(lowest, highest) integral term [N or N·m]."""
        return (-self.i_clamp if self.i_clamp_min is None else self.i_clamp_min), self.i_clamp

    def with_gains(self, **gains) -> JointLoop:
        """This loop with other gains (``p``, ``i``, ``d``, ``i_clamp``, ``i_clamp_min``, ``antiwindup``,
        ``derivative``, ``feedforward``)."""
        return replace(self, **gains)

    @property
    def gains(self) -> dict:
        """The PID's gains as ros_control's YAML names them (``i_clamp`` only with an integral)."""
        gains = {"p": self.p, "i": self.i, "d": self.d}
        if self.i:
            gains.update(i_clamp=self.i_clamp, antiwindup=self.antiwindup)
            if self.i_clamp_min is not None and self.i_clamp_min != -self.i_clamp:
                gains["i_clamp_min"] = self.i_clamp_min
        return gains

    def load(self, q: float) -> float:
        """``τ_hold(q)`` [N or N·m]."""
        return self.hold(q) if self.hold is not None else 0.0

    def feedforward_effort(self, q: float) -> float:
        """``τ_ff(q)`` [N or N·m], the effort the gravity feed-forward adds (0 without it)."""
        if not self.feedforward:
            return 0.0
        return self.feedforward_hold(q) if self.feedforward_hold is not None else self.load(q)

    def rest(self, reference: float) -> tuple[float, float]:
        """(position [m or rad], integral term [N or N·m]) where the loop rests holding ``reference``: the P
        term holds what the feed-forward or the integral (within its clamp) does not, ``p·(r - q) + i_term =
        τ_hold(q) - τ_ff(q)``, solved by fixed-point iteration (it converges where the loop is stable)."""
        q = reference
        low, high = self.integral_bounds
        for _ in range(200):
            load = self.load(q) - self.feedforward_effort(q)
            i_term = 0.0 if not self.i else max(low, min(high, load))
            held = load - i_term
            if not self.p:
                return q, i_term
            new = reference - held / self.p
            if abs(new - q) < 1e-13:
                return new, i_term
            q = new
        return q, i_term

    def _plant(self) -> tuple[float, float, float, float, float, float]:
        from scipy.linalg import expm

        m, b, h = self.mass, self.damping, self.period_s
        if self.integrator == "euler":
            h /= self.substeps
            c = 1.0 / (1.0 + h * b / m)
            step = np.array([[1.0, h * c, h * h * c / m], [0.0, c, h * c / m], [0.0, 0.0, 1.0]])
            held = np.linalg.matrix_power(step, self.substeps)
            return (held[0, 0], held[0, 1], held[1, 0], held[1, 1], held[0, 2], held[1, 2])
        held = expm(np.array([[0.0, 1.0, 0.0], [0.0, -b / m, 1.0 / m], [0.0, 0.0, 0.0]]) * h)
        return (held[0, 0], held[0, 1], held[1, 0], held[1, 1], held[0, 2], held[1, 2])

    def run(self, reference: np.ndarray, *, until_peak: bool = False, start: tuple[float, float] | None = None,
            reference_rate: np.ndarray | None = None,
            compiled: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, velocity, commanded effort) at each cycle of ``reference`` (one value a period [m or
        rad]), from rest holding ``reference[0]`` (:meth:`rest`), or from ``start`` (position [m or rad], speed
        [m/s or rad/s]) with the controller just started (integral 0, the commands on their way 0: as a session
        starts; its first rate 0, or with ``law`` "control_toolbox" the first error's difference from 0). With
        ``reference_rate`` (the reference's rate each cycle [m/s or rad/s]) the derivative acts on ``ṙ - q̇``
        whatever the ``derivative`` law (a reference that carries its velocity). Positions are those measured
        at the start of each cycle, before its command; the effort is what reaches the joint (the command within
        the effort limit). ``until_peak``: stop at the first cycle, once the reference has come to its last
        value, whose velocity no longer moves the joint the way of the move (its first peak). ``compiled``: the
        cycles run by the compiled loop (:mod:`~jointctl.metrics.step_loop_kernel`: the same operations) where it
        has a form (the loads :class:`HoldingEffort` tables or none), else in Python (False: always)."""
        # Python floats and lists in the loop: the same IEEE arithmetic as numpy's scalars, at a third of the cost.
        a00, a01, a10, a11, b0, b1 = (float(x) for x in self._plant())
        h, p, i, d = float(self.period_s), float(self.p), float(self.i), float(self.d)
        limit, hold_at = float(self.effort_limit), self.hold
        (low, clamp), antiwindup = (float(x) for x in self.integral_bounds), self.antiwindup
        on_error = self.derivative == "error"
        rates = None if reference_rate is None else np.asarray(reference_rate, dtype=float).tolist()
        feedforward, ff = self.feedforward, self.feedforward_effort
        model_hold = self.feedforward_hold
        own_model = model_hold is None  # the feed-forward is the load itself
        r_array = np.asarray(reference, dtype=float)
        r = r_array.tolist()
        if start is None:
            q, i_state = self.rest(float(r[0]))
            v = 0.0
            held = p * (float(r[0]) - q) + i_state
            held = limit if held > limit else -limit if held < -limit else held
            if feedforward:
                held = min(limit, max(-limit, held + ff(q)))
        else:
            q, v = float(start[0]), float(start[1])
            i_state = held = 0.0
        # The last error a fresh PID differentiates from: ros_control's first rate is 0, control_toolbox's e₀/h.
        e_last = 0.0 if start is not None and self.law == "control_toolbox" else float(r[0]) - q
        n = r_array.size
        arrived = n
        if until_peak:
            away = np.nonzero(r_array != r_array[-1])[0]
            arrived = int(away[-1]) + 1 if away.size else 0
        ran = None if not compiled or n == 0 else _compiled_run(
            self, (a00, a01, a10, a11, b0, b1), (h, p, i, d, limit, low, clamp),
            (antiwindup, on_error, rates is not None, feedforward, own_model, until_peak), r_array, reference_rate,
            (q, v, i_state, e_last), held, arrived)
        if ran is not None:
            return ran
        pending = deque([held] * self.delay_cycles) if self.delay_cycles else None
        qs, vs, us = [], [], []
        direction = 1.0 if r[-1] >= r[0] else -1.0
        for k in range(n):
            if k > arrived and v * direction <= 0.0:
                break
            e = r[k] - q
            if rates is not None:
                rate = rates[k] - v
            else:
                rate = (e - e_last) / h if on_error else -v
                e_last = e
            if i:
                i_state += i * h * e
                if antiwindup:
                    i_state = clamp if i_state > clamp else low if i_state < low else i_state
                i_term = clamp if i_state > clamp else low if i_state < low else i_state
            else:
                i_term = 0.0
            u = p * e + i_term + d * rate
            u = limit if u > limit else -limit if u < -limit else u
            load = hold_at(q) if hold_at is not None else 0.0
            if feedforward:
                u += load if own_model else model_hold(q)
                u = limit if u > limit else -limit if u < -limit else u
            qs.append(q)
            vs.append(v)
            us.append(u)
            if pending is not None:
                pending.append(u)
                u = pending.popleft()
            force = u - load
            q, v = a00 * q + a01 * v + b0 * force, a10 * q + a11 * v + b1 * force
        return np.array(qs, dtype=float), np.array(vs, dtype=float), np.array(us, dtype=float)

    def step(self, reference: np.ndarray) -> StepFigures:
        """The figures of the move ``reference`` (see :meth:`run`; the move is its last value minus its first)."""
        q, _, u = self.run(reference)
        return step_figures(np.arange(q.size) * self.period_s, q, reference, u, self.effort_limit)


def _table(hold) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The arrays of a :class:`HoldingEffort` for the compiled loop (None: another kind of load)."""
    if type(hold) is not HoldingEffort:
        return None
    return np.array([hold.left, hold.spacing]), hold.values, hold.slopes


def _compiled_run(loop: JointLoop, plant, gains, flags, reference: np.ndarray, rates, start, held: float,
                  arrived: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """:meth:`JointLoop.run`'s cycles by :func:`~jointctl.metrics.step_loop_kernel.loop_run` (the same
    operations), or None where it has no compiled form (a load that is not a table, numba missing)."""
    none = (np.zeros(2), np.zeros(2), np.zeros(1))
    hold = none if loop.hold is None else _table(loop.hold)
    model = none if loop.feedforward_hold is None else _table(loop.feedforward_hold)
    if hold is None or model is None:
        return None
    try:
        from jointctl.metrics.step_loop_kernel import loop_run
    except ImportError:
        return None
    antiwindup, on_error, has_rates, feedforward, own_model, until_peak = flags
    n = reference.size
    qs, vs, us = np.empty(n), np.empty(n), np.empty(n)
    count = loop_run(np.array(plant), np.array(gains), np.array(
        [antiwindup, on_error, has_rates, feedforward, own_model, loop.hold is not None, until_peak], dtype=float),
        np.ascontiguousarray(reference, dtype=float),
        np.zeros(1) if rates is None else np.ascontiguousarray(rates, dtype=float), *hold, *model,
        np.array(start, dtype=float), np.full(loop.delay_cycles, held), arrived, qs, vs, us)
    return qs[:count], vs[:count], us[:count]


def holding_effort(robot, joint: str, pose: dict, gravity_m_s2=(0.0, 0.0, -9.81),
                   samples: int = 721, *, memo: dict | None = None) -> HoldingEffort | None:
    """``τ_hold(q)`` [N or N·m] of ``joint`` of ``robot`` with the other joints at ``pose`` (name -> position),
    read off the robot model at ``samples`` positions over the joint's range (a turn for a continuous joint,
    ±1 m for a prismatic one without limits) and interpolated; None when it is 0 everywhere. ``memo``: a dict
    keeping the answers for the same robot object, joint, other joints' pose, range and gravity (a sweep's runs
    on one simulated robot ask the same)."""
    from jointctl.model.dynamics import RobotDynamics

    names = [j.name for j in robot.movable_joints]
    k = names.index(joint)
    lower, upper, _ = robot.joint(joint).range_and_speed()
    here = float(pose.get(joint, 0.0))
    if not math.isfinite(upper - lower):
        reach = math.pi if robot.joint(joint).type != "prismatic" else 1.0
        lower, upper = here - reach, here + reach
    q = np.array([float(pose.get(name, 0.0)) for name in names])
    key = ("holding_effort", id(robot), joint, tuple(np.delete(q, k).tolist()), min(lower, here), max(upper, here),
           tuple(float(g) for g in gravity_m_s2), samples)
    if memo is not None and key in memo:
        return memo[key][1]  # (the robot, kept alive so that its id is not another's, the answer)
    hold = _holding_effort(RobotDynamics(robot, gravity_m_s2=gravity_m_s2), k, q,
                           np.linspace(min(lower, here), max(upper, here), samples))
    if memo is not None:
        memo[key] = (robot, hold)
    return hold


@dataclass(frozen=True, eq=False)
class HoldingEffort:
    """``τ_hold(q)`` [N or N·m] read off an even grid of positions [m or rad] from ``left`` every ``spacing``:
    linear inside a cell, straight on beyond the grid. ``values`` the efforts at the grid's positions, ``slopes``
    each cell's [N/m or N·m/rad] (numpy arrays, also read by the compiled loop of :mod:`step_loop_kernel`)."""

    left: float
    spacing: float
    values: np.ndarray
    slopes: np.ndarray

    @classmethod
    def zero(cls) -> HoldingEffort:
        """No load anywhere (0.0 at every position)."""
        return cls.constant(0.0)

    @classmethod
    def constant(cls, effort: float) -> HoldingEffort:
        """The same ``effort`` [N or N·m] at every position (an identified plant's gravity load)."""
        return cls(0.0, 1.0, np.full(2, float(effort)), np.zeros(1))

    def __post_init__(self) -> None:
        object.__setattr__(self, "_values", self.values.tolist())
        object.__setattr__(self, "_slopes", self.slopes.tolist())

    def __call__(self, position: float) -> float:
        # The grid is even: the cell by division, linear inside it, straight on beyond the range.
        left, spacing, last = self.left, self.spacing, len(self._slopes) - 1
        cell = int((position - left) // spacing)
        cell = 0 if cell < 0 else last if cell > last else cell
        return self._values[cell] + self._slopes[cell] * (position - left - cell * spacing)


def _holding_effort(dynamics, k: int, q: np.ndarray, grid: np.ndarray) -> HoldingEffort | None:
    samples = grid.size
    efforts = np.empty(samples)
    for n, value in enumerate(grid):
        q[k] = value
        dynamics.set_pose(q, inertia=False)
        efforts[n] = dynamics.gravity_at_pose()[k]
    if not np.any(np.abs(efforts) > 1e-12):
        return None
    left, right = float(grid[0]), float(grid[-1])
    spacing = (right - left) / (samples - 1)
    return HoldingEffort(left, spacing, efforts.copy(), np.diff(efforts) / spacing)


def reference_step(start: float, step: float, *, hold_s: float = 0.0, ramp_s: float = 0.0, after_s: float = 3.0,
                   period_s: float = 0.001) -> np.ndarray:
    """A reference [m or rad] held at ``start`` for ``hold_s``, then moved by ``step``, at once or along a ramp
    of ``ramp_s`` [s] (the value of a :class:`~jointctl.commands.sources.StepSource` with ``ramp_s``), watched
    ``after_s`` [s]; one value a ``period_s``."""
    t = np.arange(int(round((hold_s + after_s) / period_s))) * period_s - hold_s
    if ramp_s > 0:
        return start + step * np.clip(t / ramp_s, 0.0, 1.0)
    return start + np.where(t >= -1e-12, step, 0.0)


@dataclass(frozen=True)
class StepFigures:
    """A move's figures: ``overshoot_pct`` past the final value, as a share of the rise from the start
    (NaN for no rise), ``settling_s`` [s] after the move began until it stays within :data:`SETTLING_BAND`
    of the move around the final value (NaN if never), ``start`` and ``final`` positions and
    ``final_error`` (reference minus final) [m or rad], ``peak_effort`` [N or N·m] the largest command
    magnitude, ``saturated_share`` of the cycles after the move began within :data:`SATURATION_MARGIN` of the
    effort limit."""

    overshoot_pct: float
    settling_s: float
    start: float
    final: float
    final_error: float
    peak_effort: float
    saturated_share: float

    def as_dict(self, prefix: str = "") -> dict:
        return {f"{prefix}{k}": float(v) for k, v in self.__dict__.items()}


def step_figures(t: np.ndarray, q: np.ndarray, reference: np.ndarray, effort: np.ndarray | None = None,
                 effort_limit: float = math.inf) -> StepFigures:
    """:class:`StepFigures` of positions ``q`` [m or rad] at times ``t`` [s] answering ``reference``; the move
    begins at the first cycle whose reference leaves its first value. The final value is the mean of the last
    0.2 s (or fifth)."""
    reference = np.asarray(reference, dtype=float)
    moved = np.nonzero(np.abs(reference - reference[0]) > 1e-12)[0]
    begin = int(moved[0]) if moved.size else 0
    y, tt = q[begin:], t[begin:]
    tail = max(1, min(y.size // 5, int(round(0.2 / max(t[1] - t[0], 1e-9))) if t.size > 1 else 1))
    start, final = float(q[begin]), float(y[-tail:].mean())
    rise = final - start
    overshoot = 100 * float(((y - final) * np.sign(rise)).max()) / abs(rise) if abs(rise) > 0 else math.nan
    band = SETTLING_BAND * abs(float(reference[-1] - reference[0]) or rise)
    outside = np.nonzero(np.abs(y - final) > band)[0]
    if outside.size == 0:
        settling = 0.0
    elif outside[-1] == y.size - 1:
        settling = math.nan
    else:
        settling = float(tt[outside[-1] + 1] - tt[0])
    peak = saturated = 0.0
    if effort is not None:
        u = np.abs(np.asarray(effort)[begin:])
        peak = float(u.max()) if u.size else 0.0
        if math.isfinite(effort_limit) and u.size:
            saturated = float(np.mean(u >= (1 - SATURATION_MARGIN) * effort_limit))
    return StepFigures(overshoot, settling, start, final, float(reference[-1]) - final, peak, saturated)


__all__ = ["JointLoop", "LAWS", "SATURATION_MARGIN", "SETTLING_BAND", "StepFigures", "holding_effort", "reference_step",
           "step_figures"]

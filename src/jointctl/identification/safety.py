"""Exciting a joint safely: amplitudes inside its limits, the actuator's saturation measured, the user's limits watched.

``identify``, ``bode`` and ``autotune`` move a joint on purpose. On a real robot a sine that is too
large for its frequency drives the motor into its effort limit (the loop then is not the loop that
is measured) or the joint into its stops. Three things keep them safe, on a simulated robot and on
hardware alike (they are hooks of the session's loop):

**The amplitude rule.** A reference of amplitude ``A`` (a sine at ``f`` for bode, the windowed chirp
for identify) moves the joint, per unit of ``A``, by a position swing ``P``, a speed ``V`` and an
effort ``E`` that the loop model predicts (the plant ``m``, ``b`` from ``--plant`` or the robot model,
the controller's gains and derivative law at the loop period:
:class:`~jointctl.identification.frequency_response.LoopModel`; a sine's steady state at ``f``, the
chirp simulated from rest). The largest safe amplitude is the smallest of::

    position  A·max(1, P)                ≤ range_fraction  · room where it really rests
    velocity  A·V                        ≤ speed_fraction  · min(URDF velocity, --max-velocity)
    effort    A·(E + k·P) + k·droop + load ≤ effort_fraction · min(URDF effort, --max-effort)

``room`` [m or rad] is the distance from where the joint rests to the nearer end of its URDF range
intersected with ``--workspace`` (one unit each way for a joint with no range); the reference itself
stays inside too (the 1 in ``max(1, P)``; for a velocity loop the reference's own swing ``A/ω``).
``droop`` is the static error of a position loop without an integral or gravity feed-forward, where
``p·(r - q) = τ_hold(q)`` (:func:`real_rest`: the load where the joint droops to, not at the reference); the
room is read from there, where the joint really rests (and from the reference, whose own swing stays inside
too); ``load`` [N or N·m] the gravity load where the joint rests (the robot model at the pose)
plus the Coulomb friction (``--plant``'s, else the URDF's), and ``k`` [N/m or N·m/rad] the largest
gravity stiffness ``|∂gravity/∂q|`` over the positions the position budget allows: the gravity load
anywhere in the swing is at most ``load + k·swing``, whatever feed-forward supplies it. The
fractions default to 0.3, 0.5 and 0.5 (:class:`Safety`). A requested amplitude beyond the safe one
is refused naming the largest safe one and the limit that binds; the limit that binds is reported
with every plan. Without a loop model (a servo loop that is not jointctl's) ``P = 1``, ``V = ω``
and the effort is not planned. Autotune's step is checked against the effort exactly (its first
cycle asks ``p·step + |gravity|``, and ``d·step/period`` more with the derivative on the error:
:func:`jointctl.identification.autotune.tune`).

**Saturation.** Every control cycle of an excitation counts as saturated when the joint's measured
effort is within ``saturation_margin`` (2 %) of the actuator's effort limit, or its speed of the
velocity limit (the URDF's: what the actuator can do; :class:`SaturationMonitor`). The share of
saturated cycles is reported per bode point, over identify's excitation and over autotune's check;
above ``saturation_share`` (1 %) identify refuses to fit, bode marks the point (``saturated``, left
out of its figures of merit) and autotune warns.

**The user's limits.** ``--max-effort`` [N or N·m], ``--max-velocity`` [m/s or rad/s] and
``--workspace LOWER:UPPER`` [m or rad] of the excited joint bound the plan (above) and are watched
every cycle (:class:`Guard`), with the URDF range less a guard band of 5 % at each end: when the
measured effort, speed or position crosses one, the excitation stops, the reference is ramped back
(a raised cosine no steeper than the speed budget, :meth:`Guard.ramp_s`) to where it started, the
joint settles there, and the command fails naming the limit, the value and the loop time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from jointctl.errors import JointCtlError
from jointctl.identification.plant_fit import IdentificationError

#: The guard's band: this fraction of the URDF range from each end.
GUARD_FRACTION = 0.05
#: The shortest ramp back after a stop [s]; then the joint is at rest once its speed stays under
#: REST_SPEED_FRACTION of the room a second for SETTLE_AFTER_RETURN_S [s].
RAMP_MIN_S = 1.0
SETTLE_AFTER_RETURN_S = 0.5
REST_SPEED_FRACTION = 0.01
#: A velocity loop's way back: the position error's gain [1/s] and the longest it may take [s].
RETURN_GAIN_PER_S = 1.0
RETURN_MAX_S = 10.0
#: A measured value crosses a user limit when it exceeds it by more than this fraction of it (a plan
#: that reaches a limit exactly, as autotune's check step may, is not a crossing by rounding).
CROSSING_TOLERANCE = 1e-6
#: How much loop time a guarded run lets pass between looks at the guard [s].
CHUNK_S = 0.25


class SafetyStop(IdentificationError):
    """The measured motion crossed a limit: the excitation was stopped and the joint brought back.
    ``field`` names the limit (``--max-effort``, ``--max-velocity``, ``--workspace`` or ``position``
    for the URDF range's guard band), ``value`` the measured value, ``time_s`` the loop time [s]."""

    code = "safety"

    def __init__(self, message: str, *, field: str, value: float, time_s: float) -> None:
        super().__init__(message, field=field, value=value)
        self.time_s = time_s


@dataclass(frozen=True)
class UserLimits:
    """Limits the user sets on the excited joint, on top of the URDF's: ``max_effort`` [N or N·m],
    ``max_velocity`` [m/s or rad/s] (magnitudes) and ``workspace`` (lower, upper) [m or rad]; None
    where not set. Refused (JointCtlError naming the flag) unless positive and finite, lower < upper."""

    max_effort: float | None = None
    max_velocity: float | None = None
    workspace: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for flag, value in (("--max-effort", self.max_effort), ("--max-velocity", self.max_velocity)):
            if value is not None and not (isinstance(value, (int, float)) and not isinstance(value, bool)
                                          and math.isfinite(value) and value > 0):
                raise JointCtlError("must be a positive number", field=flag, value=value)
        if self.workspace is not None:
            lower, upper = self.workspace
            if not (math.isfinite(lower) and math.isfinite(upper) and lower < upper):
                raise JointCtlError("must be LOWER:UPPER with LOWER below UPPER, finite", field="--workspace",
                                    value=f"{lower:g}:{upper:g}")


def parse_workspace(text: str) -> tuple[float, float]:
    """``"LOWER:UPPER"`` [m or rad] -> (lower, upper); JointCtlError naming ``--workspace`` otherwise."""
    lower, sep, upper = str(text).partition(":")
    try:
        if not sep:
            raise ValueError
        bounds = (float(lower), float(upper))
    except ValueError:
        raise JointCtlError("must be LOWER:UPPER, two numbers [m or rad]", field="--workspace", value=text) from None
    UserLimits(workspace=bounds)
    return bounds


@dataclass(frozen=True)
class Safety:
    """How an excitation is kept safe (see the module docstring): the user's ``limits``, the
    fractions of each limit the plan may use, and what counts as saturated: a cycle within
    ``saturation_margin`` (a fraction) of the actuator's effort or velocity limit, a measurement
    with more than ``saturation_share`` (a fraction) of its cycles saturated."""

    limits: UserLimits = field(default_factory=UserLimits)
    range_fraction: float = 0.3
    speed_fraction: float = 0.5
    effort_fraction: float = 0.5
    saturation_margin: float = 0.02
    saturation_share: float = 0.01

    def __post_init__(self) -> None:
        for name in ("range_fraction", "speed_fraction", "effort_fraction"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0 < value <= 1):
                raise JointCtlError("must be in (0, 1]", field=name, value=value)
        for name in ("saturation_margin", "saturation_share"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0 <= value < 1):
                raise JointCtlError("must be in [0, 1)", field=name, value=value)


DEFAULT = Safety()


@dataclass(frozen=True)
class Envelope:
    """What the excitation of ``joint`` must stay inside, resting at ``rest`` [m or rad]: its URDF
    ``lower``/``upper`` [m or rad], ``velocity_limit`` [/s] and ``effort_limit`` [N or N·m] (inf when
    none), the ``safety`` settings (the user's limits in them), ``bias`` (the load at rest) [N or N·m],
    ``droop`` [m or rad] and ``stiffness`` (the gravity stiffness k) [N/m or N·m/rad] of the module
    docstring, and ``unit`` ("m" or "rad")."""

    joint: str
    rest: float
    lower: float
    upper: float
    velocity_limit: float
    effort_limit: float
    safety: Safety = DEFAULT
    bias: float = 0.0
    droop: float = 0.0
    unit: str = "rad"
    stiffness: float = 0.0
    resting_at: float | None = None

    @property
    def window(self) -> tuple[float, float]:
        """The positions the plan may use [m or rad]: the URDF range intersected with the workspace."""
        workspace = self.safety.limits.workspace
        if workspace is None:
            return self.lower, self.upper
        return max(self.lower, workspace[0]), min(self.upper, workspace[1])

    @property
    def room(self) -> float:
        """From ``rest`` to the nearer end of :attr:`window` [m or rad] (1 when it has no end)."""
        lower, upper = self.window
        room = min(self.rest - lower, upper - self.rest)
        return 1.0 if math.isinf(room) else room

    @property
    def velocity_max(self) -> float:
        """The speed the joint must stay under [m/s or rad/s]: the URDF's, or the user's if lower."""
        user = self.safety.limits.max_velocity
        return min(self.velocity_limit, user) if user is not None else self.velocity_limit

    @property
    def effort_max(self) -> float:
        """The effort the joint must stay under [N or N·m]: the URDF's, or the user's if lower."""
        user = self.safety.limits.max_effort
        return min(self.effort_limit, user) if user is not None else self.effort_limit

    @property
    def room_at_rest(self) -> float:
        """The room [m or rad] where the joint really rests: from ``resting_at`` (a P loop's droop below its
        reference ``rest``) to the nearer end of :attr:`window`, and no more than from the reference (whose
        own swing stays inside too); :attr:`room` without a droop."""
        if self.resting_at is None:
            return self.room
        lower, upper = self.window
        room = min(self.resting_at - lower, upper - self.resting_at)
        return min(self.room, 1.0 if math.isinf(room) else room)

    def budgets(self) -> dict[str, float]:
        """What the motion may use of each limit: ``position`` [m or rad] (the swing about where the joint
        really rests, :attr:`room_at_rest`), ``velocity`` [/s] and ``effort`` [N or N·m] (after the load at
        rest and the droop's)."""
        s = self.safety
        return {"position": s.range_fraction * self.room_at_rest,
                "velocity": s.speed_fraction * self.velocity_max,
                "effort": s.effort_fraction * self.effort_max - self.bias - self.stiffness * self.droop}

    def check(self) -> None:
        """Refuse (IdentificationError naming the limit) an envelope that leaves nothing to excite."""
        lower, upper = self.window
        workspace = self.safety.limits.workspace
        if workspace is not None and not workspace[0] <= self.rest <= workspace[1]:
            raise IdentificationError(f"the joint {self.joint} rests at {self.rest:.4g} {self.unit}, outside the "
                                      "workspace: move it inside first", field="--workspace",
                                      value=f"{workspace[0]:g}:{workspace[1]:g}")
        if not self.lower <= self.rest <= self.upper:
            raise IdentificationError(f"the joint rests outside its range [{self.lower:g}, {self.upper:g}]",
                                      field="start", value=self.rest)
        budgets = self.budgets()
        if not budgets["position"] > 0:
            where = self.rest if self.resting_at is None else self.resting_at
            raise IdentificationError("the joint rests at a limit: no room to excite it"
                                      + (f" (it rests at {where:.4g} {self.unit}, {self.droop:.3g} from its reference "
                                         f"{self.rest:.4g}, the loop's p holding its load)" if self.droop else ""),
                                      field="start", value=where)
        if not budgets["effort"] > 0:
            flag = "--max-effort" if self.effort_max < self.effort_limit else "effort"
            raise IdentificationError(f"the load at rest ({self.bias:.4g}: gravity and friction) takes all of "
                                      f"{self.safety.effort_fraction:g} of the effort limit {self.effort_max:.4g}: "
                                      "nothing is left to move the joint", field=flag, value=self.effort_max)

    def limit_names(self) -> dict[str, str]:
        """Which limit each budget comes from, as the user would name it."""
        limits = self.safety.limits
        workspace = limits.workspace
        names = {"position": "the workspace" if workspace is not None and (
            workspace[0] > self.lower or workspace[1] < self.upper) else "the joint's range"}
        names["velocity"] = ("--max-velocity" if limits.max_velocity is not None
                             and limits.max_velocity < self.velocity_limit else "the joint's velocity limit")
        names["effort"] = ("--max-effort" if limits.max_effort is not None
                           and limits.max_effort < self.effort_limit else "the joint's effort limit")
        return names


@dataclass(frozen=True)
class Peaks:
    """Per unit of amplitude, the largest position swing [m or rad], speed [/s] and effort [N or N·m]
    (NaN: not predicted, no loop model) a reference makes."""

    position: float
    velocity: float
    effort: float


@dataclass(frozen=True)
class Allowance:
    """The largest safe ``amplitude`` for ``peaks`` in an ``envelope``, and the limit that ``binds``
    ("position", "velocity" or "effort")."""

    amplitude: float
    binds: str
    peaks: Peaks
    envelope: Envelope

    def predicted(self, amplitude: float | None = None) -> dict:
        """The peak motion ``amplitude`` (default the safe one) makes, each beside its limit and budget:
        position swing [m or rad] (droop included), velocity [/s], effort [N or N·m] (the load included)."""
        a = self.amplitude if amplitude is None else amplitude
        env, p = self.envelope, self.peaks
        swing = env.droop + a * p.position
        return predicted_peaks(env, swing, a * p.velocity, a * p.effort)

    def refuse_beyond(self, amplitude: float, *, flag: str = "amplitude", what: str = "") -> None:
        """IdentificationError naming the largest safe amplitude and the limit that binds, unless
        ``amplitude`` is positive and at most it."""
        if isinstance(amplitude, (int, float)) and 0 < amplitude <= self.amplitude * (1 + 1e-12):
            return
        name = self.envelope.limit_names()[self.binds]
        raise IdentificationError(f"must be positive and at most {self.amplitude:.4g} {self.envelope.unit}{what}: "
                                  f"{name} binds ({self.binds}: {_rule_text(self)})", field=flag, value=amplitude)


def predicted_peaks(envelope: Envelope, swing: float, velocity: float, effort: float) -> dict:
    """The peaks of a motion beside their budgets and limits: ``swing`` [m or rad] from the rest
    reference (the droop included), ``velocity`` [/s] and ``effort`` [N or N·m], the effort the loop
    adds (NaN: not predicted), to which the load at rest and the gravity stiffness over the swing add."""
    budgets = envelope.budgets()
    total = envelope.bias + envelope.stiffness * swing + effort if math.isfinite(effort) else math.nan
    return {"position": {"peak": swing, "budget": budgets["position"] + envelope.droop, "room": envelope.room_at_rest},
            "velocity": {"peak": velocity, "budget": budgets["velocity"], "limit": envelope.velocity_max},
            "effort": {"peak": total, "budget": envelope.safety.effort_fraction * envelope.effort_max,
                       "limit": envelope.effort_max}}


def _rule_text(allowance: Allowance) -> str:
    env, predicted = allowance.envelope, allowance.predicted()
    s = env.safety
    if allowance.binds == "position":
        if env.droop:
            return (f"the swing {predicted['position']['peak'] - env.droop:.4g} {env.unit} about where it rests "
                    f"({env.resting_at:.4g} {env.unit}, {env.droop:.3g} from its reference) is "
                    f"{s.range_fraction:g} of the {env.room_at_rest:.4g} {env.unit} of room there")
        return (f"the swing {predicted['position']['peak']:.4g} {env.unit} is {s.range_fraction:g} of the "
                f"{env.room:.4g} {env.unit} of room")
    if allowance.binds == "velocity":
        return (f"a peak speed of {predicted['velocity']['peak']:.4g} {env.unit}/s is {s.speed_fraction:g} of "
                f"{env.velocity_max:g}")
    unit = "N" if env.unit == "m" else "N·m"
    return f"a peak effort of {predicted['effort']['peak']:.4g} {unit} is {s.effort_fraction:g} of {env.effort_max:g}"


def allow(peaks: Peaks, envelope: Envelope) -> Allowance:
    """The largest amplitude for which ``peaks`` stays inside each of ``envelope``'s budgets."""
    envelope.check()
    budgets = envelope.budgets()
    effort = peaks.effort + envelope.stiffness * peaks.position
    candidates = {"position": budgets["position"] / peaks.position if peaks.position > 0 else math.inf,
                  "velocity": budgets["velocity"] / peaks.velocity if peaks.velocity > 0 else math.inf,
                  "effort": budgets["effort"] / effort if effort > 0 else math.inf}
    binds = min(candidates, key=candidates.get)
    return Allowance(candidates[binds], binds, peaks, envelope)


def sine_peaks(model, frequency_hz: float, loop: str = "position") -> Peaks:
    """Per unit amplitude, the steady-state peaks of a sine reference at ``frequency_hz`` through
    ``model`` (a LoopModel, or None: the reference alone, effort not predicted). The reference's own
    swing counts as well (1, or ``1/ω`` for a velocity loop's), and so does its speed when there is no model."""
    w = 2 * math.pi * frequency_hz
    if model is None:
        return (Peaks(1.0, w, math.nan) if loop == "position" else Peaks(1.0 / w, 1.0, math.nan))
    response = model.unit_response([frequency_hz])
    position, velocity, effort = (float(abs(response[k][0])) for k in ("position", "velocity", "effort"))
    if loop == "position":
        return Peaks(max(1.0, position), velocity, effort)
    return Peaks(max(1.0 / w, position), max(1.0, velocity), effort)


def reference_peaks(model, reference, period_s: float, *, settle_cycles: int = 0) -> Peaks:
    """Per unit amplitude, the peaks of the loop ``model`` driven by ``reference`` (a position loop's
    reference, one value a loop period, the deviation from rest for a unit amplitude) from rest and
    ``settle_cycles`` more at rest; the reference's own swing counts as well. Without a model, the
    reference's own swing and speed (by differences over ``period_s`` [s])."""
    r = np.concatenate([np.asarray(reference, dtype=float), np.zeros(settle_cycles)])
    if model is None:
        speed = np.abs(np.diff(r)).max() / period_s if r.size > 1 else 0.0
        return Peaks(float(np.abs(r).max()), float(speed), math.nan)
    q, v, u = model.simulate(r)
    return Peaks(float(max(np.abs(q).max(), np.abs(r).max())), float(np.abs(v).max()), float(np.abs(u).max()))


def gravity_profile(robot, joint: str, pose: dict, lower: float, upper: float, gravity_m_s2=(0.0, 0.0, -9.81),
                    samples: int = 17) -> tuple[float, float]:
    """(|gravity effort| [N or N·m] on ``joint`` at ``lower``, the largest gravity stiffness |∂g/∂q|
    [N/m or N·m/rad] over [``lower``, ``upper``] [m or rad]) with the other joints at ``pose`` (joint
    name -> position), from the robot model; the stiffness by central differences at ``samples`` positions."""
    from jointctl.model.dynamics import RobotDynamics

    dynamics = RobotDynamics(robot, gravity_m_s2=gravity_m_s2)
    names = [j.name for j in robot.movable_joints]
    k = names.index(joint)
    base = [float(pose.get(n, 0.0)) for n in names]

    def load(q: float) -> float:
        base[k] = float(q)
        dynamics.set_pose(base, inertia=False)
        return float(dynamics.gravity_at_pose()[k])

    h = 1e-6
    stiffness = max(abs(load(q + h) - load(q - h)) / (2 * h)
                    for q in (np.linspace(lower, upper, samples) if upper > lower else [lower]))
    return abs(load(lower)), stiffness


def envelope_for(robot, joint: str, rest: float, safety: Safety | None = None, *, pose: dict | None = None,
                 gravity_m_s2=(0.0, 0.0, -9.81), friction: float | None = None, droop_gain: float | None = None,
                 effort_limit: float | None = None) -> Envelope:
    """The envelope of ``joint`` of ``robot`` resting at ``rest``: the URDF's limits (``effort_limit``
    overrides the URDF's effort, e.g. a controller's), ``safety``'s user limits; the load at rest
    (gravity there, the others at ``pose``, plus ``friction`` [N or N·m], default the URDF's), the
    gravity stiffness over the positions the position budget allows, and the droop, the gravity load
    over ``droop_gain`` (the position loop's p when nothing else holds gravity; None: no droop)."""
    safety = safety or DEFAULT
    spec = robot.joint(joint)
    lower, upper, speed = spec.range_and_speed()
    if effort_limit is None:
        effort_limit = spec.limits.effort if spec.limits is not None and spec.limits.effort > 0 else math.inf
    unit = "m" if spec.type == "prismatic" else "rad"
    bare = Envelope(joint, rest, lower, upper, speed, effort_limit, safety, unit=unit)
    bare.check()
    reach = safety.range_fraction * bare.room
    window = bare.window
    load, _ = gravity_profile(robot, joint, pose or {}, rest, rest, gravity_m_s2)
    _, stiffness = gravity_profile(robot, joint, pose or {}, max(window[0], rest - reach),
                                   min(window[1], rest + reach), gravity_m_s2)
    bias = load + abs(spec.friction if friction is None else friction)
    resting_at = real_rest(robot, joint, pose or {}, rest, droop_gain, gravity_m_s2) if droop_gain else None
    droop = abs(rest - resting_at) if resting_at is not None else 0.0
    return Envelope(joint, rest, lower, upper, speed, effort_limit, safety, bias, droop, unit, stiffness, resting_at)


def real_rest(robot, joint: str, pose: dict, reference: float, p: float, gravity_m_s2=(0.0, 0.0, -9.81)) -> float:
    """Where a P loop of stiffness ``p`` [N/m or N·m/rad] holding ``reference`` [m or rad] really rests under
    gravity, the other joints at ``pose``: ``p·(r - q) = τ_hold(q)``, the holding effort of the robot model
    over the joint's range (not its value at the reference: a low ``p`` droops where the load is another);
    by fixed-point iteration, damped where the load's slope is close to ``p``. An IdentificationError when
    ``p`` cannot hold the load anywhere near."""
    from jointctl.identification.step_loop import holding_effort

    hold = holding_effort(robot, joint, pose, gravity_m_s2)
    if hold is None:
        return reference
    q = reference
    for _ in range(500):
        new = reference - hold(q) / p
        if abs(new - q) < 1e-12:
            return new
        q = 0.5 * (q + new)
    if abs(reference - hold(q) / p - q) < 1e-6:
        return q
    raise IdentificationError(f"its loop's p {p:.4g} cannot hold its gravity load near {reference:.4g}: it would "
                              "fall away (raise p, or add an integral or the gravity feed-forward)",
                              field="start", value=reference)


class SaturationMonitor:
    """A loop observer: at every cycle, whether the joint's measured effort is within the margin of
    ``effort_limit`` [N or N·m] or its speed of ``velocity_limit`` [/s] (the actuator's limits; see
    the module docstring). :meth:`share` counts them over a stretch of loop time."""

    def __init__(self, hardware, index: int, effort_limit: float, velocity_limit: float, margin: float) -> None:
        self._hardware, self._index = hardware, index
        self.effort_limit, self.velocity_limit, self.margin = effort_limit, velocity_limit, margin
        self._effort_at = (1 - margin) * effort_limit
        self._velocity_at = (1 - margin) * velocity_limit
        self.rows: list[tuple[float, bool, bool, float, float]] = []

    def __call__(self, time_s: float) -> None:
        u, v = self._hardware.effort[self._index], self._hardware.velocity[self._index]
        self.rows.append((time_s, abs(u) >= self._effort_at, abs(v) >= self._velocity_at, u, v))

    def share(self, start_s: float = -math.inf, end_s: float = math.inf) -> dict:
        """Over the cycles in [``start_s``, ``end_s``): the shares (fractions) of cycles at the effort
        limit, at the velocity limit and at either, the cycles counted, the peak |effort| and |speed|."""
        rows = [r for r in self.rows if start_s <= r[0] < end_s]
        n = len(rows)
        if not n:
            return {"share": 0.0, "effort_share": 0.0, "velocity_share": 0.0, "cycles": 0,
                    "peak_effort": math.nan, "peak_velocity": math.nan}
        effort = sum(1 for r in rows if r[1])
        velocity = sum(1 for r in rows if r[2])
        either = sum(1 for r in rows if r[1] or r[2])
        return {"share": either / n, "effort_share": effort / n, "velocity_share": velocity / n, "cycles": n,
                "peak_effort": max(abs(r[3]) for r in rows), "peak_velocity": max(abs(r[4]) for r in rows)}

    def describe(self) -> dict:
        return {"effort_limit": self.effort_limit, "velocity_limit": self.velocity_limit, "margin": self.margin}


def saturation_text(share: dict, monitor: SaturationMonitor, unit: str) -> str:
    """One phrase naming the share of saturated cycles and the limit that saturated most."""
    effort_unit = "N" if unit == "m" else "N·m"
    parts = []
    if share["effort_share"]:
        parts.append(f"{100 * share['effort_share']:.3g} % of the cycles at the effort limit "
                     f"{monitor.effort_limit:g} {effort_unit}")
    if share["velocity_share"]:
        parts.append(f"{100 * share['velocity_share']:.3g} % at the velocity limit {monitor.velocity_limit:g} "
                     f"{unit}/s")
    return " and ".join(parts) or "no cycle at a limit"


class Guard:
    """Watches the joint at ``index`` of ``hardware`` against ``envelope``'s user limits and its
    URDF range less ``band`` [m or rad] at each end, every cycle (:meth:`observe`, a loop observer),
    and, once a limit is crossed, replaces the excitation's reference (:meth:`reference`, called
    by the excitation's loop input with what it would send) by the way back to where it started:
    a position loop's reference ramps from its last value to ``start`` (a raised cosine, :meth:`ramp_s`);
    a velocity loop's fades to zero while a position term, ``RETURN_GAIN_PER_S·(start_position - q)``
    capped at the speed budget, brings the joint back. :attr:`finished` once it is back and at rest
    (its speed under ``REST_SPEED_FRACTION`` of the room a second for ``SETTLE_AFTER_RETURN_S``), or
    ``RETURN_MAX_S`` after the stop; :meth:`error` then says what happened."""

    def __init__(self, hardware, index: int, envelope: Envelope, *, loop: str = "position",
                 start: float | None = None, band: float = 0.0) -> None:
        self._hardware, self._index, self.envelope, self.loop = hardware, index, envelope, loop
        self.start = envelope.rest if start is None else start  # the reference to come back to
        self.start_position = envelope.rest
        self.band = band
        limits = envelope.safety.limits
        if math.isfinite(band):
            self._range = (envelope.lower + band, envelope.upper - band)
        else:
            self._range = (-math.inf, math.inf)
        self._workspace = limits.workspace
        self._max_effort = limits.max_effort
        self._max_velocity = limits.max_velocity
        self.trip: dict | None = None
        self._last = self.start
        self._back_at: float | None = None
        self._still_since: float | None = None
        self._rest_speed = REST_SPEED_FRACTION * envelope.room
        self._now = 0.0

    def observe(self, time_s: float) -> None:
        """The loop observer: checks this cycle's measured position, speed and effort."""
        hw, i = self._hardware, self._index
        self._now = time_s
        q = hw.position[i]
        v, u = hw.velocity[i], hw.effort[i]
        if self.trip is not None:
            self.trip["now"] = q
            if self._back_at is None or abs(v) > self._rest_speed:
                self._still_since = None
            elif self._still_since is None:
                self._still_since = time_s
            return
        ws = self._workspace
        if ws is not None and not ws[0] <= q <= ws[1]:
            self._stop(time_s, "--workspace", "position", q, f"{ws[0]:g}:{ws[1]:g}")
        elif self._max_velocity is not None and abs(v) > self._max_velocity * (1 + CROSSING_TOLERANCE):
            self._stop(time_s, "--max-velocity", "speed", v, f"{self._max_velocity:g}")
        elif self._max_effort is not None and abs(u) > self._max_effort * (1 + CROSSING_TOLERANCE):
            self._stop(time_s, "--max-effort", "effort", u, f"{self._max_effort:g}")
        elif not self._range[0] <= q <= self._range[1]:
            self._stop(time_s, "position", "range", q, f"[{self.envelope.lower:g}, {self.envelope.upper:g}]")

    def _stop(self, time_s: float, flag: str, what: str, value: float, limit: str) -> None:
        self.trip = {"field": flag, "what": what, "value": float(value), "limit": limit, "time_s": time_s,
                     "reference": self._last, "now": self._hardware.position[self._index]}

    @property
    def ramp_s(self) -> float:
        """How long the way back takes [s]: a position loop's raised cosine from the last reference
        to the start, at most the speed budget at its steepest (π/2·Δ/T), at least ``RAMP_MIN_S``."""
        if self.trip is None:
            return 0.0
        delta = abs(self.trip["reference"] - self.start)
        speed = self.envelope.budgets()["velocity"]
        return max(RAMP_MIN_S, math.pi / 2 * delta / speed if speed > 0 and math.isfinite(speed) else 0.0)

    def reference(self, time_s: float, planned: float) -> float:
        """The reference to send at ``time_s``: ``planned`` until a limit is crossed, then the way back."""
        trip = self.trip
        if trip is None:
            self._last = planned
            return planned
        elapsed = time_s - trip["time_s"]
        if self.loop == "position":
            s = min(1.0, max(0.0, elapsed / self.ramp_s))
            value = self.start + (trip["reference"] - self.start) * 0.5 * (1 + math.cos(math.pi * s))
            if s >= 1.0 and self._back_at is None:
                self._back_at = time_s
            return value
        fade = 0.5 * (1 + math.cos(math.pi * min(1.0, elapsed / RAMP_MIN_S)))
        cap = self.envelope.budgets()["velocity"]
        error = self.start_position - self._hardware.position[self._index]
        back = max(-cap, min(cap, RETURN_GAIN_PER_S * error))
        if self._back_at is None and elapsed >= RAMP_MIN_S and abs(error) <= 0.01 * self.envelope.room:
            self._back_at = time_s
        return fade * trip["reference"] + back

    @property
    def finished(self) -> bool:
        """A limit was crossed and the joint is back and settled (or the way back took too long)."""
        trip = self.trip
        if trip is None:
            return False
        now = self._now
        if self._still_since is not None and now - self._still_since >= SETTLE_AFTER_RETURN_S:
            return True
        return now - trip["time_s"] >= RETURN_MAX_S

    @property
    def at_rest(self) -> bool:
        """After a stop: the joint came back and is at rest (not merely out of time)."""
        return self._still_since is not None and self._now - self._still_since >= SETTLE_AFTER_RETURN_S

    def error(self, what: str = "the excitation") -> SafetyStop:
        """The SafetyStop saying which limit was crossed, by what, when and where the joint is now."""
        trip, env = self.trip, self.envelope
        unit = env.unit
        units = {"position": unit, "range": unit, "speed": f"{unit}/s", "effort": "N" if unit == "m" else "N·m"}
        where = (f"the joint came within {self.band:.3g} of a limit of its range {trip['limit']} {unit}"
                 if trip["what"] == "range" else
                 f"the joint's {trip['what']} reached {trip['value']:.4g} {units[trip['what']]}, beyond "
                 f"{trip['field']} {trip['limit']}")
        back = (f"the joint brought back to {self.start_position:.4g} {unit}" if self.loop == "velocity" else
                f"the reference ramped back to {self.start:.4g} {unit} over {self.ramp_s:.3g} s")
        rest = "at rest" if self.at_rest else f"still moving {RETURN_MAX_S:g} s after the stop"
        advice = {"range": "; give a smaller --amplitude", "position": "; give a smaller --amplitude or a wider "
                  "--workspace", "speed": "; give a smaller --amplitude or a higher --max-velocity",
                  "effort": "; give a smaller --amplitude or a higher --max-effort"}[trip["what"]]
        return SafetyStop(f"{where} at t = {trip['time_s']:.3f} s: {what} was stopped, {back} (the joint "
                          f"{rest} at {trip['now']:.4g} {unit}){advice}", field=trip["field"], value=trip["value"],
                          time_s=trip["time_s"])


def run_guarded(session, duration_s: float, guard: Guard, chunk_s: float = CHUNK_S) -> None:
    """``session.run`` for ``duration_s`` [s] of loop time, in chunks of ``chunk_s``; after a stop,
    until ``guard`` has brought the joint back (however long the plan had left, at most
    ``RETURN_MAX_S``), and no longer."""
    period = session.loop.period_s
    remaining = int(round(duration_s / period))
    chunk = max(1, int(round(chunk_s / period)))
    with session:
        while not guard.finished and (remaining > 0 or guard.trip is not None):
            cycles = min(chunk, remaining) if guard.trip is None else chunk
            session.run(cycles * period)
            remaining -= cycles


def plan_rows(envelope: Envelope) -> list[str]:
    """The envelope's limits, one line each, for a printed plan."""
    unit = envelope.unit
    effort_unit = "N" if unit == "m" else "N·m"
    lower, upper = envelope.window
    s = envelope.safety
    return [f"  position   rest {envelope.rest:.4g} {unit}, window [{lower:g}, {upper:g}] {unit} "
            f"({envelope.limit_names()['position']}), room {envelope.room:.4g} {unit}, budget "
            f"{s.range_fraction:g} of it" + (f", droop {envelope.droop:.3g} {unit}" if envelope.droop else ""),
            f"  velocity   limit {envelope.velocity_max:g} {unit}/s ({envelope.limit_names()['velocity']}), "
            f"budget {s.speed_fraction:g} of it",
            f"  effort     limit {envelope.effort_max:g} {effort_unit} ({envelope.limit_names()['effort']}), "
            f"budget {s.effort_fraction:g} of it, load at rest {envelope.bias:.4g} {effort_unit}"
            + (f", gravity stiffness {envelope.stiffness:.4g} {effort_unit}/{unit}" if envelope.stiffness else "")]


__all__ = ["Allowance", "DEFAULT", "Envelope", "GUARD_FRACTION", "Guard", "Peaks", "Safety", "SafetyStop",
           "SaturationMonitor", "UserLimits", "allow", "envelope_for", "parse_workspace", "plan_rows",
           "predicted_peaks", "reference_peaks", "run_guarded", "saturation_text", "sine_peaks", "gravity_profile"]

"""A safe excitation for identifying one joint: a windowed chirp around where the joint rests.

The joint's own position controller follows ``start + A·w(t)·sin(φ(t))`` [rad or m]: ``φ`` sweeps
linearly from ``f_start_hz`` to ``f_end_hz`` over ``duration_s``, and the window
``w(t) = sin²(π·t/duration_s)`` makes the reference start and end at ``start`` with zero velocity,
so the joint starts and ends at rest where it was.

:func:`planned_chirp` chooses the amplitude by the rule of :mod:`jointctl.identification.safety`:
the joint's loop model is driven by the chirp itself (a unit amplitude, from rest, and the settling
after it), and the largest amplitude whose predicted position swing, speed and effort stay inside
their budgets over the whole band is the safe one (a resonance in the band makes it smaller; so does a
loop whose effort grows with frequency). :func:`safe_chirp`, without a model, keeps the reference
itself inside: at most ``range_fraction`` of the distance from the start to the nearer end of the
range, and slow enough that the reference's peak speed (``≤ A·(2π·f_end + π/duration)``) stays
within ``speed_fraction`` of the joint's velocity limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointctl.identification.frequency_response import loop_model, plant_friction
from jointctl.identification.plant_fit import IdentificationError
from jointctl.identification.safety import Allowance, Envelope, Safety, allow, envelope_for, reference_peaks


@dataclass(frozen=True)
class Chirp:
    """The excitation: ``start`` [rad or m], ``amplitude`` [rad or m], frequencies [Hz], ``duration_s``."""

    start: float
    amplitude: float
    f_start_hz: float
    f_end_hz: float
    duration_s: float

    def __call__(self, t: float) -> float:
        """The position reference at ``t`` [s] from the excitation's start (``start`` outside it)."""
        if not 0.0 < t < self.duration_s:
            return self.start
        T = self.duration_s
        phase = 2 * math.pi * (self.f_start_hz * t + 0.5 * (self.f_end_hz - self.f_start_hz) * t * t / T)
        window = math.sin(math.pi * t / T) ** 2
        return self.start + self.amplitude * window * math.sin(phase)

    @property
    def peak_speed(self) -> float:
        """An upper bound of the reference's speed [per s]."""
        return self.amplitude * (2 * math.pi * max(self.f_start_hz, self.f_end_hz) + math.pi / self.duration_s)


def safe_chirp(start: float, lower: float, upper: float, velocity_limit: float, *, amplitude: float | None = None,
               f_start_hz: float = 0.2, f_end_hz: float = 3.0, duration_s: float = 10.0,
               range_fraction: float = 0.3, speed_fraction: float = 0.5) -> Chirp:
    """The chirp of the module docstring for a joint resting at ``start`` in [``lower``, ``upper``]
    (±inf when it has no range) with ``velocity_limit`` (inf when none). A requested ``amplitude``
    beyond what is safe is refused naming the largest safe one."""
    for name, value in (("f_start_hz", f_start_hz), ("f_end_hz", f_end_hz), ("duration_s", duration_s)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise IdentificationError("must be a positive number", field=name, value=value)
    if not lower <= start <= upper:
        raise IdentificationError(f"the joint rests outside its range [{lower:g}, {upper:g}]", field="start",
                                  value=start)
    room = min(start - lower, upper - start)
    if math.isinf(room):
        room = 1.0  # no range (a continuous joint): one radian each way
    safe = range_fraction * room
    probe = Chirp(start, 1.0, f_start_hz, f_end_hz, duration_s)
    if math.isfinite(velocity_limit):
        safe = min(safe, speed_fraction * velocity_limit / probe.peak_speed)
    if not safe > 0:
        raise IdentificationError("the joint rests at a limit: no room to excite it", field="start", value=start)
    if amplitude is None:
        amplitude = safe
    elif not (isinstance(amplitude, (int, float)) and 0 < amplitude <= safe * (1 + 1e-12)):
        raise IdentificationError(f"must be positive and at most {safe:.4g} (within the range and the speed limit "
                                  "from where the joint rests)", field="amplitude", value=amplitude)
    return Chirp(start, float(amplitude), f_start_hz, f_end_hz, duration_s)


def planned_chirp(envelope: Envelope, model, *, period_s: float, amplitude: float | None = None,
                  f_start_hz: float = 0.2, f_end_hz: float = 3.0, duration_s: float = 10.0,
                  settle_after_s: float = 2.0) -> tuple[Chirp, Allowance]:
    """The chirp of the module docstring from ``envelope.rest``, its amplitude by the rule of
    :mod:`jointctl.identification.safety` on ``model`` (a LoopModel of the joint's position loop
    at ``period_s`` [s], or None: the reference alone, no effort predicted), simulated over the chirp
    and ``settle_after_s`` of rest after it; (chirp, allowance). A requested ``amplitude`` beyond the
    safe one is refused naming the largest safe one and the limit that binds."""
    for name, value in (("f_start_hz", f_start_hz), ("f_end_hz", f_end_hz), ("duration_s", duration_s)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise IdentificationError("must be a positive number", field=name, value=value)
    unit = Chirp(0.0, 1.0, f_start_hz, f_end_hz, duration_s)
    t = np.arange(int(round(duration_s / period_s))) * period_s
    reference = np.array([unit(x) for x in t])
    allowance = allow(reference_peaks(model, reference, period_s, settle_cycles=int(round(settle_after_s / period_s))),
                      envelope)
    if amplitude is None:
        amplitude = allowance.amplitude
    else:
        allowance.refuse_beyond(amplitude, what=f" over {f_start_hz:g}-{f_end_hz:g} Hz")
    return Chirp(envelope.rest, float(amplitude), f_start_hz, f_end_hz, duration_s), allowance


def plan_identification(robot, joint: str, rest: float, *, pose: dict, loop: tuple, period_s: float,
                        gravity_m_s2=(0.0, 0.0, -9.81), safety: Safety | None = None, plant: dict | None = None,
                        amplitude: float | None = None, duration_s: float = 10.0, f_start_hz: float = 0.2,
                        f_end_hz: float = 3.0, settle_after_s: float = 2.0) -> tuple[Chirp, Allowance, str | None]:
    """(chirp, allowance, where the model's plant came from or None) for exciting ``joint`` of ``robot``
    from ``rest`` [m or rad], the others at ``pose`` (joint name -> position), through its position
    loop ``loop`` = (gains ``{"p", "i", "d"}`` or None when unknown, derivative law, whether its p alone
    holds gravity, its effort limit or None for the URDF's) at ``period_s`` [s]; the plant from
    ``plant`` (an identification's metrics) or the robot model under ``gravity_m_s2`` [m/s²]."""
    gains, law, droops, effort_limit = loop
    pose = {**pose, joint: rest}
    model = source = None
    if gains is not None:
        model, source = loop_model(robot, joint, pose, gains, period_s, "position", law, plant)
    envelope = envelope_for(robot, joint, rest, safety, pose=pose, gravity_m_s2=gravity_m_s2,
                            friction=plant_friction(plant), droop_gain=gains["p"] if gains and droops else None,
                            effort_limit=effort_limit)
    chirp, allowance = planned_chirp(envelope, model, period_s=period_s, amplitude=amplitude, f_start_hz=f_start_hz,
                                     f_end_hz=f_end_hz, duration_s=duration_s, settle_after_s=settle_after_s)
    return chirp, allowance, source


__all__ = ["Chirp", "plan_identification", "planned_chirp", "safe_chirp"]

"""When a measured figure is far enough from its theory, or from a user's spec, to say so.

A :class:`Margin` is how far a measured figure may miss what it is compared with before that is
worth a warning: a fraction of the expected value (``relative``) or an amount in the figure's own
unit, each with the reason for its size. The named margins below are jointctl's; an analysis whose
figure is a position states its margin as a share of the motion it predicts (the step, the sag),
with :func:`share_of`. :func:`expectation_warnings` turns a run's measured figures and their
expected values into sentences naming the figure, measured, expected and margin;
:func:`saturation_share` and :func:`saturation_warning` say when a joint's effort sat at its limit,
where no linear theory holds.

Pure Python and numpy; SI units throughout (the unit of a figure is the suffix of its name).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "AMPLITUDE_RATIO_MARGIN",
    "BANDWIDTH_MARGIN",
    "DAMPING_RATIO_MARGIN",
    "DECAY_RATE_MARGIN",
    "DEFAULT_MARGINS",
    "EFFORT_LIMIT_TOLERANCE",
    "Margin",
    "NATURAL_FREQUENCY_MARGIN",
    "OVERSHOOT_MARGIN",
    "PHASE_LAG_MARGIN",
    "REST_MARGIN_OF_MOTION",
    "SETTLING_TIME_MARGIN",
    "STATIC_FORCE_MARGIN",
    "TRACKING_MARGIN",
    "expectation_warnings",
    "margin_for",
    "miss_warning",
    "saturation_share",
    "saturation_warning",
    "share_of",
]


@dataclass(frozen=True)
class Margin:
    """How far a measured figure may miss its expectation or spec before a warning.

    ``value`` is a fraction of ``|expected|`` when ``relative`` (0.05: 5 %), else an amount in the
    figure's own unit; ``reason`` says why that much; ``text`` is how the margin reads in a
    sentence (default: "5 %" or the amount).
    """

    value: float
    relative: bool
    reason: str
    text: str = ""

    def allowed(self, expected: float) -> float:
        """The largest miss [the figure's unit] that is no warning, for an expected value."""
        return self.value * abs(expected) if self.relative else self.value

    def describe(self) -> str:
        """The margin as a sentence says it."""
        if self.text:
            return self.text
        return f"{100 * self.value:g} %" if self.relative else f"{self.value:.3g}"


#: ωn of a position loop. The linearised loop predicts it to well under 1 %: the loop's hold and
#: MuJoCo's implicit damping shift it by about h·b/(4·I) (0.25 % on the 1-DOF robot at 1 kHz), the
#: fit of a damped sinusoid recovers it to 0.1 %; 5 % is a wrong inertia, gravity or coupling.
NATURAL_FREQUENCY_MARGIN = Margin(0.05, True, "the sampled loop and the fit move ωn by under 1 %; more is a "
                                  "wrong inertia, gravity load or coupling")
#: ζ is the figure most sensitive to the loop's delay (the hold of one period lowers it by about
#: ωn·h/4 relative) and to friction the model lacks: twice ωn's margin.
DAMPING_RATIO_MARGIN = Margin(0.10, True, "ζ is the figure most sensitive to the loop's delay and to "
                              "friction the model lacks")
#: A step's overshoot in percentage points of the step: about what a 10 % miss in ζ makes of it at
#: ζ 0.2 to 0.5 (3.5 points at ζ 0.25), read off a single peak sample.
OVERSHOOT_MARGIN = Margin(3.0, False, "what ζ's 10 % margin makes of the overshoot at ζ 0.2-0.5",
                          text="3 points")
#: Gain of a frequency response: near resonance it is 1/(2ζ), so it inherits ζ's margin.
AMPLITUDE_RATIO_MARGIN = Margin(0.10, True, "near resonance the ratio is 1/(2ζ): ζ's margin")
#: Phase lag [deg]: the hold delays the loop by h/2 to h, ω·h rad at most (1.1° at 20 rad/s and
#: 1 kHz); 5° is beyond any sampling effect below ω·h = 0.08 rad.
PHASE_LAG_MARGIN = Margin(5.0, False, "the loop's hold adds at most ω·h rad of lag (1.1° at 20 rad/s, 1 kHz)",
                          text="5°")
#: Efforts and forces at rest follow from masses and gravity alone; 2 % is a load the model lacks
#: (Gazebo's drop-weight test held the equivalent of 7 kg of 11: 36 %).
STATIC_FORCE_MARGIN = Margin(0.02, True, "efforts at rest are masses times gravity; more is a load the model "
                             "lacks")
#: Decay rates [1/s] are ζ·ωn: ζ's margin.
DECAY_RATE_MARGIN = Margin(0.10, True, "a decay rate is ζ·ωn: ζ's margin")
#: Figures from a model run of the same command (tracking lag, RMS error): the model integrates the
#: loop as the loop runs it; 10 % is the model missing the plant, not the integration.
TRACKING_MARGIN = Margin(0.10, True, "the model run integrates the loop as it runs; more is the model "
                         "missing the plant")
#: -3 dB bandwidth of a loop [Hz]: ωn's margin (the bandwidth is ωn times a function of ζ).
BANDWIDTH_MARGIN = Margin(0.05, True, "a bandwidth is ωn times a function of ζ: ωn's margin")
#: A step's 2 % settling time: it jumps by up to half a period as each overshoot peak leaves the
#: band, so it is judged loosely.
SETTLING_TIME_MARGIN = Margin(0.10, True, "the settling time jumps as each overshoot peak leaves the band")
#: Rest positions, as a share of the motion the theory predicts (the step, the sag): the settling
#: band, within which a response counts as arrived.
REST_MARGIN_OF_MOTION = 0.02

#: A figure's margin by the end of its name (the longest matching suffix wins). Position-like
#: figures have none here: their margin depends on the motion (:func:`share_of`).
DEFAULT_MARGINS: dict[str, Margin] = {
    "natural_frequency_rad_s": NATURAL_FREQUENCY_MARGIN,
    "damping_ratio": DAMPING_RATIO_MARGIN,
    "overshoot_pct": OVERSHOOT_MARGIN,
    "amplitude_ratio": AMPLITUDE_RATIO_MARGIN,
    "phase_lag_deg": PHASE_LAG_MARGIN,
    "effort_n": STATIC_FORCE_MARGIN,
    "force_z_n": STATIC_FORCE_MARGIN,
    "decay_rate_1_per_s": DECAY_RATE_MARGIN,
    "bandwidth_hz": BANDWIDTH_MARGIN,
    "settling_time_s": SETTLING_TIME_MARGIN,
    "settling_s": SETTLING_TIME_MARGIN,
    "tracking_lag_s": TRACKING_MARGIN,
    "rms_tracking_error_rad": TRACKING_MARGIN,
}

#: The share of its effort limit at which a joint's effort counts as saturated: a clamped effort
#: is the limit itself, to rounding.
EFFORT_LIMIT_TOLERANCE = 1e-9


def share_of(motion: float, what: str, share: float = REST_MARGIN_OF_MOTION, floor: float = 0.0) -> Margin:
    """An absolute margin of ``share`` of ``|motion|`` (the step, the sag...; ``what`` names it in
    the sentence), at least ``floor`` [the figure's unit]."""
    value = max(share * abs(motion), floor)
    return Margin(value, False, f"{100 * share:g} % of the {what}: the settling band",
                  text=f"{100 * share:g} % of the {what} {abs(motion):.3g}, {value:.3g}")


def margin_for(key: str, margins: Mapping[str, Margin] | None = None) -> Margin | None:
    """``key``'s margin: ``margins[key]``, else the default by the end of its name; None if neither."""
    margins = margins or {}
    if key in margins:
        return margins[key]
    suffix = max((s for s in DEFAULT_MARGINS if key.endswith(s)), key=len, default=None)
    return DEFAULT_MARGINS[suffix] if suffix is not None else None


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _fmt(value) -> str:
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
    return f"{value:.4g}"


def miss_warning(key: str, measured, expected, margin: Margin, against: str = "expected") -> str | None:
    """The sentence saying that ``measured`` misses ``expected`` (numbers, or equal-length lists
    compared by their largest difference) by more than ``margin``; None when it does not, or when
    either is not a finite number (not measured, not applicable). ``against`` names what is
    compared with ("expected", "spec")."""
    if isinstance(measured, (list, tuple)) or isinstance(expected, (list, tuple)):
        if not (isinstance(measured, (list, tuple)) and isinstance(expected, (list, tuple))
                and len(measured) == len(expected) and all(map(_number, [*measured, *expected]))):
            return None
        miss = max(abs(m - e) for m, e in zip(measured, expected))
        allowed = margin.allowed(max(abs(e) for e in expected))
        by = f"{miss:.3g}"
    else:
        if not (_number(measured) and _number(expected)):
            return None
        miss = abs(measured - expected)
        allowed = margin.allowed(expected)
        by = f"{100 * miss / abs(expected):.3g} %" if margin.relative and expected != 0 else f"{miss:.3g}"
    if miss <= allowed:
        return None
    return (f"{key}: measured {_fmt(measured)}, {against} {_fmt(expected)}: off by {by}, "
            f"more than its margin of {margin.describe()} ({margin.reason}).")


def expectation_warnings(measured: Mapping, expected: Mapping, margins: Mapping[str, Margin] | None = None,
                         against: str = "expected") -> list[str]:
    """A sentence for each figure of ``expected`` that ``measured`` misses by more than its margin:
    ``margins[key]``, else :data:`DEFAULT_MARGINS` by the end of the key; figures with neither, or
    not measured, or expected as None (not applicable), are not compared."""
    margins = margins or {}
    found = []
    for key, value in expected.items():
        margin = margin_for(key, margins)
        if margin is None or key not in measured:
            continue
        sentence = miss_warning(key, measured[key], value, margin, against)
        if sentence is not None:
            found.append(sentence)
    return found


def saturation_share(effort: ArrayLike, limit: float) -> float:
    """The share (0..1) of samples of ``effort`` at the effort limit ``limit`` [N or N·m]
    (within :data:`EFFORT_LIMIT_TOLERANCE` of it); 0 for an unlimited joint."""
    e = np.asarray(effort, dtype=float)
    if e.size == 0 or not (math.isfinite(limit) and limit > 0):
        return 0.0
    return float(np.count_nonzero(np.abs(e) >= limit * (1 - EFFORT_LIMIT_TOLERANCE)) / e.size)


def saturation_warning(joint: str, share: float, limit: float, unit: str, where: str = "of the run") -> str | None:
    """The sentence saying ``joint``'s effort sat at its limit for ``share`` of the cycles
    ``where``; None when it never did."""
    if not share > 0:
        return None
    return (f"{joint}: effort at its {limit:g} {unit} limit in {100 * share:.3g} % of the cycles {where}: the "
            "loop was not linear there, and figures from linear theory do not describe it.")

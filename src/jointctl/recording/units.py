"""SI units of a joint's signals and the prefix a figure shows them in.

A prismatic joint moves in m and pushes in N, a revolute (or continuous) one turns in rad and
twists in N·m: :func:`joint_units` gives each signal's unit from the joint type. A figure shows
values in their SI unit when the largest of them lies in [0.1, 1000) (a 0.5 m stroke reads 0.5 m,
not 500 mm) and otherwise with the SI prefix that puts it in [1, 1000): a tracking error of
0.00033 rad reads 330 µrad, 0.004 m reads 4 mm, a 4800 N impact 4.8 kN (:func:`display_scale`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["DisplayScale", "JointUnits", "display_scale", "joint_units", "label"]

#: SI prefixes by power of ten (micro as µ, U+00B5).
PREFIXES = {-15: "f", -12: "p", -9: "n", -6: "µ", -3: "m", 0: "", 3: "k", 6: "M"}
#: Units shown with a prefix above 1 (kN, kN·m); lengths and angles of joints never need one, and
#: "krad" would hide a run gone astray behind a tidy axis.
_GROWING_UNITS = ("N", "N·m", "N/m", "N·m/rad", "W", "J", "Pa")
#: The largest |value| shown without a prefix: [LOWEST, 1000).
LOWEST_PLAIN = 0.1


@dataclass(frozen=True)
class JointUnits:
    """The SI units of one joint's signals: ``position`` (m or rad), ``velocity`` (m/s or rad/s),
    ``acceleration`` (m/s² or rad/s²) and ``effort`` (N or N·m)."""

    position: str
    velocity: str
    acceleration: str
    effort: str


PRISMATIC = JointUnits("m", "m/s", "m/s²", "N")
REVOLUTE = JointUnits("rad", "rad/s", "rad/s²", "N·m")


def joint_units(joint) -> JointUnits:
    """The units of ``joint``'s signals: a :class:`~jointctl.model.robot_model.Joint` (or anything
    with ``is_prismatic``), or a bool saying whether it is prismatic."""
    prismatic = joint if isinstance(joint, bool) else bool(joint.is_prismatic)
    return PRISMATIC if prismatic else REVOLUTE


@dataclass(frozen=True)
class DisplayScale:
    """How a figure shows values of SI unit ``unit``: multiplied by ``factor`` and labelled in
    ``shown`` (``unit`` with its prefix; ``factor`` = 1 and ``shown`` = ``unit`` without one)."""

    unit: str
    factor: float
    shown: str

    def __call__(self, value):
        """``value`` (a number or an array, in ``unit``) in ``shown``."""
        return value * self.factor


def display_scale(unit: str, largest: float) -> DisplayScale:
    """The prefix to show values of ``unit`` whose largest magnitude is ``largest`` (see the module
    docstring); no prefix for a dimensionless or empty unit, several units named together ("m, rad"),
    or a largest value of 0 or not finite."""
    largest = abs(float(largest))
    if not unit or unit in ("-", "%", "s") or "," in unit or not math.isfinite(largest) or largest == 0.0:
        return DisplayScale(unit, 1.0, unit)
    if LOWEST_PLAIN <= largest < 1000.0:
        return DisplayScale(unit, 1.0, unit)
    power = 3 * math.floor(math.log10(largest) / 3)
    if largest * 10.0 ** -power >= 1000.0:  # log10's rounding just below a power of 1000
        power += 3
    top = max(PREFIXES) if unit in _GROWING_UNITS else 0
    power = min(max(power, min(PREFIXES)), top)
    if power == 0:
        return DisplayScale(unit, 1.0, unit)
    return DisplayScale(unit, 10.0 ** -power, PREFIXES[power] + unit)


def label(quantity: str, unit: str) -> str:
    """An axis label ``"quantity [unit]"`` (just ``quantity`` without a unit)."""
    return f"{quantity} [{unit}]" if unit else quantity

"""The one numeric check every input goes through (YAML parameters, scenario fields, page and
ROS requests, commands): a real number, not a bool, finite, and within its bounds.

Callers keep their own error type and message place (``fail`` builds the exception from the
message); the predicate and the messages are the same everywhere.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from typing import Any


def real_number(value: Any) -> float | None:
    """``value`` as a float when it is a real number (not a bool, possibly infinite or NaN);
    None otherwise."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    try:
        return float(value)
    except (OverflowError, TypeError, ValueError):
        return None


def finite_number(value: Any) -> float | None:
    """``value`` as a float when it is a real, finite number (not a bool); None otherwise."""
    number = real_number(value)
    return number if number is not None and math.isfinite(number) else None


def checked_number(value: Any, fail: Callable[[str], Exception], *, positive: bool = False,
                   minimum: float | None = None) -> float:
    """``value`` as a finite float, or ``fail(message)`` raised: "must be a number", "must be
    finite", "must be positive", "must not be negative" / "must be at least ..."."""
    number = real_number(value)
    if number is None:
        raise fail("must be a number")
    if not math.isfinite(number):
        raise fail("must be finite")
    if positive and number <= 0:
        raise fail("must be positive")
    if minimum is not None and number < minimum:
        raise fail("must not be negative" if minimum == 0 else f"must be at least {minimum}")
    return number


__all__ = ["checked_number", "finite_number", "real_number"]

"""Waiting in tests for what another thread or process does: poll until it is so, or fail naming it.

The deadline bounds a broken run; it is not a measurement (a test never asserts how fast something came).
"""

from __future__ import annotations

import time
from collections.abc import Callable


def wait_until(predicate: Callable[[], object], what: str = "the condition", timeout_s: float = 30.0,
               every_s: float = 0.02):
    """Poll ``predicate`` every ``every_s`` [s] until it returns something true, and return that; fail
    saying ``what`` was awaited (and the last value seen) when ``timeout_s`` [s] passes first."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"waited {timeout_s:g} s for {what}; last seen: {value!r}")
        if every_s > 0:
            time.sleep(every_s)


__all__ = ["wait_until"]

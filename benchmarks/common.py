"""Shared helpers of the benchmarks: the result row and the peak memory of a child run."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass


@dataclass(frozen=True)
class Result:
    """One line of the benchmark table. ``target`` is a predicate description, ``ok`` its verdict."""

    benchmark: str
    measure: str
    value: float
    unit: str
    target: str = ""
    ok: bool | None = None


def child_peak_memory_mb(code: str) -> dict:
    """Run ``code`` in a fresh interpreter; it must print a JSON object. Adds ``peak_rss_mb``."""
    wrapper = (
        "import json, resource, sys\n"
        f"{code}\n"
        "result['peak_rss_mb'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024\n"
        "print(json.dumps(result))\n"
    )
    out = subprocess.run([sys.executable, "-c", wrapper], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])

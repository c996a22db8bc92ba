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


def stepping_alone(world, seconds: float) -> float:
    """Real-time factor of MuJoCo stepping ``world``'s model alone for ``seconds`` of simulated time
    (``mj_step(m, d, nstep)``), its controls held at the initial pose's gravity load (one run)."""
    import time

    import mujoco

    m, d = world.model, world.data
    steps = round(seconds / world.timestep_s)
    world.reset()
    mujoco.mj_forward(m, d)
    actuated = world.actuator_ids >= 0
    d.ctrl[world.actuator_ids[actuated]] = d.qfrc_bias[world.dof_adr[actuated]]
    start = time.perf_counter()
    mujoco.mj_step(m, d, steps)
    return seconds / (time.perf_counter() - start)

"""The whole stack on one_dof_step against a bare MuJoCo loop on the same model, and memory.

*Bare loop*: the same compiled MuJoCo model (sensors, floor and all), the P law
written inline, ``mj_step`` per millisecond: the fastest a Python loop can go.
*Whole stack*: ``Session`` for the built-in one_dof_step scenario: command
source, hardware read/write, controller manager, PID, joint state controller
and the trace recorder writing every cycle.
"""

from __future__ import annotations

import statistics
import tempfile
import time

import mujoco

from benchmarks.common import Result, child_peak_memory_mb
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario

SIM_SECONDS = 10.0


REPEATS = 5


def bare_loop(world) -> float:
    """Real-time factor of the bare loop on ``world``'s compiled model (one run)."""
    m, d = world.model, world.data
    qpos, ctrl = d.qpos, d.ctrl
    steps = round(SIM_SECONDS / world.timestep_s)
    world.reset()
    start = time.perf_counter()
    for _ in range(steps):
        ctrl[0] = 400.0 * (-0.5 - qpos[0])
        mujoco.mj_step(m, d)
    return SIM_SECONDS / (time.perf_counter() - start)


def whole_stack(scenario) -> tuple[float, float]:
    """(loop real-time factor, end-to-end real-time factor) of one run.

    The loop figure times ``loop.run`` with the recorder spooling every cycle to
    disk; end to end adds building the session (xacro, MuJoCo compile) and
    writing trace.csv after the run.
    """
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        session = Session(scenario, out_dir=out)
        loop_start = time.perf_counter()
        session.loop.run(SIM_SECONDS)
        loop_end = time.perf_counter()
        session.close()
        end = time.perf_counter()
    return SIM_SECONDS / (loop_end - loop_start), SIM_SECONDS / (end - start)


def speeds() -> tuple[float, float, float]:
    """Medians of bare, stack and end-to-end real-time factors, runs interleaved so that
    a busy moment of a shared machine slows both sides alike."""
    scenario = load_scenario("one_dof_step", [f"duration_s={SIM_SECONDS}"])
    world = Session(scenario).world
    bare, stack, total = [], [], []
    for _ in range(REPEATS):
        bare.append(bare_loop(world))
        loop_rtf, end_to_end = whole_stack(scenario)
        stack.append(loop_rtf)
        total.append(end_to_end)
    return statistics.median(bare), statistics.median(stack), statistics.median(total)


_MEMORY_RUN = """
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
import tempfile, os
with tempfile.TemporaryDirectory() as out:
    with Session(load_scenario("one_dof_step", ["duration_s={seconds}"]), out_dir=out) as s:
        s.run()
    size = os.path.getsize(os.path.join(out, "trace.csv"))
result = {{"trace_mb": size / 2**20}}
"""


def run() -> list[Result]:
    bare, stack, end_to_end = speeds()
    short = child_peak_memory_mb(_MEMORY_RUN.format(seconds=10))
    hour = child_peak_memory_mb(_MEMORY_RUN.format(seconds=3600))
    growth = hour["peak_rss_mb"] - short["peak_rss_mb"]
    name = "one_dof_step"
    return [
        Result(name, "bare MuJoCo loop, real-time factor", bare, "x"),
        Result(name, "whole stack, real-time factor", stack, "x", ">= 150", stack >= 150),
        Result(name, "whole stack / bare loop", stack / bare, "ratio", ">= 0.5", stack / bare >= 0.5),
        Result(name, "end to end (build, run, write trace.csv)", end_to_end, "x"),
        Result(name, "peak memory, 10 s run", short["peak_rss_mb"], "MB"),
        Result(name, f"peak memory, 1 h run ({hour['trace_mb']:.0f} MB trace)", hour["peak_rss_mb"], "MB"),
        Result(name, "peak memory growth 10 s -> 1 h", growth, "MB", "<= 50", growth <= 50),
    ]

"""The whole stack on one_dof_step against MuJoCo stepping alone and a bare MuJoCo loop on the same model, and memory.

*MuJoCo stepping alone*: the same compiled model (sensors, floor and all) stepped by
``mj_step(m, d, nstep=N)`` in one call, its controls held at the gravity load of the
scenario's initial pose: the physics' own speed, the limit of any loop.
*Bare loop*: the same model, the P law written inline, ``mj_step`` per millisecond: the
fastest a Python loop can go.
*Whole stack*: ``Session`` for the built-in one_dof_step scenario: command
source, hardware read/write, controller manager, PID, joint state controller
and the trace recorder writing every cycle; on the compiled cycle (``loop: auto``, the
default) and on the Python loop (``loop: python``).
"""

from __future__ import annotations

import statistics
import tempfile
import time

import mujoco

from benchmarks.common import Result, stepping_alone, child_peak_memory_mb
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


def speeds() -> dict[str, float]:
    """Medians of the real-time factors (stepping alone, bare loop, compiled stack and its end to end, Python
    stack), runs interleaved so that a busy moment of a shared machine slows every side alike."""
    scenario = load_scenario("one_dof_step", [f"duration_s={SIM_SECONDS}"])
    python = load_scenario("one_dof_step", [f"duration_s={SIM_SECONDS}", "loop=python"])
    warm = Session(scenario)
    warm.run(0.01)  # the compiled kernels loaded (from their cache) before anything is timed
    world = warm.world
    runs: dict[str, list[float]] = {k: [] for k in ("alone", "bare", "stack", "end_to_end", "python")}
    for _ in range(REPEATS):
        runs["alone"].append(stepping_alone(world, SIM_SECONDS))
        runs["bare"].append(bare_loop(world))
        loop_rtf, end_to_end = whole_stack(scenario)
        runs["stack"].append(loop_rtf)
        runs["end_to_end"].append(end_to_end)
        runs["python"].append(whole_stack(python)[0])
    return {k: statistics.median(v) for k, v in runs.items()}


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
    rtf = speeds()
    alone, bare, stack, end_to_end, python = (rtf[k] for k in ("alone", "bare", "stack", "end_to_end", "python"))
    short = child_peak_memory_mb(_MEMORY_RUN.format(seconds=10))
    hour = child_peak_memory_mb(_MEMORY_RUN.format(seconds=3600))
    growth = hour["peak_rss_mb"] - short["peak_rss_mb"]
    name = "one_dof_step"
    return [
        Result(name, "MuJoCo stepping alone (mj_step nstep), real-time factor", alone, "x"),
        Result(name, "bare Python MuJoCo loop, real-time factor", bare, "x"),
        Result(name, "whole stack (compiled cycle), real-time factor", stack, "x", ">= 150", stack >= 150),
        Result(name, "whole stack (compiled) / stepping alone", stack / alone, "ratio", ">= 0.8", stack / alone >= 0.8),
        Result(name, "whole stack (compiled) / bare loop", stack / bare, "ratio", ">= 0.5", stack / bare >= 0.5),
        Result(name, "whole stack (Python loop) / stepping alone", python / alone, "ratio"),
        Result(name, "end to end (build, run, write trace.csv)", end_to_end, "x"),
        Result(name, "peak memory, 10 s run", short["peak_rss_mb"], "MB"),
        Result(name, f"peak memory, 1 h run ({hour['trace_mb']:.0f} MB trace)", hour["peak_rss_mb"], "MB"),
        Result(name, "peak memory growth 10 s -> 1 h", growth, "MB", "<= 50", growth <= 50),
    ]

"""The drop-weight scenario (contact active) against a bare MuJoCo loop with the same contact.

*Bare loop*: the scenario's compiled world with the weight spawned at the same time, the
P law inline, ``mj_step`` per millisecond. *Whole stack*: ``Session`` of one_dof_drop_weight
with its recorder. Runs are interleaved so a busy moment slows both alike.
"""

from __future__ import annotations

import statistics
import tempfile
import time

import mujoco

from benchmarks.common import Result
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario

REPEATS = 5


def bare_loop(scenario) -> float:
    world = Session(scenario).world
    weight = scenario.objects[0]
    steps = round(scenario.duration_s / world.timestep_s)
    spawn_step = round(weight.spawn_at_s / world.timestep_s)
    start = time.perf_counter()
    for k in range(steps):
        if k == spawn_step:
            world.spawn(weight)
        m, d = world.model, world.data
        d.ctrl[0] = 400.0 * (-0.2 - d.qpos[0])
        mujoco.mj_step(m, d)
    return scenario.duration_s / (time.perf_counter() - start)


def whole_stack(scenario) -> float:
    with tempfile.TemporaryDirectory() as out, Session(scenario, out_dir=out) as session:
        start = time.perf_counter()
        session.loop.run(scenario.duration_s)
        return scenario.duration_s / (time.perf_counter() - start)


def run() -> list[Result]:
    scenario = load_scenario("one_dof_drop_weight")
    bare, stack = [], []
    for _ in range(REPEATS):
        bare.append(bare_loop(scenario))
        stack.append(whole_stack(scenario))
    bare_rtf, stack_rtf = statistics.median(bare), statistics.median(stack)
    name = "one_dof_drop_weight"
    return [
        Result(name, "bare MuJoCo loop with the contact, real-time factor", bare_rtf, "x"),
        Result(name, "whole stack, real-time factor", stack_rtf, "x"),
        Result(name, "whole stack / bare loop", stack_rtf / bare_rtf, "ratio"),
    ]

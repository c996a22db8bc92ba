"""The 7-DOF arm at 1 kHz: a trajectory with seven position controllers, and the Cartesian NAC.

*Bare loop*: the arm's compiled MuJoCo model, a PD law for the seven joints inline in numpy,
``mj_step`` per millisecond. *Whole stack*: the arm7dof_streamer scenario executing the move to
the pre-pose: trajectory executor, model feed-forward (gravity, damping, inertia), seven PID
position controllers; on the compiled cycle (``loop: auto``) and on the Python loop, without and with
the trace recorder. *Cartesian NAC*: the whole
arm7dof_nac_catch scenario (32 s: the admittance controller chained in front of seven velocity
loops, the weight dropped at 10 s and held), without the recorder; and the controller's own
update at the run's final state (the cost it adds to every cycle). Runs interleaved.

*Cartesian NAC against MuJoCo stepping alone* (:func:`nac_speeds`): arm7dof_nac_catch's first 3 s
(the tare, the flange pulled to the attractor) with the trace recorder, on the compiled cycle and on
the Python loop, against the same arm model stepped by ``mj_step(m, d, nstep=N)`` in one call, its
controls held at the gravity load of the pre-pose; medians of interleaved runs.
"""

from __future__ import annotations

import statistics
import tempfile
import time

import mujoco
import numpy as np

from benchmarks.common import Result, stepping_alone
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario

SECONDS = 10.0
REPEATS = 3
PRE_POSE = [[0, 1, 0, -2, 0, 1, 0]]
NAC_CONTROLLER = "arm7dof_nac_controller"
UPDATE_CALLS = 20_000


def bare_loop(scenario) -> float:
    world = Session(scenario).world
    m, d = world.model, world.data
    qpos, qvel, ctrl = d.qpos[:7], d.qvel[:7], d.ctrl
    target = np.array(PRE_POSE[0], dtype=float)
    kp, kd = np.array([500, 500, 500, 500, 30, 30, 20.0]), np.array([50, 50, 50, 50, 2, 2, 1.0])
    steps = round(SECONDS / world.timestep_s)
    start = time.perf_counter()
    for _ in range(steps):
        ctrl[:] = kp * (target - qpos) - kd * qvel
        mujoco.mj_step(m, d)
    return SECONDS / (time.perf_counter() - start)


def whole_stack(scenario, record: bool) -> float:
    with tempfile.TemporaryDirectory() as out:
        session = Session(scenario, out_dir=out if record else None)
        executor = session.manager.controller("arm7dof_trajectory_controller")
        executor.submit(executor.plan_path(PRE_POSE, timing="chapter"), now_s=0.0)
        start = time.perf_counter()
        session.loop.run(SECONDS)
        rtf = SECONDS / (time.perf_counter() - start)
        assert session.loop.mode == ("python" if scenario.loop == "python" else "compiled"), session.loop.mode_reason
        session.close()
    return rtf


def cartesian_nac(scenario) -> tuple[float, float]:
    """Real-time factor of the whole NAC scenario, and the controller's update [µs] at its end."""
    session = Session(scenario)
    start = time.perf_counter()
    session.loop.run(scenario.duration_s)
    rtf = scenario.duration_s / (time.perf_counter() - start)
    nac, now, period = session.manager.controller(NAC_CONTROLLER), session.loop.time_s, session.loop.period_s
    start = time.perf_counter()
    for _ in range(UPDATE_CALLS):
        nac.update(now, period)  # the same state every call: the cost, not the dynamics
    update_us = (time.perf_counter() - start) / UPDATE_CALLS * 1e6
    session.close()
    return rtf, update_us


NAC_SECONDS = 3.0
NAC_REPEATS = 5


def nac_stack(scenario) -> tuple[float, str]:
    """Real-time factor of ``loop.run`` over the whole scenario, the recorder writing every cycle, and the loop's
    mode (one run)."""
    with tempfile.TemporaryDirectory() as out:
        with Session(scenario, out_dir=out) as session:
            start = time.perf_counter()
            session.loop.run(scenario.duration_s)
            rtf = scenario.duration_s / (time.perf_counter() - start)
            mode = session.loop.mode
    return rtf, mode


def nac_speeds() -> dict[str, float]:
    """Medians of the real-time factors of arm7dof_nac_catch's first ``NAC_SECONDS`` on the compiled cycle and on
    the Python loop, and of MuJoCo stepping the same arm alone; runs interleaved."""
    compiled = load_scenario("arm7dof_nac_catch", [f"duration_s={NAC_SECONDS}"])
    python = load_scenario("arm7dof_nac_catch", [f"duration_s={NAC_SECONDS}", "loop=python"])
    warm = Session(compiled)
    warm.run(0.01)  # the compiled kernels loaded (from their cache) before anything is timed
    assert warm.loop.mode == "compiled", warm.loop.mode_reason
    runs: dict[str, list[float]] = {k: [] for k in ("alone", "compiled", "python")}
    for _ in range(NAC_REPEATS):
        runs["alone"].append(stepping_alone(warm.world, NAC_SECONDS))
        rtf, mode = nac_stack(compiled)
        assert mode == "compiled"
        runs["compiled"].append(rtf)
        runs["python"].append(nac_stack(python)[0])
    return {k: statistics.median(v) for k, v in runs.items()}


def nac_results() -> list[Result]:
    rtf = nac_speeds()
    alone, compiled, python = rtf["alone"], rtf["compiled"], rtf["python"]
    name = "arm7dof Cartesian NAC, first 3 s"
    return [
        Result(name, "MuJoCo stepping the arm alone (mj_step nstep), real-time factor", alone, "x"),
        Result(name, "whole stack (compiled cycle), real-time factor", compiled, "x"),
        Result(name, "whole stack (compiled) / stepping alone", compiled / alone, "ratio", ">= 0.5",
               compiled / alone >= 0.5),
        Result(name, "whole stack (Python loop) / stepping alone", python / alone, "ratio"),
    ]


def run() -> list[Result]:
    scenario = load_scenario("arm7dof_streamer", ["record.every=1"])
    python = load_scenario("arm7dof_streamer", ["record.every=1", "loop=python"])
    nac_scenario = load_scenario("arm7dof_nac_catch", [])
    Session(scenario).loop.run(cycles=1)  # the compiled kernels loaded (from their cache) before anything is timed
    bare, stack, recorded, stack_py, recorded_py, nac, nac_update = [], [], [], [], [], [], []
    for _ in range(REPEATS):
        bare.append(bare_loop(scenario))
        stack.append(whole_stack(scenario, record=False))
        recorded.append(whole_stack(scenario, record=True))
        stack_py.append(whole_stack(python, record=False))
        recorded_py.append(whole_stack(python, record=True))
        rtf, update_us = cartesian_nac(nac_scenario)
        nac.append(rtf)
        nac_update.append(update_us)
    bare_rtf, stack_rtf, rec_rtf, py_rtf, py_rec_rtf, nac_rtf, nac_us = map(
        statistics.median, (bare, stack, recorded, stack_py, recorded_py, nac, nac_update))
    name = "arm7dof trajectory"
    return [
        Result(name, "bare MuJoCo arm loop (PD inline), real-time factor", bare_rtf, "x"),
        Result(name, "whole stack (compiled cycle), real-time factor", stack_rtf, "x", ">= 50", stack_rtf >= 50),
        Result(name, "whole stack (compiled) / bare loop", stack_rtf / bare_rtf, "ratio"),
        Result(name, "whole stack (compiled) recording every cycle, real-time factor", rec_rtf, "x"),
        Result(name, "whole stack (Python loop), real-time factor", py_rtf, "x"),
        Result(name, "whole stack (Python loop) recording every cycle, real-time factor", py_rec_rtf, "x"),
        Result(name, "whole stack, compiled / Python", stack_rtf / py_rtf, "ratio"),
        Result("arm7dof Cartesian NAC", "arm7dof_nac_catch (32 s, catch included), real-time factor", nac_rtf, "x",
               ">= 50", nac_rtf >= 50),
        Result("arm7dof Cartesian NAC", "arm7dof_nac_catch / bare arm loop", nac_rtf / bare_rtf, "ratio"),
        Result("arm7dof Cartesian NAC", "CartesianAdmittanceController.update, per cycle", nac_us, "µs"),
        *nac_results(),
    ]

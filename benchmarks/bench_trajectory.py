"""Trajectory sampling speed and the executor's cost per control cycle.

*Sampling*: a 7-joint, 1000-point cubic trajectory sampled at 100 000 times in one
vectorised call, against one call per time (what a naive per-cycle evaluation costs).
*Executor*: ``TrajectoryExecutor.update`` for seven joints (on a generated robot of
seven slides), timed on its own while a goal runs, as a fraction of a 1 ms period and
against one ``mj_step`` of the same robot measured in the same run.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
import yaml

from benchmarks.common import Result
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from jointctl.trajectory.interpolation import build_interpolant
from jointctl.trajectory.messages import JointTrajectory

JOINTS = 7
POINTS = 1000


def seven_slides_urdf() -> str:
    links = ['<link name="world"/>', '<link name="base"><inertial><mass value="5"/>'
             '<inertia ixx="1" iyy="1" izz="1"/></inertial></link>',
             '<joint name="fix" type="fixed"><parent link="world"/><child link="base"/></joint>']
    for k in range(JOINTS):
        links.append(f'<link name="l{k}"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" '
                     f'izz="0.01"/></inertial></link>')
        links.append(f'<joint name="j{k}" type="prismatic"><parent link="base"/><child link="l{k}"/>'
                     f'<origin xyz="{k * 0.3} 0 1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" '
                     f'effort="1000" velocity="10"/><dynamics damping="10"/></joint>')
        links.append(f'<transmission name="t{k}"><type>transmission_interface/SimpleTransmission</type>'
                     f'<joint name="j{k}"><hardwareInterface>EffortJointInterface</hardwareInterface>'
                     f'</joint></transmission>')
    return '<robot name="slides">' + "".join(links) + "</robot>"


def controllers_yaml() -> dict:
    body = {f"j{k}_position_controller": {"type": "effort_controllers/JointPositionController",
                                          "joint": f"j{k}", "pid": {"p": 400.0, "d": 20.0},
                                          "feedforward": {"gravity": True, "damping": True, "inertia": True}}
            for k in range(JOINTS)}
    body["trajectory_controller"] = {"type": "trajectory_controllers/JointTrajectoryExecutor",
                                     "joints": [f"j{k}" for k in range(JOINTS)],
                                     "position_controllers": [f"j{k}_position_controller" for k in range(JOINTS)]}
    return {"slides": body}


def random_trajectory(rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    times = np.cumsum(rng.uniform(0.01, 0.05, POINTS))
    positions = np.clip(np.cumsum(rng.uniform(-0.01, 0.01, (POINTS, JOINTS)), axis=0), -0.9, 0.9)
    velocities = np.gradient(positions, times, axis=0)
    return times, positions, velocities


def sampling(rng) -> tuple[float, float]:
    times, positions, velocities = random_trajectory(rng)
    interp = build_interpolant(times, positions, velocities, kind="cubic")
    query = np.linspace(times[0], times[-1], 100_000)
    start = time.perf_counter()
    interp.sample(query)
    vectorised = len(query) / (time.perf_counter() - start)
    start = time.perf_counter()
    for t in query[:5_000]:
        interp.sample(float(t))
    scalar = 5_000 / (time.perf_counter() - start)
    return vectorised, scalar


def executor_cost(rng) -> tuple[float, float]:
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        (folder / "slides.urdf").write_text(seven_slides_urdf())
        (folder / "controllers.yaml").write_text(yaml.safe_dump(controllers_yaml()))
        (folder / "scenario.yaml").write_text(yaml.safe_dump({
            "robot": "slides.urdf", "controller_file": "controllers.yaml", "duration_s": 30.0,
            "start_controllers": [f"j{k}_position_controller" for k in range(JOINTS)] + ["trajectory_controller"],
        }))
        session = Session(load_scenario(folder / "scenario.yaml"))
    executor = session.manager.controller("trajectory_controller")
    times, positions, velocities = random_trajectory(rng)
    positions = positions - positions[0]  # start where the robot is (at 0)
    executor.submit(JointTrajectory.from_arrays([f"j{k}" for k in range(JOINTS)], times + 0.1, positions,
                                                velocities), now_s=0.0)
    session.loop.run(cycles=10)
    hw, world = session.hardware, session.world
    cycles = 5_000
    spent = 0.0
    for k in range(10, 10 + cycles):
        t = k * 0.001
        hw.read()
        start = time.perf_counter()
        executor.update(t, 0.001)
        spent += time.perf_counter() - start
        for c in session.manager.update_calls[1:]:
            c(t, 0.001)
        hw.write()
        hw.advance(0.001)
    per_cycle = spent / cycles
    m, d = world.model, world.data
    start = time.perf_counter()
    for _ in range(cycles):
        mujoco.mj_step(m, d)
    step = (time.perf_counter() - start) / cycles
    return per_cycle, step


def run() -> list[Result]:
    rng = np.random.default_rng(0)
    vectorised, scalar = sampling(rng)
    per_cycle, step = executor_cost(rng)
    name = "trajectory (7 joints)"
    return [
        Result(name, f"vectorised sampling, {POINTS}-point cubic", vectorised, "samples/s"),
        Result(name, "one call per sample", scalar, "samples/s"),
        Result(name, "vectorised / per-call sampling", vectorised / scalar, "ratio"),
        Result(name, "executor cost per cycle", per_cycle * 1e6, "us"),
        Result(name, "executor cost / 1 ms period", per_cycle / 1e-3, "fraction", "<= 0.05",
               per_cycle / 1e-3 <= 0.05),
        Result(name, "executor cost / mj_step of the same robot", per_cycle / step, "ratio"),
    ]

"""One run of a sweep, in this process: :func:`evaluate` turns a :class:`RunTask` into its :class:`Row`.

A run is an ordinary scenario run (the same :class:`~jointctl.scenario.session.Session`, loop and analysis as
``jointctl run``) with the task's values set as ``--set`` items: every field a sweep varies is the scenario's
(``model.*``, ``payload_kg``, ``latency_cycles`` and ``noise.*`` too, which the session applies to the simulated
robot only). The analysis draws no figures (a sweep keeps the numbers) and reads the trace from memory, at full
precision (no ``trace.csv`` is written); the row keeps the analysed joint's position and reference, decimated,
for the overlay figure, and which loop ran it (``loop``: ``compiled`` or ``python``).

*Built worlds kept.* Building a session parses the robot's description (xacro, URDF) and compiles its MuJoCo
model; on the 1-DOF robot that costs as much as its 3 s of compiled loop. The runs of one sweep (the tasks
sharing a ``reuse`` key) keep, in the process that runs them (:data:`WORLDS`, a Dask worker's or this one's),
the robot's model and the simulated world of each :func:`~jointctl.scenario.session.world_key` (the robot's
files, its ``model.*`` changes and payload, the physics step, gravity, the floor): a run whose world was built
for an earlier one restarts it (MuJoCo's ``mj_resetData``, its initial positions) and builds every other part
anew (hardware, controllers, command sources, loop, recorder), so it starts from the state a new build gives and
its row is the same, to the last digit. A world whose model changed in its run (an object spawned) is not kept.
The keys include the sweep's own ``reuse`` key: a file edited between two sweeps is read again.

Whatever goes wrong in a run (bad values, a controller that failed, unstable physics, a refused goal, an
analysis that cannot read the response, any exception) becomes the row's ``error``, never an exception.
"""

from __future__ import annotations

import math
import tempfile
import threading
import time
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from jointctl.errors import JointCtlError
from jointctl.model.loader import load_robot_model
from jointctl.model.robot_model import RobotModel
from jointctl.recording.figures import not_drawn
from jointctl.scenario.analyses import check_analysis
from jointctl.scenario.session import Session, world_key
from jointctl.sim.world import MujocoWorld
from jointctl.scenario.spec import Scenario
from jointctl.scenario.targets import resolve_target
from jointctl.sweep.variations import noise_seed, yaml_text

#: How long a robot given as the target (not a scenario) is held [s], as ``jointctl run`` does.
ROBOT_RUN_S = 5.0
#: Metrics of a run's analysis that are not measured figures of the run: the theory (``expected``, ``plant``: a
#: model's figures) and the run's wall-clock speed (which would make the table depend on the machine).
NOT_ROW_METRICS = ("expected", "plant", "scenario", "real_time_factor", "video")
#: Samples kept of the analysed joint's response (for the overlay figure).
TRACE_POINTS = 400
#: Simulated worlds (and robot models) a process keeps for the runs that follow, the most recently used.
KEPT_WORLDS = 8


@dataclass(frozen=True)
class RunTask:
    """Everything one run needs, small and picklable (it travels to a worker): the target (a scenario or a
    robot, as :func:`~jointctl.scenario.targets.resolve_target` reads it), its controller file, ``--set``
    items applied to every run, this run's ``values`` (field -> value), the sweep's ``seed``; ``reuse`` the
    sweep's key for the worlds its runs share (:data:`WORLDS`; None: the run builds its own)."""

    index: int
    target: str
    values: Mapping[str, Any]
    seed: int = 0
    controllers: str | None = None
    overrides: tuple[str, ...] = ()
    package_path: tuple[str, ...] = ()
    trace_points: int = TRACE_POINTS
    reuse: str | None = None


@dataclass
class Row:
    """One run's result: its ``values``, its analysis's ``metrics`` (numbers or flags, None for not measured), or the
    ``error`` that ended it (``"PhysicsError: ..."``); ``trace`` the analysed joint's decimated response
    (``joint``, ``time_s`` [s], ``position`` and ``reference`` [m or rad]); ``run_s`` the run's own wall-clock
    time in its worker [s]; ``passed`` the verdict of the sweep's spec (None without one, or on error); ``worker``
    the address of the Dask worker that ran it (None in this process; not part of the table); ``loop`` the loop
    that ran it, ``compiled`` or ``python`` (``loop_reason`` why python; None when it did not run)."""

    index: int
    values: dict[str, Any]
    metrics: dict[str, float | bool | None] = field(default_factory=dict)
    error: str | None = None
    trace: dict[str, Any] | None = None
    run_s: float = 0.0
    passed: bool | None = None
    worker: str | None = None
    loop: str | None = None
    loop_reason: str | None = None


class BuiltWorlds:
    """The robot models and simulated worlds one process keeps between the runs of a sweep (see the module
    docstring), at most ``size`` of each, the least recently used dropped first. A world is taken out while its
    run uses it (two threads of one worker never share one) and kept again after. ``built`` and ``reused`` count
    the worlds built and restarted."""

    def __init__(self, size: int = KEPT_WORLDS) -> None:
        self.size = size
        self._robots: OrderedDict[tuple, RobotModel] = OrderedDict()
        self._worlds: OrderedDict[tuple, MujocoWorld] = OrderedDict()
        self._lock = threading.Lock()
        self.built = 0
        self.reused = 0

    def take(self, task: RunTask, scenario: Scenario) -> tuple[RobotModel, MujocoWorld | None, tuple]:
        """The robot model of ``scenario`` (loaded once per sweep) and a world kept for its key (None: the session
        builds one), and the key to keep it under after the run."""
        robot_key = (task.reuse, task.package_path, str(scenario.robot.description))
        key = (task.reuse, task.package_path, *world_key(scenario))
        with self._lock:
            robot = self._robots.get(robot_key)
            world = self._worlds.pop(key, None)
            if robot is not None:
                self._robots.move_to_end(robot_key)
        if robot is None:
            robot = load_robot_model(scenario.robot.description, search_path=task.package_path)
            self._keep(self._robots, robot_key, robot)
        if world is not None and world.robot is not robot and not scenario.changes_robot:
            world = None  # built of another load of the robot's files (not the model the controllers get)
        if world is None:
            self.built += 1
        else:
            self.reused += 1
        return robot, world, key

    def keep(self, key: tuple, world: MujocoWorld | None) -> None:
        """Keep ``world`` for the next run of ``key``, unless its model changed in its run."""
        if world is not None and world.is_as_built():
            self._keep(self._worlds, key, world)

    def _keep(self, kept: OrderedDict, key: tuple, value) -> None:
        with self._lock:
            kept[key] = value
            kept.move_to_end(key)
            while len(kept) > self.size:
                kept.popitem(last=False)

    def clear(self) -> None:
        """Drop every robot model and world kept."""
        with self._lock:
            self._robots.clear()
            self._worlds.clear()


#: This process's kept worlds (each Dask worker process has its own).
WORLDS = BuiltWorlds()


def task_overrides(task: RunTask) -> list[str]:
    """The task's ``--set`` items: the seed of the run's sensor noise (from the sweep's seed and the run's index,
    unless the sweep's own items or values set one), the sweep's own items, then the run's values (every one a
    scenario field, the simulated robot's too)."""
    seed = ", ".join(str(part) for part in noise_seed(task.seed, task.index))
    values = [f"{name}={yaml_text(value)}" for name, value in task.values.items()]
    return [f"noise.seed=[{seed}]", *task.overrides, *values]


def task_scenario(task: RunTask) -> Scenario:
    """The scenario of ``task``: its target with the task's values set (ConfigError naming the field and value)."""
    return resolve_target(task.target, controllers=task.controllers, overrides=task_overrides(task),
                          robot_defaults=[f"duration_s={ROBOT_RUN_S}"]).scenario


def build_session(task: RunTask, out_dir: str | Path | None) -> Session:
    """The task's session, built and checked, not run (its trace goes to ``out_dir``; None: not recorded)."""
    return Session(task_scenario(task), out_dir=out_dir, package_path=task.package_path)


def evaluate(task: RunTask) -> Row:
    """Run ``task`` in this process and return its row; a failure is the row's ``error``, never raised."""
    start = time.perf_counter()
    row = Row(task.index, dict(task.values))
    try:
        row.metrics, row.trace = _run(task, row)
    except JointCtlError as exc:
        row.error = describe(exc)
    except Exception as exc:  # noqa: BLE001  (a sweep names every failure in its row and carries on)
        row.error = describe(exc)
    row.run_s = time.perf_counter() - start
    return row


def describe(exc: BaseException) -> str:
    """``"PhysicsError: ..."``: the failure's kind and its one line."""
    text = " ".join(str(exc).split()) or repr(exc)
    return f"{type(exc).__name__}: {text}"


def _run(task: RunTask, row: Row) -> tuple[dict[str, float | bool | None], dict[str, Any]]:
    scenario = task_scenario(task)
    robot, world, key = WORLDS.take(task, scenario) if task.reuse is not None else (None, None, None)
    session = None
    with tempfile.TemporaryDirectory(prefix="jointctl-run-") as tmp, not_drawn():
        out = Path(tmp)  # for what an analysis writes besides the trace (the runs of its variants)
        try:
            session = Session(scenario, package_path=task.package_path, robot=robot, world=world, keep_trace=True)
            with session:
                analysis = check_analysis(session)
                session.run()
        finally:
            if key is not None:
                WORLDS.keep(key, session.world if session is not None else world)
        row.loop, row.loop_reason = session.loop.mode, session.loop.mode_reason
        session.manager.raise_failures()
        if session.rejected_goals:
            raise session.rejected_goals[0][1]
        trace = session.trace()
        metrics: dict[str, Any] = {}
        if analysis is not None:
            metrics = analysis(session, trace, out, session.scenario.analysis)
        return numbers(metrics), key_trace(session, trace, task.trace_points)


def numbers(metrics: Mapping[str, Any], prefix: str = "") -> dict[str, float | bool | None]:
    """The analysis's figures flattened (``a.b``), numbers and flags only (a flag such as ``moving_at_step``
    stays a bool): non-finite numbers None, strings, lists and :data:`NOT_ROW_METRICS` left out."""
    flat: dict[str, float | bool | None] = {}
    for key, value in metrics.items():
        name = f"{prefix}{key}"
        if not prefix and key in NOT_ROW_METRICS:
            continue
        if isinstance(value, Mapping):
            flat.update(numbers(value, f"{name}."))
        elif value is None:
            flat[name] = None
        elif isinstance(value, (bool, np.bool_)):
            flat[name] = bool(value)
        elif isinstance(value, (int, float, np.number)) and not isinstance(value, bool):
            number = float(value)
            flat[name] = number if math.isfinite(number) else None
    return flat


def key_trace(session: Session, trace, points: int) -> dict[str, Any] | None:
    """The analysed joint's (else the first joint's) position and reference against time, at most ``points``
    samples (every k-th)."""
    joints = session.hardware.joint_names
    if not joints or points < 2:
        return None
    named = (session.scenario.analysis or {}).get("joint")
    joint = named if named in joints else joints[0]
    every = max(1, math.ceil(len(trace.time_s) / points))
    return {"joint": joint, "time_s": trace.time_s[::every].copy(),
            "position": trace.joint(joint, "position")[::every].copy(),
            "reference": trace.joint(joint, "reference")[::every].copy()}


__all__ = ["KEPT_WORLDS", "NOT_ROW_METRICS", "ROBOT_RUN_S", "WORLDS", "BuiltWorlds", "Row", "RunTask", "build_session",
           "describe", "evaluate", "key_trace", "numbers", "task_overrides", "task_scenario"]

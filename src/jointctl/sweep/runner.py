"""One run of a sweep, in this process: :func:`evaluate` turns a :class:`RunTask` into its :class:`Row`.

A run is an ordinary scenario run (the same :class:`~jointctl.scenario.session.Session`, loop and analysis as
``jointctl run``) with the task's values set as ``--set`` items: every field a sweep varies is the scenario's
(``model.*``, ``payload_kg``, ``latency_cycles`` and ``noise.*`` too, which the session applies to the simulated
robot only). The analysis draws no figures (a sweep keeps the numbers) and the trace goes to a temporary folder;
the row keeps the analysed joint's position and reference, decimated, for the overlay figure.

Whatever goes wrong in a run (bad values, a controller that failed, unstable physics, a refused goal, an
analysis that cannot read the response, any exception) becomes the row's ``error``, never an exception.
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from jointctl.errors import JointCtlError
from jointctl.recording.figures import not_drawn
from jointctl.recording.trace import load_trace
from jointctl.scenario.analyses import check_analysis
from jointctl.scenario.session import Session
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


@dataclass(frozen=True)
class RunTask:
    """Everything one run needs, small and picklable (it travels to a worker): the target (a scenario or a
    robot, as :func:`~jointctl.scenario.targets.resolve_target` reads it), its controller file, ``--set``
    items applied to every run, this run's ``values`` (field -> value), the sweep's ``seed``."""

    index: int
    target: str
    values: Mapping[str, Any]
    seed: int = 0
    controllers: str | None = None
    overrides: tuple[str, ...] = ()
    package_path: tuple[str, ...] = ()
    trace_points: int = TRACE_POINTS


@dataclass
class Row:
    """One run's result: its ``values``, its analysis's ``metrics`` (numbers or flags, None for not measured), or the
    ``error`` that ended it (``"PhysicsError: ..."``); ``trace`` the analysed joint's decimated response
    (``joint``, ``time_s`` [s], ``position`` and ``reference`` [m or rad]); ``run_s`` the run's own wall-clock
    time in its worker [s]; ``passed`` the verdict of the sweep's spec (None without one, or on error); ``worker``
    the address of the Dask worker that ran it (None in this process; not part of the table)."""

    index: int
    values: dict[str, Any]
    metrics: dict[str, float | bool | None] = field(default_factory=dict)
    error: str | None = None
    trace: dict[str, Any] | None = None
    run_s: float = 0.0
    passed: bool | None = None
    worker: str | None = None


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
        row.metrics, row.trace = _run(task)
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


def _run(task: RunTask) -> tuple[dict[str, float | bool | None], dict[str, Any]]:
    scenario = task_scenario(task)
    with tempfile.TemporaryDirectory(prefix="jointctl-run-") as tmp, not_drawn():
        out = Path(tmp)
        with Session(scenario, out_dir=out, package_path=task.package_path) as session:
            analysis = check_analysis(session)
            session.run()
        session.manager.raise_failures()
        if session.rejected_goals:
            raise session.rejected_goals[0][1]
        trace = load_trace(session.trace_path)
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


__all__ = ["NOT_ROW_METRICS", "ROBOT_RUN_S", "Row", "RunTask", "build_session", "describe", "evaluate", "key_trace",
           "numbers", "task_overrides", "task_scenario"]

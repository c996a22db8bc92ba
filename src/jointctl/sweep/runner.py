"""One run of a sweep, in this process: :func:`evaluate` turns a :class:`RunTask` into its :class:`Row`.

A run is an ordinary scenario run (the same :class:`~jointctl.scenario.session.Session`, loop and analysis as
``jointctl run``) with the task's values applied: scenario fields as ``--set`` items, ``model.*`` and
``payload_kg`` to the simulated robot only, ``latency_cycles`` and ``noise.*`` by putting the simulated
hardware behind :class:`~jointctl.hardware.imperfect.ImperfectHardware`. The analysis draws no figures (a
sweep keeps the numbers) and the trace goes to a temporary folder; the row keeps the analysed joint's
position and reference, decimated, for the overlay figure.

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

from jointctl.errors import ConfigError, JointCtlError
from jointctl.hardware.imperfect import ImperfectHardware
from jointctl.recording.figures import not_drawn
from jointctl.recording.trace import load_trace
from jointctl.scenario.analyses import check_analysis
from jointctl.scenario.session import Session, session_defaults
from jointctl.scenario.targets import resolve_target
from jointctl.sweep.plant import check_payload, payload_link, varied_plant
from jointctl.sweep.variations import (LATENCY, MODEL_PREFIX, NOISE_POSITION, NOISE_VELOCITY, PAYLOAD, noise_seed,
                                       yaml_text)

#: How long a robot given as the target (not a scenario) is held [s], as ``jointctl run`` does.
ROBOT_RUN_S = 5.0
#: Metrics of a run's analysis that are not measured figures of the run: the theory from the nominal model
#: (``expected``, ``plant``: the varied plant is not what the analysis knows) and the run's wall-clock speed
#: (which would make the table depend on the machine).
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


@dataclass(frozen=True)
class RunSettings:
    """A task's values sorted by what they change (see :mod:`jointctl.sweep.variations`)."""

    overrides: tuple[str, ...]
    model: dict[str, float]
    payload_kg: float
    latency_cycles: int
    position_noise: float
    velocity_noise: float

    @property
    def changes_plant(self) -> bool:
        return bool(self.model) or self.payload_kg != 0.0

    @property
    def changes_hardware(self) -> bool:
        return self.latency_cycles != 0 or self.position_noise != 0.0 or self.velocity_noise != 0.0


def settings_of(values: Mapping[str, Any]) -> RunSettings:
    """Sort ``values`` and check the special ones (ConfigError naming the field and value)."""
    overrides, model = [], {}
    payload, latency, noise = 0.0, 0, {NOISE_POSITION: 0.0, NOISE_VELOCITY: 0.0}
    for name, value in values.items():
        if name == PAYLOAD:
            payload = check_payload(value)
        elif name == LATENCY:
            latency = latency_cycles(value)
        elif name in noise:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value < 0:
                raise ConfigError("must be a standard deviation, 0 or more", source="--vary", field=name, value=value)
            noise[name] = float(value)
        elif name.startswith(MODEL_PREFIX):
            model[name] = value
        else:
            overrides.append(f"{name}={yaml_text(value)}")
    return RunSettings(tuple(overrides), model, payload, latency, noise[NOISE_POSITION], noise[NOISE_VELOCITY])


def latency_cycles(value: Any) -> int:
    """``latency_cycles`` as a whole number of cycles, 0 or more: a grid's 2.0 is 2; a distribution's draw is
    rounded to the nearest cycle."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError("must be a whole number of control cycles", source="--vary", field=LATENCY, value=value)
    cycles = int(round(value))
    if cycles < 0:
        raise ConfigError("must not be negative", source="--vary", field=LATENCY, value=value)
    return cycles


def build_session(task: RunTask, out_dir: str | Path | None) -> Session:
    """The task's session, built and checked, not run (its trace goes to ``out_dir``; None: not recorded)."""
    scenario, plant, wrap = task_hooks(task)
    return Session(scenario, out_dir=out_dir, package_path=task.package_path, plant=plant, wrap_hardware=wrap)


def task_hooks(task: RunTask):
    """(the task's scenario, its plant change or None, its hardware wrapper or None)."""
    settings = settings_of(task.values)
    target = resolve_target(task.target, controllers=task.controllers,
                            overrides=[*task.overrides, *settings.overrides],
                            robot_defaults=[f"duration_s={ROBOT_RUN_S}"])
    scenario = target.scenario
    manifest = str(scenario.robot.manifest) if scenario.robot.manifest else None

    def plant(robot):
        link = payload_link(robot, scenario.robot.extras, manifest) if settings.payload_kg else None
        return varied_plant(robot, settings.model, settings.payload_kg, link)

    def wrap(hardware):
        return ImperfectHardware(hardware, latency_cycles=settings.latency_cycles,
                                 position_noise=settings.position_noise, velocity_noise=settings.velocity_noise,
                                 seed=noise_seed(task.seed, task.index))

    return scenario, plant if settings.changes_plant else None, wrap if settings.changes_hardware else None


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
    scenario, plant, wrap = task_hooks(task)
    # The defaults reach the sessions an analysis builds to run its scenario again (another mode, other gains).
    with tempfile.TemporaryDirectory(prefix="jointctl-run-") as tmp, not_drawn(), session_defaults(plant, wrap):
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


__all__ = ["NOT_ROW_METRICS", "ROBOT_RUN_S", "Row", "RunSettings", "RunTask", "build_session", "describe",
           "evaluate", "key_trace", "latency_cycles", "numbers", "settings_of"]

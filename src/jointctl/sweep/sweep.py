"""A sweep, start to end: :func:`run_sweep`.

1. The variations are parsed and checked against the target before anything runs: every field exists (the
   nearest name when not), every grid and list value is one the field takes (a distribution's centre
   stands for it); bad input raises :class:`~jointctl.errors.ConfigError` naming the field and value.
2. The nominal run (the target with nothing varied) runs here: its metrics are the ones the spec may bound,
   and the summary's and figures' reference; its wall-clock time, times the runs, is what the runs would take one
   after the other.
3. The runs go to the engine (:class:`~jointctl.sweep.engine.Engine`) as independent tasks; each returns its
   row. A failed run is a row naming its failure. Asked for no engine, cluster or workers, a sweep runs here when
   a local cluster would save it less than the cluster's start (:func:`runs_here`), and says so.
4. The rows are judged against the spec, and, with ``out_dir``, written with the figures.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Callable, Iterable
from pathlib import Path

from jointctl.errors import ConfigError
from jointctl.model.loader import load_robot_model
from jointctl.scenario.analyses import check_analysis
from jointctl.scenario.plant import model_target, payload_link
from jointctl.scenario.spec import ROBOT_SETTINGS, check_robot_setting
from jointctl.scenario.targets import resolve_target
from jointctl.sweep.criteria import Spec, parse_spec
from jointctl.sweep.engine import Engine, ProgressLine, cores
from jointctl.sweep.figures import write_figures
from jointctl.sweep.results import SweepResult
from jointctl.sweep.runner import ROBOT_RUN_S, Row, RunTask, build_session, evaluate
from jointctl.sweep.variations import LATENCY, MODEL_PREFIX, PAYLOAD, Variation, check_samples, expand, variations_from

#: What a local cluster costs a sweep [s]: starting its worker processes (each importing jointctl) and stopping them.
#: Measured 1.8-2.0 s on a 2-core machine at rest, up to 6 s on a loaded one; the smaller figure keeps a sweep that
#: the cluster would speed up on it.
CLUSTER_START_S = 2.0


def runs_here(serial_s: float, workers: int) -> bool:
    """Whether runs taking ``serial_s`` one after the other [s] finish sooner in this process than on a local
    cluster of ``workers`` processes: the cluster saves at most ``serial_s·(1 - 1/workers)`` and costs
    :data:`CLUSTER_START_S`."""
    return serial_s * (1.0 - 1.0 / max(1, workers)) < CLUSTER_START_S


def run_sweep(target: str, variations: Iterable[str | Variation], *, samples: int | None = None, seed: int = 0,
              spec: str | Spec | None = None, scheduler: str | None = None, workers: int | None = None,
              in_process: bool = False, engine: Engine | None = None, out_dir: str | Path | None = None,
              controllers: str | None = None, overrides: Iterable[str] = (), package_path: Iterable[str] = (),
              nominal: bool = True, check: bool = True, figures: bool = True, reuse: bool = True,
              progress: bool | Callable[[Row], None] = False, say: Callable[[str], None] | None = None) -> SweepResult:
    """Run ``target`` (a scenario or robot, as ``jointctl run`` takes it) once per combination of
    ``variations`` (``"FIELD=VALUES"`` items or :class:`Variation`; see :mod:`jointctl.sweep.variations`), with
    ``samples`` draws of the distributions seeded by ``seed``, and return the rows.

    ``overrides`` (``--set`` items) and ``controllers`` apply to every run and to the nominal one. The runs go to
    ``engine`` when given (left open), else to one made for the call: the cluster at ``scheduler``, a local
    cluster of ``workers`` processes, or this process (``in_process``); with none of these, this process when the
    nominal run's time says the runs are too few to pay for a cluster's start (:func:`runs_here`; ``say`` is told so
    in a line), else a local cluster of one process per core. ``spec``
    (``"overshoot_pct<=10,settling_time_s<=0.3"``) judges each row. ``nominal=False`` skips the nominal run
    (and with it the check of the spec's metric names); ``check=False`` the check of the variations' values against
    the target (for a caller that sweeps the same variations again and again, e.g. a design loop). ``reuse``
    (the default): each process running the runs keeps the worlds it built for the next runs of this sweep
    (:data:`~jointctl.sweep.runner.WORLDS`); False: every run builds its own. With ``out_dir``: ``results.csv``,
    ``summary.json``, ``traces.npz`` and (``figures``) the PNGs. ``progress``: True for a progress line on stderr
    (:class:`~jointctl.sweep.engine.ProgressLine`), or a function called with each row as it arrives.
    """
    found = variations_from(variations)
    count = check_samples(samples, seed, found)
    spec = spec if isinstance(spec, Spec) else parse_spec(spec)
    base = RunTask(-1, target, {}, seed, controllers, tuple(overrides), tuple(package_path),
                   reuse=uuid.uuid4().hex if reuse else None)
    own = engine is None
    chosen = own and scheduler is None and workers is None and not in_process
    if own:
        engine = Engine(scheduler=scheduler, workers=workers, in_process=in_process)  # its arguments checked here
    if check:
        check_variations(base, found)
    nominal_row = None
    if nominal:
        nominal_row = evaluate(base)
        if nominal_row.error is None:
            spec.check_metrics(nominal_row.metrics)
    tasks = [RunTask(k, target, values, seed, controllers, base.overrides, base.package_path, reuse=base.reuse)
             for k, values in enumerate(expand(found, count, seed))]
    if chosen and nominal_row is not None and nominal_row.error is None \
            and runs_here(nominal_row.run_s * len(tasks), cores()):
        engine = Engine(in_process=True)
        if say is not None:
            say(f"{len(tasks)} run{'s' if len(tasks) != 1 else ''} of about {nominal_row.run_s:.2g} s: in this process "
                f"(a local Dask cluster takes about {CLUSTER_START_S:g} s to start; --workers N for one)")
    try:
        engine.start()
        line = ProgressLine(len(tasks)) if progress is True else None
        start = time.perf_counter()
        rows, interrupted = engine.run(tasks, line or progress or None)
        wall = time.perf_counter() - start
        if line is not None:
            line.close()
    finally:
        if own:
            engine.close()
    for row in rows:
        row.passed = spec.verdict(row.metrics) if row.error is None else None
    result = SweepResult(target, found, spec, count, seed, len(tasks), rows, nominal_row, interrupted,
                         engine.description, wall)
    if out_dir is not None:
        result.write(out_dir)
        if figures:
            write_figures(result, out_dir)
    return result


def check_variations(base: RunTask, variations: tuple[Variation, ...]) -> None:
    """Refuse, before anything runs, a field the target does not have and a grid or list value it does not take
    (ConfigError naming the field and the value). Distributions are checked at their centre; their draws are
    checked run by run (a draw out of range is that run's error). A setting of the simulated robot (payload, model,
    latency, noise) is checked as the scenario loader checks it; any other field by building the run's session."""
    target = resolve_target(base.target, controllers=base.controllers, overrides=base.overrides,
                            robot_defaults=[f"duration_s={ROBOT_RUN_S}"])
    scenario = target.scenario
    robot = None
    if any(v.field.startswith(MODEL_PREFIX) or v.field == PAYLOAD for v in variations):
        robot = load_robot_model(scenario.robot.description, search_path=base.package_path)
    for variation in variations:
        field = variation.field
        values = [variation.representative] if variation.is_distribution else list(variation.values)
        if field.split(".")[0] in ROBOT_SETTINGS:
            for value in values:
                if field == LATENCY and not variation.is_distribution and value != round(value):
                    raise ConfigError("a grid or list of latencies must be whole numbers of cycles", source="--vary",
                                      field=field, value=value)
                check_robot_setting(field, value, source="--vary")
            if field.startswith(MODEL_PREFIX):
                model_target(robot, field)
            elif field == PAYLOAD:
                payload_link(robot, scenario.robot.extras, str(scenario.robot.manifest or ""))
        else:
            for value in values:
                _check_session(base, {field: value})
    _check_session(base, {v.field: v.representative for v in variations})


def _check_session(base: RunTask, values: dict) -> None:
    """Build (not run) the session of ``base`` with ``values``: every check a run makes before it moves."""
    task = RunTask(base.index, base.target, values, base.seed, base.controllers, base.overrides, base.package_path)
    with build_session(task, None) as session:
        check_analysis(session)


__all__ = ["check_variations", "run_sweep"]

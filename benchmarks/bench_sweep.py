"""Sweeps on Dask: parallel efficiency, scheduling overhead, and a 1000-run sweep's wall time.

*Baseline*: the 200 runs of ``jointctl sweep one_dof_step --vary payload_kg=0:5:200`` one after the other in this
process (no Dask): their summed run time is the work. *One worker / two workers*: the same sweep on a local cluster
of one and of two worker processes (started, and their imports done, before the clock starts). Measured:

- parallel efficiency = wall(1 worker) / (2 · wall(2 workers)), target >= 0.85;
- scheduling overhead per run = (wall(1 worker) - the runs' own summed time) / runs, against the mean run's own
  time, target <= 5 % (the runs' own time is measured inside each task: building the session, the 3 s of loop
  time, the analysis);
- the wall time of 1000 runs (payload 0..5 kg x Kp 200..800) on two workers, and its cost per run;
- the cost of one run of the arm's Monte Carlo (arm7dof_pose, joint damping and payload drawn), for the estimate of
  a cluster in docs/sweeps.md;
- the throughput of a sweep as it runs (each worker keeps the worlds it built for the sweep's next runs, the loop
  compiled, the trace in memory) against the same sweep run by jointctl as it was when the compiled cycle was
  asked for (:data:`BASELINE_COMMIT`, the commit before the first kernel, taken from this repository's history by
  ``git archive``): the same :data:`OLD_RUNS` runs on a local cluster of two workers, each way in its own process
  (its cluster started and warmed before the clock starts), interleaved, best of :data:`REPEATS`, target >= 3x;
  and the 1000 runs above against that throughput. Without the repository's history (a source tarball) the
  comparison is not measured.

The 200-run sweeps on one and two workers are interleaved, three of each, and the fastest of each counts.

The efficiency is bounded by the machine: on 2 cores the scheduler and this client share them with the workers.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.common import Result

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
#: jointctl as it was when the compiled cycle was asked for: the parent of the commit of the first kernel.
BASELINE_COMMIT = "36a311fb215ac50771839cdd6f93302a5f8f9403"

TARGET = "one_dof_step"
RUNS = 200
VARY_200 = [f"payload_kg=0:5:{RUNS}"]
VARY_1000 = ["payload_kg=0:5:40", "controllers.joint1_position_controller.pid.p=200:800:25"]
#: The runs measured both ways: the 1000 runs' gains on 8 of their 40 payloads (25 runs a payload, as in the 1000).
OLD_RUNS = 200
VARY_OLD = ["payload_kg=0:5:8", "controllers.joint1_position_controller.pid.p=200:800:25"]
REPEATS = 3
#: The arm's Monte Carlo sample, for the cost of one of its runs (docs/sweeps.md's estimate for a cluster).
ARM_TARGET = "arm7dof_pose"
ARM_VARY = ["model.joint1.damping=normal(10,3)", "payload_kg=uniform(0,2)"]
ARM_SAMPLES = 3


def _sweep(vary, engine):
    from jointctl.sweep import run_sweep

    result = run_sweep(TARGET, vary, engine=engine, nominal=False)
    assert all(row.loop == "compiled" for row in result.rows)
    assert not result.errors, result.errors[0].error
    return result


#: A sweep timed in its own process (the baseline's code or this one's: the API both have).
TIMED = """
import time
from jointctl.sweep import Engine, run_sweep
with Engine(workers=2) as engine:
    run_sweep(TARGET, ["payload_kg=[0, 1, 2, 3]"], engine=engine, nominal=False)  # the workers' imports, first builds
    start = time.perf_counter()
    result = run_sweep(TARGET, VARY_OLD, engine=engine, nominal=False)
    wall = time.perf_counter() - start
assert not any(row.error for row in result.rows)
print(wall)
"""

#: The machine's own parallel efficiency: the same runs in plain processes, no Dask (each prints its wall time).
PLAIN = """
import sys, time
from jointctl.sweep.runner import RunTask, evaluate
evaluate(RunTask(0, "one_dof_step", {}))
start = time.perf_counter()
for k in range(RUNS):
    assert evaluate(RunTask(k, "one_dof_step", {"payload_kg": 5.0 * k / RUNS})).error is None
print(time.perf_counter() - start)
"""


def baseline_source(folder: Path) -> Path | None:
    """The ``src`` folder of :data:`BASELINE_COMMIT`'s tree, written into ``folder`` (None without git or the
    commit)."""
    import io
    import tarfile

    try:
        tree = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", BASELINE_COMMIT],
                              capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    with tarfile.open(fileobj=io.BytesIO(tree)) as archive:
        archive.extractall(folder)  # (this repository's own tree)
    return folder / "src"


def timed_sweep(source: Path) -> float:
    """Wall time [s] of the :data:`OLD_RUNS` runs of :data:`VARY_OLD` on two workers, by the jointctl in
    ``source`` (its own process and cluster, warmed first)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(source), os.environ.get("PYTHONPATH")]))}
    code = TIMED.replace("VARY_OLD", repr(VARY_OLD)).replace("TARGET", repr(TARGET))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=source.parent)
    if out.returncode != 0:
        raise RuntimeError(f"the sweep of {source} failed: {out.stderr[-2000:]}")
    return float(out.stdout.strip().splitlines()[-1])


def old_and_new() -> tuple[float, float] | None:
    """Wall times [s] of :data:`OLD_RUNS` runs by the baseline's code and by this code, each the fastest of
    :data:`REPEATS`, interleaved; None without the baseline's tree."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="jointctl-baseline-") as tmp:
        old_source = baseline_source(Path(tmp))
        if old_source is None:
            return None
        old_walls, new_walls = [], []
        for _ in range(REPEATS):
            old_walls.append(timed_sweep(old_source))
            new_walls.append(timed_sweep(SRC))
    return min(old_walls), min(new_walls)


def plain_processes(count: int, runs: int) -> float:
    """Wall time [s] of ``count`` plain processes each running ``runs`` runs at once (the slowest's)."""
    code = PLAIN.replace("RUNS", str(runs))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(SRC), os.environ.get("PYTHONPATH")]))}
    processes = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env=env)
                 for _ in range(count)]
    return max(float(p.communicate()[0].strip().splitlines()[-1]) for p in processes)


def run() -> list[Result]:
    from jointctl.sweep import Engine

    machine = plain_processes(1, RUNS // 2) / plain_processes(2, RUNS // 2)  # two do twice the work

    with Engine(in_process=True) as here:
        baseline = _sweep(VARY_200, here)
    per_run_here = sum(r.run_s for r in baseline.rows) / RUNS
    with Engine(workers=1) as one, Engine(workers=2) as two:
        _sweep(["payload_kg=[0, 1]"], one)  # warm the workers: their first runs read and compile the model files
        _sweep(["payload_kg=[0, 1, 2, 3]"], two)
        # Interleaved, best of REPEATS: another process busy on the machine slows one repeat, not the best one.
        singles, doubles = [], []
        for _ in range(REPEATS):
            singles.append(_sweep(VARY_200, one))
            doubles.append(_sweep(VARY_200, two))
        start = time.perf_counter()
        thousand = _sweep(VARY_1000, two)
        wall_1000 = time.perf_counter() - start
    with Engine(in_process=True) as here:
        arm = run_sweep_rows(ARM_TARGET, ARM_VARY, here)
    walls = old_and_new()
    arm_run = min(r.run_s for r in arm)
    single = min(singles, key=lambda r: r.wall_s)
    double = min(doubles, key=lambda r: r.wall_s)
    own = sum(r.run_s for r in single.rows) / RUNS
    overhead = (single.wall_s - own * RUNS) / RUNS
    efficiency = single.wall_s / (2 * double.wall_s)
    own_2 = sum(r.run_s for r in double.rows) / RUNS  # above own: the two workers share the machine's cores
    per_run_1000 = sum(r.run_s for r in thousand.rows) / len(thousand.rows)
    throughput = len(thousand.rows) / wall_1000  # runs per second, the new way
    rows = [
        Result("sweep", "one run's own time, in this process (baseline)", per_run_here * 1e3, "ms"),
        Result("sweep", "one run's own time, on 1 worker", own * 1e3, "ms"),
        Result("sweep", "one run's own time, on each of 2 workers", own_2 * 1e3, "ms"),
        Result("sweep", f"{RUNS} runs: 1 worker / in this process", single.wall_s / baseline.wall_s, "x"),
        Result("sweep", "scheduling overhead per run / the run's own time", 100 * overhead / own, "%", "<= 5 %",
               overhead / own <= 0.05),
        Result("sweep", f"parallel efficiency, {RUNS} runs, 2 workers against 1", efficiency, "",
               ">= 0.85", efficiency >= 0.85),
        Result("sweep", "the machine's: 2 plain processes against 1, no Dask (the ceiling)", machine, ""),
        Result("sweep", "1000 runs on 2 workers, wall time (incl. the check of the target)", wall_1000, "s"),
        Result("sweep", "1000 runs on 2 workers: wall time per run x workers / run's own time",
               wall_1000 * 2 / len(thousand.rows) / per_run_1000, "x"),
        Result("sweep", f"{ARM_TARGET}: one run's own time (fastest of {len(arm)}, in this process)", arm_run, "s"),
    ]
    if walls is None:
        return rows + [Result("sweep", f"this code / {BASELINE_COMMIT[:8]} (no git history here: not measured)",
                              float("nan"), "x", ">= 3")]
    wall_old, wall_new = walls
    return rows + [
        Result("sweep", f"{BASELINE_COMMIT[:8]} (before the compiled cycle): {OLD_RUNS} runs on 2 workers, "
               f"throughput (fastest of {REPEATS})", OLD_RUNS / wall_old, "runs/s"),
        Result("sweep", f"this code: the same {OLD_RUNS} runs on 2 workers, throughput (fastest of {REPEATS})",
               OLD_RUNS / wall_new, "runs/s"),
        Result("sweep", f"this code / {BASELINE_COMMIT[:8]}, {OLD_RUNS} runs on 2 workers, throughput",
               wall_old / wall_new, "x", ">= 3", wall_old / wall_new >= 3),
        Result("sweep", f"1000 runs on 2 workers (throughput above) / {BASELINE_COMMIT[:8]}'s throughput",
               throughput * wall_old / OLD_RUNS, "x"),
    ]


def run_sweep_rows(target, vary, engine):
    from jointctl.sweep import run_sweep

    result = run_sweep(target, vary, samples=ARM_SAMPLES, seed=1, engine=engine, nominal=False)
    assert not result.errors, result.errors[0].error
    return result.rows


if __name__ == "__main__":
    for row in run():
        print(row)

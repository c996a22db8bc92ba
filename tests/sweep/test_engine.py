"""The real engine: Dask's own ``dask scheduler`` and ``dask worker`` processes on loopback and across two network
namespaces, a local cluster of one worker, and this process give the same table; Ctrl-C keeps the finished rows.

The workers import this tree's jointctl (PYTHONPATH=src). Namespaces need root and ``ip``: without them the
across-hosts test skips, unless JOINTCTL_REQUIRE_ROS is set (as for the ROS two-host test), when it fails.
"""

from __future__ import annotations

import csv
import functools
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import psutil
import pytest

from jointctl.cli import main
from jointctl.sweep import Engine, run_sweep
from jointctl.sweep import engine as engine_module
from tests.netns import two_hosts
from tests.processes import stop_process
from tests.waiting import wait_until

pytestmark = pytest.mark.wall_clock

SRC = Path(__file__).resolve().parents[2] / "src"
DASK = [sys.executable, "-m", "dask"]
#: Two payloads, two durations (0.4 s ends before the step at 0.5 s: those runs fail in the analysis) and two draws of
#: sensor noise: 8 runs whose table depends on the seed's draws and each run's noise stream.
VARY = ["payload_kg=[0, 2.5]", "duration_s=[1.5, 0.4]", "noise.position=uniform(0, 1e-4)"]
SAMPLES, SEED = 2, 11


def env() -> dict:
    values = dict(os.environ)
    values["PYTHONPATH"] = os.pathsep.join(filter(None, [str(SRC), values.get("PYTHONPATH")]))
    return values


def stop(processes) -> None:
    """Each process told to stop and awaited in turn, the last started first: the workers before their scheduler
    (a worker closing because its scheduler went away while a SIGTERM arrives can hang in its close)."""
    for process in reversed(processes):
        stop_process(process, timeout_s=15.0)


wait_for = functools.partial(wait_until, timeout_s=60.0, every_s=0.1)


def sweep(out: Path, **engine) -> bytes:
    result = run_sweep("one_dof_step", VARY, samples=SAMPLES, seed=SEED, out_dir=out, figures=False, **engine)
    assert len(result.rows) == 8 and not result.interrupted
    return (out / "results.csv").read_bytes()


@pytest.fixture
def loopback_cluster(tmp_path):
    """``dask scheduler`` on 127.0.0.1 at a port it picks (told in its scheduler file) and two ``dask worker``
    processes of one thread each; stopped afterwards."""
    file = tmp_path / "scheduler.json"
    processes = [subprocess.Popen([*DASK, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                   "--dashboard-address", ":0", "--scheduler-file", str(file)], env=env(), cwd=tmp_path,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        wait_for(lambda: file.is_file() and file.stat().st_size > 0, "the scheduler file")
        address = json.loads(file.read_text())["address"]
        for k in range(2):
            processes.append(subprocess.Popen(
                [*DASK, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1",
                 "--name", f"w{k}", "--local-directory", str(tmp_path / f"w{k}")], env=env(), cwd=tmp_path,
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout=30) as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        stop(processes)


def test_the_same_seed_gives_the_same_table_here_on_one_worker_and_on_two(loopback_cluster, tmp_path):
    here = sweep(tmp_path / "here", in_process=True)
    assert sweep(tmp_path / "one", workers=1) == here
    with Engine(scheduler=loopback_cluster) as engine:
        assert engine.worker_count == 2
        result = run_sweep("one_dof_step", VARY, samples=SAMPLES, seed=SEED, engine=engine,
                           out_dir=tmp_path / "two", figures=False)
    assert (tmp_path / "two" / "results.csv").read_bytes() == here
    assert len({row.worker for row in result.rows}) == 2  # both workers ran some
    # The failing samples are rows naming their failure; the others measured.
    with (tmp_path / "two" / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    short = [r for r in rows if r["duration_s"] == "0.4"]
    assert len(short) == 4 and all(r["error"].startswith("AnalysisError: step_time_s must lie inside the record")
                                   and r["overshoot_pct"] == "" for r in short)
    # The finished runs measured: the fitted ωn always; the overshoot where the run settled (2.5 kg still rings by
    # 0.3·exp(-1.42·0.85 s) = 9 cm at 1.35 s, where its last tenth begins: no final value to measure it from).
    finished = [r for r in rows if r["duration_s"] == "1.5"]
    assert all(r["error"] == "" and float(r["natural_frequency_rad_s"]) > 0 for r in finished)
    assert all((r["overshoot_pct"] == "") == (r["payload_kg"] == "2.5") for r in finished)


def test_an_address_where_no_scheduler_answers_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(engine_module, "CONNECT_TIMEOUT_S", 1.0)
    assert main(["sweep", "one_dof_step", "--vary", "payload_kg=[0]", "--scheduler", "tcp://127.0.0.1:9",
                 "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("jointctl: error: --scheduler: no Dask scheduler answers there") and err.count("\n") == 1


def test_ctrl_c_cancels_the_rest_stops_the_workers_and_keeps_the_finished_rows(tmp_path):
    out = tmp_path / "sweep"
    command = [sys.executable, "-m", "jointctl.cli", "sweep", "one_dof_step", "--vary", "payload_kg=0:5:400",
               "--workers", "2", "--no-figures", "--out", str(out)]
    process = subprocess.Popen(command, env=env(), cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, start_new_session=True)
    try:
        first = process.stderr.readline()  # the first progress line: a tenth of the runs done
        assert first.startswith("sweep: "), first + process.stderr.read()
        workers = psutil.Process(process.pid).children(recursive=True)
        assert workers, "the local cluster's processes"
        os.killpg(process.pid, signal.SIGINT)  # as a terminal's Ctrl-C: to the whole foreground group
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert "interrupted after" in err
    with (out / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert 40 <= len(rows) < 400
    assert all(r["error"] == "" for r in rows)  # cancelled runs are not rows, finished ones all measured
    assert json.loads((out / "summary.json").read_text())["interrupted"] is True
    gone, alive = psutil.wait_procs(workers, timeout=30)
    assert not alive, [p.pid for p in alive]


# -- across two hosts ------------------------------------------------------------------------------------------
ADDR_A, ADDR_B = "10.201.0.1", "10.201.0.2"
PORT = 8786


@pytest.fixture
def hosts():
    """Two namespaces (A, B) joined by a veth pair (:func:`tests.netns.two_hosts`)."""
    with two_hosts("js", ADDR_A, ADDR_B) as namespaces:
        yield namespaces


def _in(ns: str, *cmd: str) -> list[str]:
    return ["ip", "netns", "exec", ns, *cmd]


def test_a_sweep_from_host_b_runs_on_workers_of_both_hosts_and_gives_the_same_table(hosts, tmp_path):
    ns_a, ns_b = hosts
    address = f"tcp://{ADDR_A}:{PORT}"
    processes = []
    try:
        processes.append(subprocess.Popen(_in(ns_a, *DASK, "scheduler", "--host", ADDR_A, "--port", str(PORT),
                                              "--no-dashboard", "--dashboard-address", ":0"), env=env(), cwd=tmp_path,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        for ns, addr in ((ns_a, ADDR_A), (ns_b, ADDR_B)):
            processes.append(subprocess.Popen(
                _in(ns, *DASK, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", addr,
                    "--local-directory", str(tmp_path / f"worker_{addr}")), env=env(), cwd=tmp_path,
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        ready = subprocess.run(_in(ns_b, sys.executable, "-c", (
            "from distributed import Client\n"
            f"c = Client({address!r}, timeout=60)\n"
            "c.wait_for_workers(2, timeout=60)\n"
            "print(sorted(w.split(':')[1] for w in c.scheduler_info()['workers']))")),
            env=env(), capture_output=True, text=True, timeout=150)
        assert ready.returncode == 0, ready.stderr[-2000:]
        assert ready.stdout.strip() == str(sorted(["//" + ADDR_A, "//" + ADDR_B]))
        out = tmp_path / "from_b"
        args = ["sweep", "one_dof_step", *[a for v in VARY for a in ("--vary", v)], "--samples", str(SAMPLES),
                "--seed", str(SEED), "--no-figures", "--scheduler", address, "--out", str(out)]
        run = subprocess.run(_in(ns_b, sys.executable, "-m", "jointctl.cli", *args), env=env(), cwd=tmp_path,
                             capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, run.stderr[-2000:]
        assert f"on the Dask cluster at {address} (2 workers)" in run.stderr
    finally:
        stop(processes)
    here = sweep(tmp_path / "here", in_process=True)
    assert (out / "results.csv").read_bytes() == here


def test_workers_of_another_jointctl_are_refused_before_any_run(loopback_cluster, monkeypatch):
    """This process reports another version than the one the workers import: the sweep is refused before any run,
    naming both versions, and the engine has let go of the cluster."""
    from jointctl import __version__ as theirs
    from jointctl.errors import JointCtlError

    monkeypatch.setattr(engine_module, "__version__", "0.0.0+other")
    engine = Engine(scheduler=loopback_cluster)
    with pytest.raises(JointCtlError) as refused:
        engine.start()
    assert refused.value.field == "--scheduler" and refused.value.value == loopback_cluster
    message = refused.value.message
    assert message.startswith("workers run another jointctl than this one (0.0.0+other): {")
    assert message.count(repr(theirs)) == 2  # each of the two workers, with the version it imports
    assert engine.client is None


def test_a_run_whose_worker_dies_is_a_row_saying_so_and_the_others_measure(tmp_path, monkeypatch):
    """Run 1 kills its worker process; with no retry allowed (Dask's allowed-failures 0) its row names the
    worker's death and keeps its values, and the nanny's new worker runs the rest as this process does. (One task
    at a time on the worker, worker-saturation 1: no other task is lost with it.)"""
    import dask

    from jointctl.sweep.runner import RunTask, evaluate
    from tests.sweep.dying_worker import DYING_INDEX, evaluate_or_die

    monkeypatch.setattr(engine_module, "evaluate_on_worker", evaluate_or_die)
    tasks = [RunTask(k, "one_dof_step", {"payload_kg": payload}) for k, payload in enumerate((0.0, 1.0, 2.5))]
    with dask.config.set({"distributed.scheduler.allowed-failures": 0,
                          "distributed.scheduler.worker-saturation": 1.0}), Engine(workers=1) as engine:
        rows, interrupted = engine.run(tasks)
    assert not interrupted and [row.index for row in rows] == [0, 1, 2]
    died = rows[DYING_INDEX]
    assert died.values == {"payload_kg": 1.0} and died.metrics == {}
    assert died.error.startswith("KilledWorker: ") and "died" in died.error, died.error
    for row in rows[:DYING_INDEX] + rows[DYING_INDEX + 1:]:
        here = evaluate(tasks[row.index])
        assert row.error is None and row.metrics == here.metrics


def test_a_large_sweep_goes_in_batches_in_order_and_a_small_one_a_run_a_task():
    from jointctl.sweep.runner import RunTask

    tasks = [RunTask(k, "one_dof_step", {}) for k in range(200)]
    cut = engine_module.batches(tasks, 2)
    assert [len(b) for b in cut] == [6] * 33 + [2]  # 200 // (2 workers x 16) = 6 runs a batch
    assert [t.index for b in cut for t in b] == list(range(200))
    assert [len(b) for b in engine_module.batches(tasks, 1)] == [8] * 25  # at most 8
    assert [len(b) for b in engine_module.batches(tasks[:40], 2)] == [1] * 40


def test_a_batch_lost_with_its_worker_is_run_again_a_run_a_task(tmp_path, monkeypatch):
    """Run 1 kills its worker with the batch it came in (runs 0 and 1); the batch's runs go again one a task: run
    0 measures, run 1 kills a worker again and its row says so, the other batches measure."""
    import dask

    from jointctl.sweep.runner import RunTask, evaluate
    from tests.sweep.dying_worker import DYING_INDEX, evaluate_batch_or_die, evaluate_or_die

    monkeypatch.setattr(engine_module, "evaluate_on_worker", evaluate_or_die)
    monkeypatch.setattr(engine_module, "evaluate_batch_on_worker", evaluate_batch_or_die)
    tasks = [RunTask(k, "one_dof_step", {"payload_kg": 0.1 * k}) for k in range(32)]
    assert len(engine_module.batches(tasks, 1)[0]) == 2
    with dask.config.set({"distributed.scheduler.allowed-failures": 0,
                          "distributed.scheduler.worker-saturation": 1.0}), Engine(workers=1) as engine:
        rows, interrupted = engine.run(tasks)
    assert not interrupted and [row.index for row in rows] == list(range(32))
    assert rows[DYING_INDEX].error.startswith("KilledWorker: ") and rows[DYING_INDEX].metrics == {}
    assert [row.index for row in rows if row.error] == [DYING_INDEX]
    assert rows[0].metrics == evaluate(tasks[0]).metrics and rows[31].metrics == evaluate(tasks[31]).metrics

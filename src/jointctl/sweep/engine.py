"""Where a sweep's runs go: Dask distributed, or this process.

:class:`Engine` is a context manager around a Dask client:

- by default a ``LocalCluster`` of worker processes on this machine, one per core (``workers``), each with one
  thread (a run is Python and MuJoCo on one core), started on entry and stopped on exit;
- with ``scheduler`` (``tcp://host:8786``), a cluster someone started (``dask scheduler`` and ``dask worker``
  on each machine, jointctl installed there); it is left running;
- with ``in_process``, no Dask at all: the runs one after the other here (for debugging, or where worker
  processes cannot be had).

Each run is one task, :func:`~jointctl.sweep.runner.evaluate` of its :class:`~jointctl.sweep.runner.RunTask`,
returning its row; the rows come back in any order and are put in run order. A task that does not come back
(a worker that died) is a row whose error says so. Ctrl-C (KeyboardInterrupt) cancels the tasks not yet done
and returns the rows finished so far, marked interrupted.
"""

from __future__ import annotations

import importlib
import logging
import os
import signal
import sys
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from typing import TextIO

from jointctl import __version__
from jointctl.errors import JointCtlError
from jointctl.sweep.runner import Row, RunTask, describe, evaluate

#: How long to wait for a scheduler to answer and for its first worker [s].
CONNECT_TIMEOUT_S = 30.0


def jointctl_version() -> str:
    """The jointctl version of the process it runs in, after importing what a run needs (asked of every worker of
    a cluster when the engine starts: the imports then do not count in the first runs' time)."""
    for module in ("jointctl.scenario.analyses", "jointctl.sweep.runner"):
        importlib.import_module(module)
    return __version__


def evaluate_on_worker(task: RunTask) -> Row:
    """:func:`~jointctl.sweep.runner.evaluate` on a Dask worker, the row noting the worker's address."""
    from distributed import get_worker

    row = evaluate(task)
    row.worker = get_worker().address
    return row


def evaluate_batch_on_worker(tasks: Sequence[RunTask]) -> list[Row]:
    """:func:`evaluate_on_worker` of each task in turn (one cluster task carrying several runs)."""
    return [evaluate_on_worker(task) for task in tasks]


#: The most runs one cluster task carries: a run on a kept world takes tens of milliseconds, and each task costs
#: the scheduler and the client about a millisecond of the cores the workers share on a small machine.
BATCH_RUNS = 8
#: Batches only when every worker gets at least this many of them (the load stays balanced to the end).
BATCHES_PER_WORKER = 16


def batches(tasks: Sequence[RunTask], workers: int) -> list[list[RunTask]]:
    """``tasks`` in order, cut into batches of up to :data:`BATCH_RUNS` (single runs for a small sweep)."""
    size = max(1, min(BATCH_RUNS, len(tasks) // (max(1, workers) * BATCHES_PER_WORKER)))
    return [list(tasks[k:k + size]) for k in range(0, len(tasks), size)]


def cores() -> int:
    """The cores this process may run on (its CPU affinity, else the machine's count)."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


class Engine:
    """Runs tasks on a local Dask cluster (default: ``workers`` processes, one per core), on the cluster at
    ``scheduler``, or, with ``in_process``, here. Use it in a ``with`` block; one engine may run several
    sweeps (a design loop pays the cluster's start once)."""

    def __init__(self, *, scheduler: str | None = None, workers: int | None = None, in_process: bool = False) -> None:
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise JointCtlError("must be a whole number of worker processes, 1 or more", field="--workers",
                                value=workers)
        if in_process and (scheduler is not None or workers is not None):
            raise JointCtlError("runs in this process: no scheduler or workers with it", field="--in-process")
        if scheduler is not None and workers is not None:
            raise JointCtlError("the cluster at --scheduler has its own workers", field="--workers", value=workers)
        self.scheduler = scheduler
        self.workers = workers
        self.in_process = in_process
        self.client = None
        self.cluster = None
        #: What ran the runs, in words ("a local cluster of 2 worker processes").
        self.description = "this process"

    # -- starting and stopping ---------------------------------------------------------------------------------
    def __enter__(self) -> Engine:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def start(self) -> Engine:
        """Start the local cluster or connect to the scheduler (JointCtlError when it cannot be had)."""
        if self.in_process or self.client is not None:
            return self
        _quiet_dask_logs()
        from distributed import Client

        if self.scheduler is not None:
            try:
                self.client = Client(self.scheduler, timeout=CONNECT_TIMEOUT_S)
            except (OSError, TimeoutError, ValueError) as exc:
                raise JointCtlError(f"no Dask scheduler answers there ({describe(exc)})", field="--scheduler",
                                    value=self.scheduler) from None
            try:
                self.client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
            except TimeoutError:
                self.close()
                raise JointCtlError(f"the scheduler has no workers after {CONNECT_TIMEOUT_S:g} s (start some: "
                                    f"dask worker {self.scheduler})", field="--scheduler",
                                    value=self.scheduler) from None
            self._check_workers()
            count = len(self.client.scheduler_info()["workers"])
            self.description = f"the Dask cluster at {self.scheduler} ({count} workers)"
            return self
        import dask
        from distributed import LocalCluster

        count = self.workers or cores()
        # Without Dask's statistical profiler, which samples each task's stack every 10 ms and takes the GIL from
        # the run to do it: runs are 4 % faster, the sweep 6 % (measured on one_dof_step).
        with _sigint_ignored_by_children(), dask.config.set({"distributed.worker.profile.enabled": False}):
            # No dashboard; the scheduler's small HTTP server (health, metrics) on a port the system picks, not
            # Dask's 8787, which another cluster on the machine may hold.
            self.cluster = LocalCluster(n_workers=count, threads_per_worker=1, processes=True,
                                        dashboard_address=None, scheduler_kwargs={"dashboard_address": ":0"},
                                        silence_logs=logging.ERROR)
        self.client = Client(self.cluster)
        self.client.run(jointctl_version)
        self.description = f"a local Dask cluster of {count} worker process{'es' if count != 1 else ''}"
        return self

    def _check_workers(self) -> None:
        """Every worker imports the same jointctl as this process, or the sweep is refused."""
        try:
            versions = self.client.run(jointctl_version)
        except Exception as exc:  # noqa: BLE001  (whatever a worker without jointctl raises)
            self.close()
            raise JointCtlError(f"a worker cannot run jointctl ({describe(exc)}); install jointctl "
                                f"{__version__} where the workers run", field="--scheduler",
                                value=self.scheduler) from None
        wrong = {worker: v for worker, v in versions.items() if v != __version__}
        if wrong:
            self.close()
            raise JointCtlError(f"workers run another jointctl than this one ({__version__}): {wrong}",
                                field="--scheduler", value=self.scheduler)

    def close(self) -> None:
        """Disconnect; stop the local cluster (a cluster at an address keeps running)."""
        client, cluster = self.client, self.cluster
        self.client = self.cluster = None
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()

    @property
    def worker_count(self) -> int:
        """Workers now connected (1 in this process)."""
        if self.client is None:
            return 1
        return len(self.client.scheduler_info()["workers"])

    # -- running -------------------------------------------------------------------------------------------------
    def run(self, tasks: Sequence[RunTask], on_row: Callable[[Row], None] | None = None) -> tuple[list[Row], bool]:
        """Run every task; ``on_row(row)`` as each finishes (any order). Returns the finished rows in run order
        and whether the sweep was interrupted (Ctrl-C: the rest cancelled)."""
        done: dict[int, Row] = {}

        def finished(row: Row) -> None:
            done[row.index] = row
            if on_row is not None:
                on_row(row)

        interrupted = False
        try:
            if self.client is None and not self.in_process:
                self.start()
            if self.client is None:
                for task in tasks:
                    finished(evaluate(task))
            else:
                self._run_on_cluster(tasks, finished)
        except KeyboardInterrupt:
            interrupted = True
        return [done[i] for i in sorted(done)], interrupted

    def _run_on_cluster(self, tasks: Sequence[RunTask], finished: Callable[[Row], None]) -> None:
        """The tasks in batches (:func:`batches`); a batch lost with its worker is run again a run a task, so that
        only the run that was lost with a worker says so."""
        from distributed import as_completed

        token = uuid.uuid4().hex[:8]
        work = {}  # future key -> its tasks
        futures = []
        for k, batch in enumerate(batches(tasks, self.worker_count)):
            if len(batch) == 1:
                key = f"jointctl-run-{token}-{batch[0].index}"
                future = self.client.submit(evaluate_on_worker, batch[0], key=key, pure=False)
            else:
                key = f"jointctl-runs-{token}-{k}"
                future = self.client.submit(evaluate_batch_on_worker, batch, key=key, pure=False)
            work[key] = batch
            futures.append(future)
        running = as_completed(futures)
        try:
            for future in running:
                batch = work[future.key]
                try:
                    result = future.result()
                    rows = result if isinstance(result, list) else [result]
                except Exception as exc:  # noqa: BLE001  (a worker died with the task, or it was lost)
                    if len(batch) > 1:
                        for task in batch:  # again, a run a task: only the one that kills its worker fails
                            key = f"jointctl-run-{token}-{task.index}"
                            work[key] = [task]
                            retry = self.client.submit(evaluate_on_worker, task, key=key, pure=False)
                            futures.append(retry)
                            running.add(retry)
                        future.release()
                        continue
                    rows = [Row(batch[0].index, dict(batch[0].values), error=describe(exc))]
                future.release()
                for row in rows:
                    finished(row)
        except KeyboardInterrupt:
            self.client.cancel([f for f in futures if not f.done()])
            raise


class ProgressLine:
    """``sweep: 37/200 runs (18 %), 2 failed, 4.1 s, about 17 s to go`` on ``stream``: redrawn in place on a
    terminal, else a line every tenth of the sweep."""

    def __init__(self, total: int, stream: TextIO | None = None) -> None:
        self.total = total
        self.stream = stream if stream is not None else sys.stderr
        self.done = 0
        self.failed = 0
        self.start_s = time.monotonic()
        self._tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self._last_tenth = 0

    def __call__(self, row: Row) -> None:
        self.done += 1
        self.failed += row.error is not None
        tenth = 10 * self.done // max(1, self.total)
        if self._tty:
            self.stream.write("\r" + self.line() + ("\n" if self.done == self.total else ""))
        elif tenth > self._last_tenth or self.done == self.total:
            self.stream.write(self.line() + "\n")
        self._last_tenth = tenth
        self.stream.flush()

    def line(self) -> str:
        elapsed = time.monotonic() - self.start_s
        left = elapsed / self.done * (self.total - self.done) if self.done else float("nan")
        eta = "done" if self.done == self.total else f"about {_duration(left)} to go"
        failed = f", {self.failed} failed" if self.failed else ""
        return (f"sweep: {self.done}/{self.total} runs ({100 * self.done // max(1, self.total)} %){failed}, "
                f"{_duration(elapsed)}, {eta}")

    def close(self) -> None:
        if self._tty and self.done != self.total:
            self.stream.write("\n")
            self.stream.flush()


def _duration(seconds: float) -> str:
    if seconds != seconds:  # NaN: nothing done yet
        return "?"
    if seconds < 60:
        return f"{seconds:.1f} s"
    if seconds < 3600:
        return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"
    return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"


def _quiet_dask_logs() -> None:
    """Dask's INFO and WARNING lines (workers starting and stopping, closed streams) off the user's terminal."""
    for name in ("distributed", "distributed.nanny", "distributed.scheduler", "distributed.worker",
                 "distributed.core", "distributed.comm", "distributed.client"):
        logging.getLogger(name).setLevel(logging.ERROR)


class _sigint_ignored_by_children:
    """While the local cluster's processes start, SIGINT is ignored, so they inherit the ignoring: a Ctrl-C on
    the terminal then reaches this process only, which cancels the tasks and stops them in order."""

    def __enter__(self):
        self._previous = None
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        return self

    def __exit__(self, *exc) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)


__all__ = ["CONNECT_TIMEOUT_S", "Engine", "ProgressLine", "evaluate_on_worker", "jointctl_version"]

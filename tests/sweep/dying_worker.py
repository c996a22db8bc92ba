"""A task function for a Dask worker that kills its worker process for one run (as a crash in MuJoCo's C code
or the kernel's OOM killer would): imported by the worker by name, so it lives in a module of its own."""

from __future__ import annotations

import os

from jointctl.sweep.engine import evaluate_on_worker

#: The run whose worker dies.
DYING_INDEX = 1


def evaluate_or_die(task):
    """The worker process exits at once (no exception, no reply) for run :data:`DYING_INDEX`; the others run."""
    if task.index == DYING_INDEX:
        os._exit(9)
    return evaluate_on_worker(task)


def evaluate_batch_or_die(tasks):
    """:func:`evaluate_or_die` of each task in turn (a batch: the worker dies with the whole batch)."""
    return [evaluate_or_die(task) for task in tasks]

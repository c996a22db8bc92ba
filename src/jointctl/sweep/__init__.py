"""Sweeps and Monte Carlo runs of a scenario over what varies: gains, the plant, payload, latency, noise.

A sweep runs one ordinary scenario run per sample (every field it varies is the scenario's, as ``--set`` names it)
on Dask distributed (a local cluster, an existing one by address, or this process when the runs are too few to pay
for a cluster's start) and turns the rows into ``results.csv``, ``summary.json`` and figures. The library:

- :func:`run_sweep` (target, ``--vary`` items, samples, seed, spec, engine...) -> :class:`SweepResult`;
- :class:`Engine`: a local cluster, a cluster at an address, or this process; reusable across sweeps;
- :func:`evaluate` one :class:`RunTask` in this process -> its :class:`Row`;
- :func:`parse_variation`, :func:`parse_spec`, :func:`expand`: the pieces, for callers that build their own runs.

``jointctl sweep`` is the command; docs/sweeps.md the guide.
"""

from jointctl.sweep.criteria import Spec, Term, parse_spec
from jointctl.sweep.engine import Engine, ProgressLine
from jointctl.sweep.results import SweepResult, load_traces
from jointctl.sweep.runner import Row, RunTask, evaluate
from jointctl.sweep.sweep import check_variations, run_sweep
from jointctl.sweep.variations import Variation, expand, parse_variation, variations_from

__all__ = ["Engine", "ProgressLine", "Row", "RunTask", "Spec", "SweepResult", "Term", "Variation",
           "check_variations", "evaluate", "expand", "load_traces", "parse_spec", "parse_variation", "run_sweep",
           "variations_from"]

"""A sweep's results: the rows in memory (:class:`SweepResult`) and on disk.

- ``results.csv``: one row a run, in run order: ``index``, the varied fields' values, the analysis's metrics
  (numbers, and flags such as ``moving_at_step`` as ``true``/``false``; empty when not measured), ``pass``
  (``true``/``false`` against the spec; empty without a spec or when the run failed) and ``error`` (the
  failure's kind and line; empty when the run finished). Numbers are written in full (``repr``), so the same
  sweep gives the same file, byte for byte.
- ``summary.json``: the counts (runs, passed, failed, errors by kind), the nominal run's metrics, and per
  metric its range and its worst case with the run that gave it (strict JSON: not measured is null); a flag
  counts as 1 when true, 0 when false, so its mean is the share of runs where it holds.
- ``traces.npz``: each finished run's analysed joint, decimated: ``index``, ``offset`` (where each run's
  samples start in the next three), ``time_s`` [s], ``position`` and ``reference`` [m or rad].

The worst case of a metric the spec bounds is its value furthest on the wrong side (the largest under
``<=``; a run that did not measure it counts as worst); of any other metric, the value furthest from the
nominal run's.
"""

from __future__ import annotations

import csv
import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from jointctl.recording.metrics_file import metrics_json
from jointctl.sweep.criteria import Spec
from jointctl.sweep.runner import Row
from jointctl.sweep.variations import Variation

RESULTS_FILE = "results.csv"
SUMMARY_FILE = "summary.json"
TRACES_FILE = "traces.npz"
TRACE_ARRAYS = ("time_s", "position", "reference")


@dataclass
class SweepResult:
    """A sweep's rows (finished runs, in run order) and what it was."""

    target: str
    variations: tuple[Variation, ...]
    spec: Spec
    samples: int
    seed: int
    planned: int
    rows: list[Row]
    nominal: Row | None
    interrupted: bool
    engine: str
    #: Wall-clock time of the runs [s] (from the first task submitted to the last row back).
    wall_s: float
    out_dir: Path | None = None

    @property
    def fields(self) -> list[str]:
        return [v.field for v in self.variations]

    @property
    def metric_names(self) -> list[str]:
        """Every metric reported, the nominal run's order first, then as the rows add them."""
        names: dict[str, None] = {}
        for row in ([self.nominal] if self.nominal is not None else []) + self.rows:
            if row.error is None:
                names.update(dict.fromkeys(row.metrics))
        return list(names)

    @property
    def errors(self) -> list[Row]:
        return [r for r in self.rows if r.error is not None]

    @property
    def passed(self) -> list[Row]:
        return [r for r in self.rows if r.passed is True]

    @property
    def failed(self) -> list[Row]:
        return [r for r in self.rows if r.passed is False]

    def column(self, metric: str) -> np.ndarray:
        """``metric`` of every row, NaN where not measured or the run failed."""
        return np.array([_as_float(r.metrics.get(metric)) if r.error is None else math.nan for r in self.rows])

    def worst(self, metric: str) -> tuple[float | None, Row] | None:
        """The worst value of ``metric`` and its row (see the module), or None when no run reported it."""
        finished = [r for r in self.rows if r.error is None]
        term = self.spec.term(metric)
        if term is not None:
            unmeasured = [r for r in finished if math.isnan(_as_float(r.metrics.get(metric)))]
            if unmeasured:
                return None, unmeasured[0]
            rows = [r for r in finished if metric in r.metrics]
            if not rows:
                return None
            pick = max if term.upper else min
            row = pick(rows, key=lambda r: r.metrics[metric])
            return row.metrics[metric], row
        rows = [r for r in finished if not math.isnan(_as_float(r.metrics.get(metric)))]
        nominal = math.nan
        if self.nominal is not None and self.nominal.error is None:
            nominal = _as_float(self.nominal.metrics.get(metric))
        if not rows or math.isnan(nominal):
            return None
        row = max(rows, key=lambda r: abs(r.metrics[metric] - nominal))
        return row.metrics[metric], row

    # -- the files ----------------------------------------------------------------------------------------------
    def table(self) -> tuple[list[str], list[list[str]]]:
        """``results.csv``'s header and rows, as text."""
        metrics = self.metric_names
        header = ["index", *self.fields, *metrics, "pass", "error"]
        lines = []
        for row in self.rows:
            line = [str(row.index)] + [_cell(row.values.get(f)) for f in self.fields]
            line += [_cell(row.metrics.get(m)) if row.error is None else "" for m in metrics]
            line += [_cell(row.passed), row.error or ""]
            lines.append(line)
        return header, lines

    def summary(self) -> dict[str, Any]:
        """``summary.json``'s content."""
        kinds = Counter(r.error.split(":", 1)[0] for r in self.errors)
        metrics = {}
        for name in self.metric_names:
            values = self.column(name)
            measured = values[np.isfinite(values)]
            finished = len(self.rows) - len(self.errors)
            entry: dict[str, Any] = {"measured": int(measured.size), "not_measured": int(finished - measured.size)}
            if measured.size:
                low, high = int(np.nanargmin(values)), int(np.nanargmax(values))
                entry["min"] = self._case(float(values[low]), self.rows[low])
                entry["max"] = self._case(float(values[high]), self.rows[high])
                entry["mean"] = float(np.mean(measured))
            if self.nominal is not None and self.nominal.error is None:
                entry["nominal"] = self.nominal.metrics.get(name)
            worst = self.worst(name)
            if worst is not None:
                term = self.spec.term(name)
                entry["worst"] = {**self._case(worst[0], worst[1]),
                                  "by": f"--spec {term}" if term else "furthest from the nominal run"}
            metrics[name] = entry
        return {
            "target": self.target,
            "varied": {v.field: v.describe() for v in self.variations},
            "samples": self.samples,
            "seed": self.seed,
            "spec": str(self.spec) or None,
            "runs": self.planned,
            "finished": len(self.rows),
            "interrupted": self.interrupted,
            "passed": len(self.passed) if self.spec else None,
            "failed": len(self.failed) if self.spec else None,
            "errors": len(self.errors),
            "errors_by_kind": dict(sorted(kinds.items())),
            "engine": self.engine,
            "wall_s": self.wall_s,
            "nominal": (self.nominal.metrics if self.nominal.error is None else {"error": self.nominal.error})
            if self.nominal is not None else None,
            "metrics": metrics,
        }

    def _case(self, value: float | None, row: Row) -> dict[str, Any]:
        return {"value": value, "index": row.index, "values": dict(row.values)}

    def write(self, out_dir: str | Path) -> Path:
        """``results.csv``, ``summary.json`` and ``traces.npz`` into ``out_dir``; returns it."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        header, lines = self.table()
        with (out / RESULTS_FILE).open("w", newline="") as f:
            writer = csv.writer(f, lineterminator="\n")
            writer.writerow(header)
            writer.writerows(lines)
        (out / SUMMARY_FILE).write_text(metrics_json(self.summary()) + "\n")
        write_traces(out / TRACES_FILE, self.rows)
        self.out_dir = out
        return out


def write_traces(path: Path, rows: list[Row]) -> None:
    """Every row's key trace into one ``.npz`` (see the module)."""
    kept = [r for r in rows if r.trace is not None]
    lengths = [len(r.trace["time_s"]) for r in kept]
    empty = np.zeros(0)
    np.savez_compressed(
        path, index=np.array([r.index for r in kept], dtype=np.int64),
        offset=np.cumsum([0, *lengths]).astype(np.int64),
        joint=np.array([r.trace["joint"] for r in kept], dtype=str),
        time_s=np.concatenate([r.trace["time_s"] for r in kept]) if kept else empty,
        position=np.concatenate([r.trace["position"] for r in kept]) if kept else empty,
        reference=np.concatenate([r.trace["reference"] for r in kept]) if kept else empty)


def load_traces(path: str | Path) -> dict[int, dict[str, Any]]:
    """``traces.npz`` back: run index -> its key trace (``joint``, ``time_s``, ``position``, ``reference``)."""
    with np.load(path) as data:
        offsets = data["offset"]
        return {int(i): {"joint": str(data["joint"][k]),
                         **{name: data[name][offsets[k]:offsets[k + 1]] for name in TRACE_ARRAYS}}
                for k, i in enumerate(data["index"])}


def _as_float(value: Any) -> float:
    """A metric as a number: a flag 1 or 0, anything else not a number NaN."""
    return float(value) if isinstance(value, (int, float)) else math.nan


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return str(value)


__all__ = ["RESULTS_FILE", "SUMMARY_FILE", "SweepResult", "TRACES_FILE", "load_traces", "write_traces"]

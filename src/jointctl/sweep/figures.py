"""A sweep's figures (matplotlib's Agg canvas, no display), written beside ``results.csv``:

- ``<metric>_vs_<field>.png``: each plotted metric against each varied numeric field, one dot a run (passed
  blue, failed red), the nominal run dashed, the spec's limit dotted;
- ``heatmap_<metric>.png`` when two fields or more vary: the metric over the first two numeric fields, the
  worst case over everything else in each cell (a grid or list each), else one dot a run coloured by it;
- ``responses.png``: every finished run's analysed joint overlaid. A step response is normalised (0 before
  the step, 1 at its final value, or at the commanded step for a run that did not settle) and drawn with the
  spec's band: the overshoot limit, and the settling band (±2 % of the step, the step analysis's) from the
  settling-time limit on.

The plotted metrics are the spec's, else the first four the analysis reports.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from jointctl.sweep.results import SweepResult

DPI = 110
_METADATA = {"Software": None}
PASS_COLOUR, FAIL_COLOUR, NEUTRAL_COLOUR = "tab:blue", "tab:red", "tab:gray"
#: The step analysis's settling band, as a fraction of the step (jointctl.metrics.response.step_response).
SETTLE_BAND = 0.02
MAX_METRICS = 4


def plotted_metrics(result: SweepResult) -> list[str]:
    """The spec's metrics, else the first :data:`MAX_METRICS` reported."""
    names = result.metric_names
    if result.spec:
        return [t.metric for t in result.spec.terms if t.metric in names]
    return names[:MAX_METRICS]


def numeric_fields(result: SweepResult) -> list[str]:
    """The varied fields whose values are all numbers."""
    return [f for f in result.fields
            if all(isinstance(r.values.get(f), (int, float)) and not isinstance(r.values.get(f), bool)
                   for r in result.rows)]


def write_figures(result: SweepResult, out_dir: str | Path) -> list[Path]:
    """Every figure of the module's list that the sweep has data for; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    metrics = plotted_metrics(result)
    fields = numeric_fields(result)
    if result.rows and metrics:
        for field in fields:
            for metric in metrics:
                path = out / f"{_slug(metric)}_vs_{_slug(field)}.png"
                written.append(metric_against_field(result, metric, field, path))
        if len(fields) >= 2:
            for metric in metrics:
                written.append(heat_map(result, metric, fields[0], fields[1], out / f"heatmap_{_slug(metric)}.png"))
    if any(r.trace is not None for r in result.rows):
        written.append(responses(result, out / "responses.png"))
    return written


def metric_against_field(result: SweepResult, metric: str, field: str, path: Path) -> Path:
    fig, ax = _axes(f"{metric} against {field}", field, metric)
    rows = [r for r in result.rows if r.error is None]
    x = np.array([float(r.values[field]) for r in rows])
    y = np.array([_number(r.metrics.get(metric)) for r in rows])
    colours = [_colour(r.passed) for r in rows]
    ax.scatter(x, y, c=colours, s=14, zorder=3)
    unmeasured = ~np.isfinite(y)
    if unmeasured.any():
        ax.scatter(x[unmeasured], np.full(unmeasured.sum(), np.nanmin(y) if np.isfinite(y).any() else 0.0),
                   marker="x", c=FAIL_COLOUR, label="not measured", zorder=3)
    nominal = _nominal(result, metric)
    if nominal is not None:
        ax.axhline(nominal, color="k", linestyle="--", linewidth=1, label=f"nominal {nominal:.4g}")
    term = result.spec.term(metric)
    if term is not None:
        ax.axhline(term.limit, color=FAIL_COLOUR, linestyle=":", linewidth=1.5, label=f"spec {term}")
    errors = sum(r.error is not None for r in result.rows)
    if errors:
        ax.set_title(f"{metric} against {field} ({errors} run{'s' if errors != 1 else ''} failed, not shown)")
    return _save(fig, ax, path)


def heat_map(result: SweepResult, metric: str, x_field: str, y_field: str, path: Path) -> Path:
    rows = [r for r in result.rows if r.error is None]
    gridded = all(not v.is_distribution for v in result.variations if v.field in (x_field, y_field))
    term = result.spec.term(metric)
    worst_is_max = term.upper if term is not None else True
    if gridded:
        xs = sorted({float(r.values[x_field]) for r in rows})
        ys = sorted({float(r.values[y_field]) for r in rows})
        cells = np.full((len(ys), len(xs)), np.nan)
        for r in rows:
            value = _number(r.metrics.get(metric))
            i, j = ys.index(float(r.values[y_field])), xs.index(float(r.values[x_field]))
            if math.isfinite(value):
                old = cells[i, j]
                cells[i, j] = value if old != old else (max if worst_is_max else min)(old, value)
        fig = Figure(figsize=(8.0, 5.5), dpi=DPI)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        image = ax.imshow(cells, origin="lower", aspect="auto", cmap="viridis_r" if worst_is_max else "viridis")
        ax.set_xticks(range(len(xs)), [f"{x:.4g}" for x in xs])
        ax.set_yticks(range(len(ys)), [f"{y:.4g}" for y in ys])
        middle = np.nanmean(cells) if np.isfinite(cells).any() else 0.0
        for (i, j), value in np.ndenumerate(cells):
            if math.isfinite(value):
                dark = (value > middle) == worst_is_max  # the colour map's dark end is the worst
                ax.text(j, i, f"{value:.3g}", ha="center", va="center", fontsize=8, color="w" if dark else "k")
                if term is not None and not term.holds(value):
                    ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, edgecolor=FAIL_COLOUR, linewidth=2))
        if term is not None:
            ax.plot([], [], color=FAIL_COLOUR, linewidth=2, label=f"fails {term}")
            ax.legend(loc="upper left", bbox_to_anchor=(0, -0.12), fontsize=8, frameon=False)
        extra = "" if len(result.fields) == 2 and result.samples == 1 else " (worst case in each cell)"
        ax.set_title(f"{metric}{extra}")
    else:
        fig = Figure(figsize=(8.0, 5.5), dpi=DPI)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        image = ax.scatter([float(r.values[x_field]) for r in rows], [float(r.values[y_field]) for r in rows],
                           c=[_number(r.metrics.get(metric)) for r in rows], s=18, cmap="viridis_r")
        ax.set_title(metric)
    fig.colorbar(image, ax=ax, label=metric)
    ax.set_xlabel(x_field)
    ax.set_ylabel(y_field)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI, format="png", metadata=_METADATA)
    return path


def responses(result: SweepResult, path: Path) -> Path:
    rows = [r for r in result.rows if r.error is None and r.trace is not None]
    joint = rows[0].trace["joint"] if rows else ""
    step = _is_step(result)
    ylabel = "normalised response (0 before the step, 1 at its end)" if step else f"{joint} position"
    fig, ax = _axes(f"every run's {joint} response ({len(rows)} runs)", "time [s]", ylabel)
    lines, colours = [], []
    for r in rows:
        t, y = r.trace["time_s"], r.trace["position"]
        if step:
            y = _normalised(y, r.metrics, r.trace["reference"])
            if y is None:
                continue
        lines.append(np.column_stack([t, y]))
        colours.append(_colour(r.passed))
    alpha = max(0.08, min(0.8, 20.0 / max(1, len(lines))))
    ax.add_collection(LineCollection(lines, colors=colours, linewidths=0.8, alpha=alpha))
    ax.autoscale_view()
    nominal = result.nominal
    if nominal is not None and nominal.error is None and nominal.trace is not None:
        t, y = nominal.trace["time_s"], nominal.trace["position"]
        y = _normalised(y, nominal.metrics, nominal.trace["reference"]) if step else y
        if y is not None:
            ax.plot(t, y, color="k", linewidth=1.2, linestyle="--", label="nominal")
        if not step:
            ax.plot(t, nominal.trace["reference"], color="k", linewidth=0.8, drawstyle="steps-post",
                    label="reference")
    if step and lines:
        step_s, end_s = _step_band(ax, result, rows)
        # From just before the step: before it, a normalised response is the start's transient, not the step's.
        ax.set_xlim(step_s - 0.05 * (end_s - step_s), end_s)
        after = np.concatenate([line[line[:, 0] >= step_s, 1] for line in lines])
        if after.size:
            low, high = min(float(after.min()), -0.05), float(after.max())
            if overshoot := result.spec.term("overshoot_pct"):
                high = max(high, 1 + overshoot.limit / 100)
            ax.set_ylim(low - 0.05 * (high - low), high + 0.05 * (high - low))
    ax.plot([], [], color=PASS_COLOUR, label="passed" if result.spec else "runs")
    if result.spec:
        ax.plot([], [], color=FAIL_COLOUR, label="failed")
    return _save(fig, ax, path)


def _step_band(ax, result: SweepResult, rows) -> tuple[float, float]:
    """The spec's band on a normalised step: the overshoot limit, and the settling band from the settling-time
    limit on (counted from the step, found where the reference changes). Returns (the step's time, the end) [s]."""
    t = rows[0].trace["time_s"]
    reference = rows[0].trace["reference"]
    changed = np.flatnonzero(np.abs(reference - reference[0]) > 1e-12)
    step_s = float(t[changed[0]]) if changed.size else float(t[0])
    end = float(max(r.trace["time_s"][-1] for r in rows))
    overshoot = result.spec.term("overshoot_pct")
    if overshoot is not None and overshoot.upper:
        ax.axhline(1 + overshoot.limit / 100, color=FAIL_COLOUR, linestyle=":", linewidth=1.5,
                   label=f"spec {overshoot}")
    settling = result.spec.term("settling_time_s")
    if settling is not None and settling.upper:
        start = step_s + settling.limit
        ax.fill_between([start, end], 1 - SETTLE_BAND, 1 + SETTLE_BAND, color="tab:green", alpha=0.25,
                        label=f"±{100 * SETTLE_BAND:g} % from {settling}")
        ax.axvline(start, color="tab:green", linestyle=":", linewidth=1)
    return step_s, end


def _is_step(result: SweepResult) -> bool:
    names = result.metric_names
    return "initial_value" in names and "final_value" in names and "overshoot_pct" in names


def _normalised(y: np.ndarray, metrics, reference: np.ndarray) -> np.ndarray | None:
    """0 at the response's initial value, 1 at its final value; a run that did not settle (no final value) is
    drawn to the step of its ``reference`` instead."""
    y0, y1 = _number(metrics.get("initial_value")), _number(metrics.get("final_value"))
    step = y1 - y0 if math.isfinite(y1) else float(reference[-1] - reference[0])
    if not math.isfinite(y0) or not math.isfinite(step) or step == 0:
        return None
    return (y - y0) / step


def _nominal(result: SweepResult, metric: str) -> float | None:
    if result.nominal is None or result.nominal.error is not None:
        return None
    value = _number(result.nominal.metrics.get(metric))
    return value if math.isfinite(value) else None


def _number(value) -> float:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan


def _colour(passed: bool | None) -> str:
    return FAIL_COLOUR if passed is False else PASS_COLOUR


def _axes(title: str, xlabel: str, ylabel: str):
    fig = Figure(figsize=(8.0, 4.5), dpi=DPI)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.set_title(title)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.4)
    return fig, ax


def _save(fig: Figure, ax, path: Path) -> Path:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI, format="png", metadata=_METADATA)
    return path


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_")


__all__ = ["heat_map", "metric_against_field", "plotted_metrics", "responses", "write_figures"]

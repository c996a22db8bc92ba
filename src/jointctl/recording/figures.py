"""PNG and SVG figures of recorded traces, in the spirit of rqt_plot screenshots.

Uses :class:`matplotlib.figure.Figure` with the Agg canvas directly: no pyplot, safe to call from
any thread or without a display (the SVG settings matplotlib reads from its global rcParams are set
only while an SVG is written, one at a time). A figure of one axis is 8 x 4.5 in at 110 dpi
(880 x 495 px), 2 in taller for each further axis, with a grid, labelled axes and a legend; nothing
time-dependent is written into the image or its metadata, so the same data give the same files.

Each figure is written twice: the PNG named by the caller and an SVG beside it (same name, ``.svg``)
whose text stays text (``svg.fonttype: none``), so labels, units and markers can be searched and
read back. Values are shown in their SI unit with the prefix chosen for their range
(:func:`~jointctl.recording.units.display_scale`: a 0.33 mrad error reads 330 µrad, not
0.00033 rad), and the axis label says which. Lines and markers carry SVG ids (matplotlib's
``gid``): ``series-<label>`` for a series, ``event-<label>`` and ``event-label-<label>`` for an
:class:`Event`'s line and text, ``level-<label>`` for a :class:`Level` (a second line of the same
label ``level-<label>-2``), ``step-*`` for a step figure's marks (:func:`plot_step`); ``<label>`` in
lower case, each run of characters other than letters and digits one ``-`` (:func:`marker_id`).
Traces longer than :data:`MAX_POINTS` are drawn through the minimum and maximum of each of
``MAX_POINTS / 2`` slices, which a 700 px wide axis shows as the whole trace, at a fraction of the
file size.

Within :func:`not_drawn` the plot functions check their data and return the path they would have
written, drawing nothing: for runs whose numbers are wanted and not their pictures (a sweep's
thousand runs, where drawing would cost more than the physics).
"""

from __future__ import annotations

import os
import re
import threading
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.transforms import blended_transform_factory
from numpy.typing import ArrayLike

from jointctl.recording.units import DisplayScale, display_scale, label

__all__ = ["DPI", "FIGSIZE_IN", "MAX_POINTS", "Event", "Level", "Panel", "StepMarks", "marker_id", "new_figure",
           "not_drawn", "plot_command_and_position", "plot_panels", "plot_series", "plot_step", "save_figure"]

FIGSIZE_IN = (8.0, 4.5)
DPI = 110
_METADATA = {"Software": None}  # keep the matplotlib version out of the file
_SVG_METADATA = {"Creator": None, "Date": None}  # nor the version or the date in the SVG
#: matplotlib reads the SVG settings from its global rcParams while it writes: set them around the
#: write, one figure at a time (text as text; ids from a fixed salt, so the same data give the same file).
_SVG_RC = {"svg.fonttype": "none", "svg.hashsalt": "jointctl"}
_SVG_LOCK = threading.Lock()
#: Samples of one line above which it is drawn through each slice's minimum and maximum.
MAX_POINTS = 4000
#: A limit line is drawn inside the axis when it lies within this share of the data's span beyond
#: the data; farther away it would squash them, and its legend entry says it is off the axis.
LIMIT_REACH = 0.5
#: A legend of more entries than this goes beside its axis.
LEGEND_INSIDE = 6

_EVENT_COLORS = {"spawn": "tab:purple", "contact": "tab:red", "goal": "tab:gray", "rejected": "tab:orange"}
_LEVEL_STYLES = {"limit": {"color": "tab:red", "linestyle": "--", "linewidth": 1.0},
                 "expected": {"color": "black", "linestyle": ":", "linewidth": 1.2}}


@dataclass(frozen=True)
class Event:
    """A moment of the run drawn as a labelled vertical line on every axis of a figure:
    ``time_s`` [s], ``label`` (e.g. "weight spawned"), ``kind`` choosing its colour: "spawn",
    "contact", "goal", "rejected" or anything else (grey)."""

    time_s: float
    label: str
    kind: str = "event"


@dataclass(frozen=True)
class Level:
    """A horizontal line at ``value`` (in the axis' SI unit) with a legend ``label``.

    ``kind`` "limit" (red, dashed; e.g. an effort limit) is drawn inside the axis only when it lies
    within :data:`LIMIT_REACH` of the data's span beyond them (its legend entry says "off the axis"
    when no line of that label is); "expected" (black, dotted; e.g. the expected final value) is
    always shown. Lines sharing a label share one legend entry. ``series``: the label of the
    series whose colour the line takes (the joint whose limit it is), None for the kind's colour."""

    value: float
    label: str
    kind: str = "limit"
    series: str | None = None


@dataclass(frozen=True)
class Panel:
    """One axis of a figure.

    ``series``: legend label -> samples (as many as the figure's times), drawn in insertion order;
    ``ylabel`` the quantity shown and ``unit`` the samples' SI unit: the axis reads
    ``"ylabel [unit]"`` with the prefix chosen for the values shown (``unit`` None: ``ylabel`` is
    the whole label and the values are shown as they are); ``levels`` horizontal lines in the same
    unit; ``styles`` matplotlib line properties by series label (e.g. ``{"drawstyle": "steps-post"}``
    for a held command); ``height`` the axis' share of the figure's height."""

    series: Mapping[str, ArrayLike]
    ylabel: str
    unit: str | None = None
    levels: Sequence[Level] = ()
    styles: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    height: float = 1.0


@dataclass(frozen=True)
class StepMarks:
    """What a step figure marks, in the response's SI unit and seconds of the record.

    ``step_time_s`` when the reference stepped; ``initial_value`` and ``final_value`` the response
    before and after (measured); ``settle_band`` the settling band's half-width as a share of the
    step (0.02: ±2 %, drawn about ``final_value`` from the step on); ``overshoot_pct`` and the peak
    (``peak_time_s``, ``peak_value``); the rise from 10 % to 90 % of the step (``rise_start_s``,
    ``rise_end_s``; None if not reached); ``settling_time_s`` how long after the step it entered the
    band for good (None if it never did); ``expected_final`` the theory's final value (None without
    one). ``peak_time_s``, ``rise_start_s`` and ``rise_end_s`` are times of the record [s],
    ``settling_time_s`` a duration after the step [s]. A response that did not settle has no
    ``final_value`` (None): no band, overshoot or rise is drawn, and the legend says it did not
    settle."""

    step_time_s: float
    initial_value: float
    final_value: float | None
    settle_band: float
    overshoot_pct: float | None
    peak_time_s: float
    peak_value: float
    rise_start_s: float | None
    rise_end_s: float | None
    settling_time_s: float | None
    expected_final: float | None = None


#: False within :func:`not_drawn` (per thread and task: a context variable).
_DRAWING: ContextVar[bool] = ContextVar("jointctl_figures_drawing", default=True)


@contextmanager
def not_drawn() -> Iterator[None]:
    """Within this block the plot functions draw and write nothing (they still check their data)."""
    token = _DRAWING.set(False)
    try:
        yield
    finally:
        _DRAWING.reset(token)


def marker_id(prefix: str, text: str) -> str:
    """The SVG id of a marker: ``prefix-text`` in lower case, every run of characters other than
    ASCII letters and digits as one ``-`` (``marker_id("event", "weight spawned")`` is
    ``"event-weight-spawned"``)."""
    slug = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")
    return f"{prefix}-{slug}" if slug else prefix


def _times(time_s: ArrayLike) -> np.ndarray:
    t = np.asarray(time_s, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError("time_s must be a non-empty 1-D array")
    return t


def _curves(
    time_s: ArrayLike, series: Mapping[str, ArrayLike]
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    t = _times(time_s)
    out: dict[str, np.ndarray] = {}
    for name, values in series.items():
        y = np.asarray(values, dtype=float)
        if y.shape != t.shape:
            raise ValueError(f"series {name!r} has shape {y.shape}, time_s has {t.shape}")
        out[name] = y
    if not out:
        raise ValueError("nothing to plot: no series given")
    return t, out


def _window(t: np.ndarray, zoom: tuple[float, float] | None) -> tuple[np.ndarray, np.ndarray]:
    """(samples inside ``zoom``, samples drawn: those and one more each side so lines reach the edges)."""
    if zoom is None:
        everything = np.ones(t.shape, dtype=bool)
        return everything, everything
    t0, t1 = float(zoom[0]), float(zoom[1])
    if not t1 > t0:
        raise ValueError(f"zoom must be (t0, t1) with t1 > t0, got {zoom!r}")
    visible = (t >= t0) & (t <= t1)
    drawn = visible.copy()
    inside = np.flatnonzero(visible)
    if inside.size:
        drawn[max(inside[0] - 1, 0)] = drawn[min(inside[-1] + 1, t.size - 1)] = True
    return visible, drawn


def _decimated(t: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """``(t, y)`` through the first and last sample and each slice's minimum and maximum when longer
    than ``max_points`` (a trace with gaps, NaN, is kept whole)."""
    n = t.size
    if n <= max_points or not np.all(np.isfinite(y)):
        return t, y
    size = -(-n // max(1, max_points // 2))
    slices = -(-n // size)
    padded = np.pad(y, (0, slices * size - n), mode="edge").reshape(slices, size)
    offsets = np.arange(slices) * size
    keep = np.zeros(n, dtype=bool)
    keep[[0, n - 1]] = True
    keep[np.minimum(offsets + np.argmin(padded, axis=1), n - 1)] = True
    keep[np.minimum(offsets + np.argmax(padded, axis=1), n - 1)] = True
    return t[keep], y[keep]


def _largest(curves: Mapping[str, np.ndarray], visible: np.ndarray) -> float:
    values = [np.abs(y[visible & np.isfinite(y)]) for y in curves.values()]
    values = [v for v in values if v.size]
    return max((float(v.max()) for v in values), default=0.0)


def _draw_panel(ax: Axes, t: np.ndarray, panel: Panel, zoom: tuple[float, float] | None,
                markers: bool = False) -> DisplayScale:
    """Draw ``panel`` on ``ax``: its series (scaled to the prefix chosen for what is visible), its
    y label with the unit shown, its levels; the y axis fitted to the visible samples."""
    t, curves = _curves(t, panel.series)
    visible, drawn = _window(t, zoom)
    unit = panel.unit
    scale = display_scale(unit, _largest(curves, visible)) if unit is not None else DisplayScale("", 1.0, "")
    ax.set_ylabel(label(panel.ylabel, scale.shown) if unit is not None else panel.ylabel)
    if unit is not None:
        ax.ticklabel_format(axis="y", useOffset=False)
    base = {"marker": "o", "markersize": 4, "linewidth": 0.8} if markers else {}
    lo, hi = np.inf, -np.inf
    colors: dict[str, str] = {}
    for name, y in curves.items():
        shown = scale(y)
        td, yd = _decimated(t[drawn], shown[drawn])
        line = ax.plot(td, yd, label=name, gid=marker_id("series", name), **{**base, **panel.styles.get(name, {})})
        colors[name] = line[0].get_color()
        seen = shown[visible & np.isfinite(shown)]
        if seen.size:
            lo, hi = min(lo, float(seen.min())), max(hi, float(seen.max()))
    if zoom is not None:
        ax.set_xlim(float(zoom[0]), float(zoom[1]))
    if np.isfinite(lo):
        for level in panel.levels:
            if level.kind != "limit":
                lo, hi = min(lo, scale(level.value)), max(hi, scale(level.value))
        reach = LIMIT_REACH * (hi - lo)
        inside = {level.label for level in panel.levels
                  if level.kind == "limit" and lo - reach <= scale(level.value) <= hi + reach}
        for level in panel.levels:
            if level.label in inside:
                lo, hi = min(lo, scale(level.value)), max(hi, scale(level.value))
        pad = 0.05 * (hi - lo) if hi > lo else max(1e-9, 0.05 * abs(hi))
        ax.set_ylim(lo - pad, hi + pad)
        _draw_levels(ax, panel.levels, scale, inside, colors)
    return scale


def _draw_levels(ax: Axes, levels: Sequence[Level], scale: DisplayScale, inside: set[str],
                 colors: Mapping[str, str]) -> None:
    """Each level as a horizontal line (in its series' colour, if it names one). Limits not
    ``inside`` the axis keep their line (and SVG id) but share one legend entry saying so."""
    outside = list(dict.fromkeys(level.label for level in levels if level.kind == "limit"
                                 and level.label not in inside))
    if len(outside) == 1:
        summary = {outside[0]: f"{outside[0]} (off the axis)"}
    else:  # several: one entry listing them
        summary = {text: "off the axis:\n" + "\n".join(outside) for text in outside}
    labelled: set[str] = set()
    ids: dict[str, int] = {}
    for level in levels:
        text = summary.get(level.label, level.label)
        gid = marker_id("level", level.label)
        ids[gid] = ids.get(gid, 0) + 1
        style = dict(_LEVEL_STYLES.get(level.kind, _LEVEL_STYLES["limit"]))
        if level.series in colors:
            style["color"] = colors[level.series]
        ax.axhline(scale(level.value), label=None if text in labelled else text,
                   gid=gid if ids[gid] == 1 else f"{gid}-{ids[gid]}", **style)
        labelled.add(text)


def _draw_events(axes: Sequence[Axes], events: Sequence[Event], zoom: tuple[float, float] | None) -> None:
    """Each event as a vertical line on every axis, its label written along the line at the top of
    the first axis; events outside ``zoom`` are left out."""
    seen: dict[str, int] = {}
    for event in sorted(events, key=lambda e: e.time_s):
        if zoom is not None and not zoom[0] <= event.time_s <= zoom[1]:
            continue
        gid = marker_id("event", event.label)
        seen[gid] = seen.get(gid, 0) + 1
        if seen[gid] > 1:
            gid = f"{gid}-{seen[gid]}"
        color = _EVENT_COLORS.get(event.kind, "tab:gray")
        for k, ax in enumerate(axes):
            ax.axvline(event.time_s, color=color, linestyle="-.", linewidth=1.0, alpha=0.8,
                       gid=gid if k == 0 else f"{gid}-{k}")
        top = axes[0]
        top.text(event.time_s, 0.98, f" {event.label}", rotation=90, ha="right", va="top", fontsize=8,
                 color=color, transform=blended_transform_factory(top.transData, top.transAxes),
                 bbox={"facecolor": "white", "alpha": 0.7, "edgecolor": "none", "pad": 1.0},
                 gid=gid.replace("event-", "event-label-", 1))


def _new_figure(title: str, heights: Sequence[float], size_in: tuple[float, float] = FIGSIZE_IN
                ) -> tuple[Figure, list[Axes]]:
    fig, axes = new_figure(heights, size_in)
    axes[0].set_title(title)
    axes[-1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, which="major", alpha=0.4)
        ax.grid(False, which="minor")
    return fig, axes


def new_figure(heights: Sequence[float], size_in: tuple[float, float] = FIGSIZE_IN) -> tuple[Figure, list[Axes]]:
    """A figure (no pyplot: safe from any thread) of panels one above the other sharing x, gridded."""
    fig = Figure(figsize=size_in, dpi=DPI)
    FigureCanvasAgg(fig)
    axes = list(np.atleast_1d(fig.subplots(len(heights), 1, sharex=True, squeeze=False,
                                           gridspec_kw={"height_ratios": list(heights)})[:, 0]))
    for ax in axes:
        ax.grid(True, which="both", alpha=0.4)
    return fig, axes


def save_figure(fig: Figure, axes: Sequence[Axes], path: str | os.PathLike[str]) -> Path:
    """The PNG at ``path`` and the SVG beside it (text kept as text), legends placed first."""
    return _save(fig, axes, path)


def _save(fig: Figure, axes: Sequence[Axes], path: str | os.PathLike[str]) -> Path:
    """The PNG at ``path`` and the SVG beside it, legends placed first."""
    for ax in axes:
        handles, _ = ax.get_legend_handles_labels()
        if handles:
            if len(handles) > LEGEND_INSIDE:  # beside the axis, where it hides nothing
                ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0.0)
            else:
                ax.legend(loc="best", fontsize=8 if len(handles) > 4 else None)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=DPI, format="png", metadata=_METADATA)
    with _SVG_LOCK, matplotlib.rc_context(_SVG_RC):
        fig.savefig(out.with_suffix(".svg"), dpi=DPI, format="svg", metadata=_SVG_METADATA)
    return out


def plot_panels(
    path: str | os.PathLike[str],
    time_s: ArrayLike,
    panels: Sequence[Panel],
    *,
    title: str,
    zoom: tuple[float, float] | None = None,
    events: Sequence[Event] = (),
    markers: bool = False,
    size_in: tuple[float, float] | None = None,
) -> Path:
    """Save a PNG (and its SVG) of one or more axes above each other sharing the time axis.

    Args:
        path: output PNG file; parent folders are created; the SVG is ``path`` with ``.svg``.
        time_s: sample times [s] of every panel's series.
        panels: the axes, top first (:class:`Panel`).
        title: figure title.
        zoom: optional (t0, t1) [s] limiting the x axis; each y axis is fitted to the data inside it.
        events: moments marked on every axis (:class:`Event`).
        markers: draw each sample as a dot joined by thin lines (for sparse points).
        size_in: figure size [in]; default 8 x 4.5 for one panel, 2 in taller for each more.

    Returns:
        ``path`` as a :class:`pathlib.Path`.
    """
    if not panels:
        raise ValueError("nothing to plot: no panels given")
    t = _times(time_s)
    for panel in panels:
        _curves(t, panel.series)  # every panel checked before anything is drawn
    _window(t, zoom)
    if not _DRAWING.get():
        return Path(path)
    size = size_in or (FIGSIZE_IN[0], FIGSIZE_IN[1] + 2.0 * (len(panels) - 1))
    fig, axes = _new_figure(title, [p.height for p in panels], size)
    for ax, panel in zip(axes, panels):
        _draw_panel(ax, t, panel, zoom, markers)
    _draw_events(axes, events, zoom)
    return _save(fig, axes, path)


def plot_command_and_position(
    path: str | os.PathLike[str],
    time_s: ArrayLike,
    command: ArrayLike,
    position: ArrayLike,
    *,
    title: str,
    unit: str | None,
    ylabel: str = "position",
    command_label: str = "reference",
    position_label: str = "position",
    zoom: tuple[float, float] | None = None,
    events: Sequence[Event] = (),
    levels: Sequence[Level] = (),
) -> Path:
    """Save a PNG (and its SVG) of a command (drawn as held steps) and the measured position.

    Args:
        path: output PNG file; parent folders are created.
        time_s: sample times [s].
        command, position: signals in SI ``unit`` ("m", "rad", "m/s"...; the axis reads
            ``ylabel [unit]`` with a prefix chosen for their range; None: ``ylabel`` says it all).
        title: figure title.
        zoom: optional (t0, t1) [s] limiting the x axis; the y axis is fitted
            to the data inside it.
        events, levels: vertical markers and horizontal lines (:class:`Event`, :class:`Level`).

    Returns:
        ``path`` as a :class:`pathlib.Path`.
    """
    if command_label == position_label:
        raise ValueError("command_label and position_label must differ")
    panel = Panel({command_label: command, position_label: position}, ylabel, unit, levels,
                  styles={command_label: {"drawstyle": "steps-post"}})
    return plot_panels(path, time_s, [panel], title=title, zoom=zoom, events=events)


def plot_series(
    path: str | os.PathLike[str],
    time_s: ArrayLike,
    series: Mapping[str, ArrayLike],
    *,
    title: str,
    ylabel: str,
    unit: str | None = None,
    zoom: tuple[float, float] | None = None,
    markers: bool = False,
    events: Sequence[Event] = (),
    levels: Sequence[Level] = (),
) -> Path:
    """Save a PNG (and its SVG) of several series (effort, velocity...) against time on one axis.

    Args:
        path: output PNG file; parent folders are created.
        time_s: sample times [s].
        series: legend label -> samples, drawn in insertion order.
        title: figure title.
        ylabel: the quantity, e.g. ``"effort"``, with ``unit`` its SI unit (``"N"``): the axis
            reads ``effort [N]`` or ``effort [kN]``, as the values' range asks; without ``unit``,
            ``ylabel`` is the whole label (e.g. ``"effort [N]"``) and the values are shown as given.
        zoom: optional (t0, t1) [s] limiting the x axis.
        markers: draw each sample as a dot joined by thin lines (for sparse points).
        events, levels: vertical markers and horizontal lines (:class:`Event`, :class:`Level`).

    Returns:
        ``path`` as a :class:`pathlib.Path`.
    """
    return plot_panels(path, time_s, [Panel(series, ylabel, unit, levels)], title=title, zoom=zoom,
                       events=events, markers=markers)


def plot_step(
    path: str | os.PathLike[str],
    time_s: ArrayLike,
    command: ArrayLike,
    position: ArrayLike,
    *,
    title: str,
    unit: str,
    marks: StepMarks,
    theory: ArrayLike | None = None,
    theory_label: str = "linear theory",
    zoom: tuple[float, float] | None = None,
    events: Sequence[Event] = (),
) -> Path:
    """Save a PNG (and its SVG) of a step response read the way a control engineer reads one.

    Drawn: the command (held steps), the measured position, the ``theory`` response (same times,
    dashed; None: none), the ±band about the measured final value from the step on
    (``step-settling-band``), the expected final value (``level-expected-final-value``), the
    overshoot's peak and its size (``step-overshoot``), the 10-90 % rise (``step-rise-time``) and
    the settling time (``step-settling-time``), all in SI ``unit`` (see :class:`StepMarks`).

    Returns:
        ``path`` as a :class:`pathlib.Path`.
    """
    series = {"reference": command, "position": position}
    styles: dict[str, dict[str, Any]] = {"reference": {"drawstyle": "steps-post"}}
    if theory is not None:
        series[theory_label] = theory
        styles[theory_label] = {"linestyle": "--", "linewidth": 1.2, "color": "tab:green"}
    levels = ([Level(marks.expected_final, "expected final value", "expected")]
              if marks.expected_final is not None else [])
    t = _times(time_s)
    panel = Panel(series, "position", unit, levels, styles)
    _curves(t, series)
    _window(t, zoom)
    if not _DRAWING.get():
        return Path(path)
    fig, axes = _new_figure(title, [1.0])
    ax = axes[0]
    scale = _draw_panel(ax, t, panel, zoom)
    _mark_step(ax, scale, marks, float(zoom[1]) if zoom is not None else float(t[-1]))
    _draw_events(axes, events, zoom)
    return _save(fig, axes, path)


def _duration(seconds: float) -> str:
    return f"{1e3 * seconds:.3g} ms" if abs(seconds) < 1.0 else f"{seconds:.3g} s"


def _mark_step(ax: Axes, scale: DisplayScale, marks: StepMarks, end_s: float) -> None:
    if marks.final_value is None:  # no steady state: nothing to draw a band, an overshoot or a rise about
        ax.plot([], [], linestyle="none", label="not settled: no final value", gid="step-not-settled")
        return
    step = marks.final_value - marks.initial_value
    half = abs(marks.settle_band * step)
    band = ax.fill_between([marks.step_time_s, max(end_s, marks.step_time_s)],
                           scale(marks.final_value - half), scale(marks.final_value + half),
                           color="tab:orange", alpha=0.25, linewidth=0,
                           label=f"±{100 * marks.settle_band:g} % settling band")
    band.set_gid("step-settling-band")
    if marks.overshoot_pct is not None and marks.overshoot_pct > 0:
        peak = ax.plot([marks.peak_time_s], [scale(marks.peak_value)], marker="v", color="tab:red",
                       linestyle="none", label=f"overshoot {marks.overshoot_pct:.3g} %")[0]
        peak.set_gid("step-overshoot")
        ax.annotate("", xy=(marks.peak_time_s, scale(marks.peak_value)),
                    xytext=(marks.peak_time_s, scale(marks.final_value)),
                    arrowprops={"arrowstyle": "<->", "color": "tab:red", "linewidth": 0.8})
    if marks.rise_start_s is not None and marks.rise_end_s is not None:
        levels = scale(marks.initial_value + np.array([0.1, 0.9]) * step)
        rise = ax.plot([marks.rise_start_s, marks.rise_end_s], levels, marker="o", markersize=4,
                       color="tab:purple", linestyle="none",
                       label=f"rise 10-90 %: {_duration(marks.rise_end_s - marks.rise_start_s)}")[0]
        rise.set_gid("step-rise-time")
        middle = scale(marks.initial_value + 0.5 * step)
        ax.annotate("", xy=(marks.rise_end_s, middle), xytext=(marks.rise_start_s, middle),
                    arrowprops={"arrowstyle": "<->", "color": "tab:purple", "linewidth": 0.8})
    if marks.settling_time_s is not None:
        ax.axvline(marks.step_time_s + marks.settling_time_s, color="tab:orange", linestyle=":", linewidth=1.2,
                   label=f"settled ({100 * marks.settle_band:g} %) after {_duration(marks.settling_time_s)}",
                   gid="step-settling-time")

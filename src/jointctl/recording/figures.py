"""PNG figures of recorded traces, in the spirit of rqt_plot screenshots.

Uses :class:`matplotlib.figure.Figure` with the Agg canvas directly: no pyplot,
no global state, safe to call from any thread or without a display. Every
figure is 8 x 4.5 in at 110 dpi (880 x 495 px), with a grid, labelled axes
and a legend; nothing time-dependent is written into the image or its PNG
metadata, so the same data give the same file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

__all__ = ["DPI", "FIGSIZE_IN", "plot_command_and_position", "plot_series"]

FIGSIZE_IN = (8.0, 4.5)
DPI = 110
_METADATA = {"Software": None}  # keep the matplotlib version out of the file


def _curves(
    time_s: ArrayLike, series: Mapping[str, ArrayLike]
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    t = np.asarray(time_s, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError("time_s must be a non-empty 1-D array")
    out: dict[str, np.ndarray] = {}
    for name, values in series.items():
        y = np.asarray(values, dtype=float)
        if y.shape != t.shape:
            raise ValueError(f"series {name!r} has shape {y.shape}, time_s has {t.shape}")
        out[name] = y
    if not out:
        raise ValueError("nothing to plot: no series given")
    return t, out


def _new_axes(title: str, ylabel: str) -> tuple[Figure, Axes]:
    fig = Figure(figsize=FIGSIZE_IN, dpi=DPI)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.set_title(title)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.4)
    return fig, ax


def _apply_zoom(
    ax: Axes, t: np.ndarray, curves: Mapping[str, np.ndarray], zoom: tuple[float, float] | None
) -> None:
    """Limit the x axis to ``zoom`` [s] and fit the y axis to the visible data."""
    if zoom is None:
        return
    t0, t1 = float(zoom[0]), float(zoom[1])
    if not t1 > t0:
        raise ValueError(f"zoom must be (t0, t1) with t1 > t0, got {zoom!r}")
    ax.set_xlim(t0, t1)
    visible = (t >= t0) & (t <= t1)
    if visible.any():
        lo = min(float(np.min(y[visible])) for y in curves.values())
        hi = max(float(np.max(y[visible])) for y in curves.values())
        pad = 0.05 * (hi - lo) if hi > lo else max(1e-9, 0.05 * abs(hi))
        ax.set_ylim(lo - pad, hi + pad)


def _save(fig: Figure, ax: Axes, path: str | os.PathLike[str]) -> Path:
    ax.legend(loc="best")
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=DPI, format="png", metadata=_METADATA)
    return out


def plot_command_and_position(
    path: str | os.PathLike[str],
    time_s: ArrayLike,
    command: ArrayLike,
    position: ArrayLike,
    *,
    title: str,
    ylabel: str = "position [m]",
    command_label: str = "reference",
    position_label: str = "position",
    zoom: tuple[float, float] | None = None,
) -> Path:
    """Save a PNG of a command (drawn as held steps) and the measured position.

    Args:
        path: output PNG file; parent folders are created.
        time_s: sample times [s].
        command, position: signals in the units named by ``ylabel``.
        title: figure title.
        zoom: optional (t0, t1) [s] limiting the x axis; the y axis is fitted
            to the data inside it.

    Returns:
        ``path`` as a :class:`pathlib.Path`.
    """
    if command_label == position_label:
        raise ValueError("command_label and position_label must differ")
    t, curves = _curves(time_s, {command_label: command, position_label: position})
    fig, ax = _new_axes(title, ylabel)
    ax.plot(t, curves[command_label], drawstyle="steps-post", label=command_label)
    ax.plot(t, curves[position_label], label=position_label)
    _apply_zoom(ax, t, curves, zoom)
    return _save(fig, ax, path)


def plot_series(
    path: str | os.PathLike[str],
    time_s: ArrayLike,
    series: Mapping[str, ArrayLike],
    *,
    title: str,
    ylabel: str,
    zoom: tuple[float, float] | None = None,
    markers: bool = False,
) -> Path:
    """Save a PNG of several series (effort, velocity...) against time on one axis.

    Args:
        path: output PNG file; parent folders are created.
        time_s: sample times [s].
        series: legend label -> samples, drawn in insertion order.
        title: figure title.
        ylabel: y-axis label with units, e.g. ``"effort [N]"``.
        zoom: optional (t0, t1) [s] limiting the x axis.
        markers: draw each sample as a dot joined by thin lines (for sparse points).

    Returns:
        ``path`` as a :class:`pathlib.Path`.
    """
    t, curves = _curves(time_s, series)
    fig, ax = _new_axes(title, ylabel)
    style = {"marker": "o", "markersize": 4, "linewidth": 0.8} if markers else {}
    for name, y in curves.items():
        ax.plot(t, y, label=name, **style)
    _apply_zoom(ax, t, curves, zoom)
    return _save(fig, ax, path)

"""Read a figure back from the SVG jointctl writes beside each PNG: its texts, its axes' labels and
legends, and where a marker (an element with an id) sits, in data coordinates read off the ticks."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

SVG = "{http://www.w3.org/2000/svg}"
XLINK = "{http://www.w3.org/1999/xlink}"
#: A tick axis' multiplier or offset text (``1e−5``, ``+1.2``, ``×10⁻³``).
NUMBER = re.compile(r"[−+\-]?[\d.]*(e[−+\-]?\d+|×10\S*)?")


def _number(text: str) -> float:
    return float(text.replace("\u2212", "-"))


def _text(element: ET.Element) -> str:
    return "".join(element.itertext()).strip()


class SvgAxes:
    """One ``axes_N`` group: its labels, legend and tick positions."""

    def __init__(self, element: ET.Element) -> None:
        self.element = element
        axis = [g for g in element if g.get("id", "").startswith("matplotlib.axis")]
        x_axis, y_axis = sorted(axis, key=lambda g: int(g.get("id").rsplit("_", 1)[1]))  # x first, then y
        self.xlabel = self._label(x_axis, "xtick")
        self.ylabel = self._label(y_axis, "ytick")
        self.xticks = self._ticks(x_axis, "xtick", "x")
        self.yticks = self._ticks(y_axis, "ytick", "y")
        legend = next((g for g in element if g.get("id", "").startswith("legend")), None)
        self.legend = [_text(t) for t in legend.iter(f"{SVG}text")] if legend is not None else []

    @staticmethod
    def _label(axis: ET.Element, tick: str) -> str:
        """The axis' label: its text outside the ticks that is not a multiplier or offset (``1e−5``)."""
        texts = [_text(t) for g in axis if not g.get("id", "").startswith(tick) for t in g.iter(f"{SVG}text")]
        return " ".join(t for t in texts if not NUMBER.fullmatch(t))

    @staticmethod
    def _ticks(axis: ET.Element, tick: str, coordinate: str) -> tuple[np.ndarray, np.ndarray]:
        """(pixel positions, values) of the labelled ticks."""
        pixels, values = [], []
        for group in axis:
            if not group.get("id", "").startswith(tick):
                continue
            use = next(group.iter(f"{SVG}use"))
            text = next(group.iter(f"{SVG}text"), None)
            if text is None or not _text(text):
                continue
            pixels.append(float(use.get(coordinate)))
            values.append(_number(_text(text)))
        return np.array(pixels), np.array(values)

    def x_value(self, pixel: float) -> float:
        """The data x (time [s]) at an SVG x coordinate, by a straight line through the ticks."""
        slope, offset = np.polyfit(*self.xticks, 1)
        return float(slope * pixel + offset)

    def y_value(self, pixel: float) -> float:
        """The data y (in the axis' shown unit) at an SVG y coordinate."""
        slope, offset = np.polyfit(*self.yticks, 1)
        return float(slope * pixel + offset)

    def ids(self) -> set[str]:
        return {e.get("id") for e in self.element.iter() if e.get("id")}


class SvgFigure:
    """A saved figure's SVG: ``texts`` (every text element's string), ``axes`` (top first)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.root = ET.parse(self.path).getroot()
        self.texts = [_text(t) for t in self.root.iter(f"{SVG}text")]
        self.axes = [SvgAxes(g) for g in self.root.iter(f"{SVG}g") if re.fullmatch(r"axes_\d+", g.get("id", ""))]

    def element(self, gid: str) -> ET.Element:
        found = [e for e in self.root.iter() if e.get("id") == gid]
        assert found, f"no element with id {gid!r} in {self.path.name}"
        return found[0]

    def ids(self) -> set[str]:
        return {e.get("id") for e in self.root.iter() if e.get("id")}

    def vertical_line_x(self, gid: str) -> float:
        """The SVG x of the vertical line (an axvline) with id ``gid``."""
        path = next(self.element(gid).iter(f"{SVG}path"))
        xs = [float(x) for x in re.findall(r"[ML]\s*([-\d.]+)\s", path.get("d"))]
        assert xs and max(xs) - min(xs) < 1e-6, f"{gid} is not a vertical line"
        return xs[0]

    def horizontal_line_y(self, gid: str) -> float:
        """The SVG y of the horizontal line (an axhline) with id ``gid``."""
        path = next(self.element(gid).iter(f"{SVG}path"))
        ys = [float(y) for y in re.findall(r"[ML]\s*[-\d.]+\s+([-\d.]+)", path.get("d"))]
        assert ys and max(ys) - min(ys) < 1e-6, f"{gid} is not a horizontal line"
        return ys[0]

    def text_of(self, gid: str) -> str:
        return _text(self.element(gid))

"""Figures: PNG and SVG written, right pixel size, deterministic; units, prefixes and markers read back
from the SVG (text kept as text, markers found by their ids, positions read off the axis' ticks)."""

from __future__ import annotations

import dataclasses
import math
import re

import matplotlib.image as mpimg
import numpy as np
import pytest

from jointctl.recording.figures import (DPI, FIGSIZE_IN, MAX_POINTS, Event, Level, Panel, StepMarks, _decimated,
                                       not_drawn, plot_command_and_position, plot_panels, plot_series, plot_step)
from tests.recording.svg_figure import SvgFigure

PIXELS = (round(FIGSIZE_IN[1] * DPI), round(FIGSIZE_IN[0] * DPI))  # (rows, cols)


@pytest.fixture
def trace():
    t = np.arange(3000) * 1e-3
    command = np.where(t < 0.5, -0.2, -0.5)
    position = -0.5 + 0.3 * np.exp(-5 * np.clip(t - 0.5, 0, None)) * np.cos(
        19 * np.clip(t - 0.5, 0, None)
    )
    position[t < 0.5] = -0.2
    return t, command, position


def test_pixel_size_is_880_by_495():
    assert PIXELS == (495, 880)


def test_command_and_position_png(tmp_path, trace):
    t, command, position = trace
    out = tmp_path / "sub" / "step.png"
    returned = plot_command_and_position(out, t, command, position, title="Step, Kp = 400", unit="m")
    assert returned == out
    assert out.stat().st_size > 1000
    image = mpimg.imread(out)
    assert image.shape[:2] == PIXELS
    assert np.ptp(image[..., :3]) > 0.5  # something was drawn


def test_zoom_changes_the_picture(tmp_path, trace):
    t, command, position = trace
    full = plot_command_and_position(tmp_path / "full.png", t, command, position, title="s", unit="m")
    zoom = plot_command_and_position(
        tmp_path / "zoom.png", t, command, position, title="s", zoom=(0.45, 0.8),
        unit="rad", command_label="ref", position_label="joint1",
    )
    assert mpimg.imread(zoom).shape[:2] == PIXELS
    assert full.read_bytes() != zoom.read_bytes()
    with pytest.raises(ValueError, match="zoom"):
        plot_command_and_position(tmp_path / "bad.png", t, command, position, title="s", unit="m",
                                  zoom=(1.0, 0.5))


def test_plot_series_png(tmp_path):
    t = np.arange(2000) * 1e-3
    series = {
        "effort (Kp=100)": 5 * np.sin(2 * math.pi * t),
        "effort (Kp=400)": 8 * np.sin(2 * math.pi * t + 0.3),
        "gravity": np.full_like(t, 9.81),
    }
    out = plot_series(str(tmp_path / "effort.png"), t, series, title="Effort",
                      ylabel="effort [N]", zoom=(0.2, 0.6))
    assert out.stat().st_size > 1000
    assert mpimg.imread(out).shape[:2] == PIXELS


def test_figures_are_deterministic(tmp_path, trace):
    t, command, position = trace
    a = plot_command_and_position(tmp_path / "a.png", t, command, position, title="same", unit="m")
    b = plot_command_and_position(tmp_path / "b.png", t, command, position, title="same", unit="m")
    assert a.read_bytes() == b.read_bytes()
    assert b"matplotlib" not in a.read_bytes()  # no version stamp in the metadata
    svg_a, svg_b = a.with_suffix(".svg").read_bytes(), b.with_suffix(".svg").read_bytes()
    assert svg_a == svg_b  # ids from a fixed salt, no date
    assert b"matplotlib v" not in svg_a.lower() and b"<dc:date>" not in svg_a


def test_bad_input(tmp_path, trace):
    t, command, position = trace
    with pytest.raises(ValueError, match="shape"):
        plot_series(tmp_path / "x.png", t, {"v": position[:-1]}, title="v", ylabel="v [m/s]")
    with pytest.raises(ValueError, match="no series"):
        plot_series(tmp_path / "x.png", t, {}, title="v", ylabel="v [m/s]")
    with pytest.raises(ValueError, match="differ"):
        plot_command_and_position(tmp_path / "x.png", t, command, position, title="s", unit="m",
                                  command_label="x", position_label="x")
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "x.svg").exists()
    plot_series(tmp_path / "x.png", t, {"v": position}, title="v", ylabel="v [m/s]")
    assert (tmp_path / "x.png").exists()  # where the refused calls would have written, a good one does


# -- read back from the SVG ------------------------------------------------------------------------------

def test_the_svg_beside_the_png_keeps_its_text_as_text(tmp_path, trace):
    t, command, position = trace
    png = plot_command_and_position(tmp_path / "step.png", t, command, position, title="Step, Kp = 400", unit="m")
    svg = SvgFigure(png.with_suffix(".svg"))
    assert "Step, Kp = 400" in svg.texts
    (axes,) = svg.axes
    assert axes.xlabel == "time [s]"
    assert axes.ylabel == "position [m]"
    assert axes.legend == ["reference", "position"]


@pytest.mark.parametrize("unit, largest, shown, top", [
    ("rad", 3.3e-4, "µrad", 330.0),  # the arm's tracking error: 330 µrad, not 0.00033 rad
    ("rad", 0.004, "mrad", 4.0),
    ("m", 0.02, "mm", 20.0),
    ("m", 0.5, "m", 0.5),            # a stroke stays in m
    ("N", 4800.0, "kN", 4.8),        # an impact in kN
    ("N·m", 150.0, "N·m", 150.0),
])
def test_the_axis_shows_the_unit_with_the_prefix_of_the_values_range(tmp_path, unit, largest, shown, top):
    t = np.arange(1000) * 1e-3
    values = -largest * np.sin(math.pi * t)  # reaches -largest at 0.5 s
    svg = SvgFigure(plot_series(tmp_path / "e.png", t, {"e": values}, title="e", ylabel="error", unit=unit)
                    .with_suffix(".svg"))
    (axes,) = svg.axes
    assert axes.ylabel == f"error [{shown}]"
    pixels, ticks = axes.yticks
    assert -top * 1.15 <= ticks.min() <= -top * 0.9  # the ticks are in the shown unit: the data reach -top
    assert 1e-3 < np.max(np.abs(ticks)) < 1000


def test_events_are_labelled_vertical_lines_at_their_time(tmp_path):
    t = np.arange(3000) * 1e-3
    events = [Event(0.5, "weight spawned", "spawn"), Event(1.25, "weight impact", "contact"),
              Event(2.0, "goal start", "goal"), Event(2.0, "goal start", "goal")]
    png = plot_series(tmp_path / "f.png", t, {"force": np.sin(t)}, title="f", ylabel="force", unit="N",
                      events=events)
    svg = SvgFigure(png.with_suffix(".svg"))
    axes = svg.axes[0]
    for gid, time_s in (("event-weight-spawned", 0.5), ("event-weight-impact", 1.25), ("event-goal-start", 2.0),
                        ("event-goal-start-2", 2.0)):
        assert axes.x_value(svg.vertical_line_x(gid)) == pytest.approx(time_s, abs=1e-3)
    assert svg.text_of("event-label-weight-spawned") == "weight spawned"
    assert svg.text_of("event-label-weight-impact") == "weight impact"
    zoomed = SvgFigure(plot_series(tmp_path / "z.png", t, {"force": np.sin(t)}, title="f", ylabel="force",
                                   unit="N", events=events, zoom=(1.0, 1.5)).with_suffix(".svg"))
    assert "event-weight-impact" in zoomed.ids() and "event-weight-spawned" not in zoomed.ids()


def test_an_effort_limit_near_the_data_is_drawn_and_one_far_off_says_so(tmp_path):
    t = np.arange(1000) * 1e-3
    effort = 80 * np.sin(2 * math.pi * t)
    near = [Level(100.0, "effort limit ±100 N"), Level(-100.0, "effort limit ±100 N")]
    svg = SvgFigure(plot_series(tmp_path / "near.png", t, {"effort": effort}, title="e", ylabel="effort",
                                unit="N", levels=near).with_suffix(".svg"))
    axes = svg.axes[0]
    assert axes.y_value(svg.horizontal_line_y("level-effort-limit-100-n")) == pytest.approx(100.0, abs=0.5)
    assert axes.y_value(svg.horizontal_line_y("level-effort-limit-100-n-2")) == pytest.approx(-100.0, abs=0.5)
    assert axes.legend == ["effort", "effort limit ±100 N"]
    far = [Level(1000.0, "effort limit ±1000 N"), Level(-1000.0, "effort limit ±1000 N")]
    svg = SvgFigure(plot_series(tmp_path / "far.png", t, {"effort": effort}, title="e", ylabel="effort",
                                unit="N", levels=far).with_suffix(".svg"))
    axes = svg.axes[0]
    assert axes.legend == ["effort", "effort limit ±1000 N (off the axis)"]
    assert axes.yticks[1].max() < 200  # the data keep the axis
    assert axes.ylabel == "effort [N]"


def test_limits_of_several_joints_take_their_colours_and_those_off_the_axis_share_an_entry(tmp_path):
    t = np.arange(1000) * 1e-3
    series = {"joint0": 50 * t, "joint1": -60 * t}
    levels = [Level(v, f"{j} limit ±{abs(v):g} N·m", series=j)
              for j, limit in (("joint0", 1300.0), ("joint1", 70.0)) for v in (limit, -limit)]
    svg = SvgFigure(plot_series(tmp_path / "e.png", t, series, title="e", ylabel="effort", unit="N·m",
                                levels=levels).with_suffix(".svg"))
    legend = svg.axes[0].legend
    assert "joint1 limit ±70 N·m" in legend
    assert "off the axis:" not in legend and "joint0 limit ±1300 N·m (off the axis)" in legend
    style = svg.element("level-joint1-limit-70-n-m").find(".//{http://www.w3.org/2000/svg}path").get("style")
    assert "#ff7f0e" in style  # joint1's colour, the second of the cycle


def _step_marks(t, position, expected_final):
    return StepMarks(step_time_s=0.5, initial_value=-0.2, final_value=-0.5, settle_band=0.02, overshoot_pct=40.0,
                     peak_time_s=0.665, peak_value=float(np.interp(0.665, t, position)), rise_start_s=0.52,
                     rise_end_s=0.56, settling_time_s=0.8, expected_final=expected_final)


def test_a_step_figure_marks_band_overshoot_rise_settling_final_value_and_theory(tmp_path, trace):
    t, command, position = trace
    theory = position + 0.001
    png = plot_step(tmp_path / "step.png", t, command, position, title="step", unit="m",
                    marks=_step_marks(t, position, -0.505), theory=theory, events=[Event(1.0, "weight spawned")])
    svg = SvgFigure(png.with_suffix(".svg"))
    axes = svg.axes[0]
    assert axes.ylabel == "position [m]"
    assert axes.legend == ["reference", "position", "linear theory", "expected final value", "±2 % settling band",
                           "overshoot 40 %", "rise 10-90 %: 40 ms", "settled (2 %) after 800 ms"]
    assert axes.y_value(svg.horizontal_line_y("level-expected-final-value")) == pytest.approx(-0.505, abs=1e-3)
    assert axes.x_value(svg.vertical_line_x("step-settling-time")) == pytest.approx(1.3, abs=1e-3)
    assert {"step-settling-band", "step-overshoot", "step-rise-time", "event-weight-spawned"} <= svg.ids()
    # The band: ±2 % of the 0.3 m step about the final value, from the step to the end of the record.
    band = svg.element("step-settling-band").find(".//{http://www.w3.org/2000/svg}path").get("d")
    xs, ys = np.array([[float(v) for v in p.split()] for p in re.findall(r"[ML] ([-\d.]+ [-\d.]+)", band)]).T
    use = svg.element("step-settling-band").find(".//{http://www.w3.org/2000/svg}use")
    ys = ys + float(use.get("y"))  # matplotlib draws the band as a marker placed at (x, y)
    assert axes.x_value(xs.min()) == pytest.approx(0.5, abs=1e-3)
    assert axes.x_value(xs.max()) == pytest.approx(t[-1], abs=1e-3)
    assert sorted(axes.y_value(y) for y in (ys.min(), ys.max())) == pytest.approx([-0.506, -0.494], abs=1e-4)


def test_a_step_that_did_not_settle_marks_no_band_overshoot_or_rise_and_says_so(tmp_path, trace):
    t, command, position = trace
    marks = dataclasses.replace(_step_marks(t, position, None), final_value=None, overshoot_pct=None,
                                rise_start_s=None, rise_end_s=None, settling_time_s=None)
    png = plot_step(tmp_path / "step.png", t, command, position, title="step", unit="m", marks=marks)
    svg = SvgFigure(png.with_suffix(".svg"))
    assert svg.axes[0].legend == ["reference", "position", "not settled: no final value"]
    assert not {"step-settling-band", "step-overshoot", "step-rise-time", "step-settling-time"} & svg.ids()


def test_a_step_without_theory_or_expectation_leaves_them_out(tmp_path, trace):
    t, command, position = trace
    png = plot_step(tmp_path / "step.png", t, command, position, title="step", unit="m",
                    marks=_step_marks(t, position, None), zoom=(0.4, 1.5))
    svg = SvgFigure(png.with_suffix(".svg"))
    assert "linear theory" not in svg.axes[0].legend
    assert "level-expected-final-value" not in svg.ids()
    assert svg.axes[0].xticks[1].min() >= 0.4


def test_panels_stack_with_their_own_units(tmp_path):
    t = np.arange(2000) * 1e-3
    measured = 20 * np.sin(2 * math.pi * t)
    model = measured + 0.003 * np.cos(7 * t)
    png = plot_panels(tmp_path / "identify.png", t,
                      [Panel({"measured effort": measured, "model": model}, "effort", "N·m", height=2.0),
                       Panel({"measured - model": measured - model}, "residual", "N·m")], title="fit")
    svg = SvgFigure(png.with_suffix(".svg"))
    assert [a.ylabel for a in svg.axes] == ["effort [N·m]", "residual [mN·m]"]
    assert mpimg.imread(png).shape[:2] == (round((FIGSIZE_IN[1] + 2) * DPI), round(FIGSIZE_IN[0] * DPI))


def test_long_traces_are_drawn_through_their_extremes(tmp_path):
    rng = np.random.default_rng(1)
    t = np.arange(200_000) * 1e-4
    y = rng.normal(0.0, 1.0, t.size)
    y[123_457] = 40.0  # one spike
    td, yd = _decimated(t, y)
    assert td.size <= MAX_POINTS + 2 and np.all(np.diff(td) > 0)
    assert yd.max() == 40.0 and yd.min() == y.min() and td[0] == t[0] and td[-1] == t[-1]
    png = plot_series(tmp_path / "noise.png", t, {"noise": y}, title="n", ylabel="v", unit="m/s")
    svg_path = png.with_suffix(".svg")
    assert svg_path.stat().st_size < 400_000
    assert SvgFigure(svg_path).axes[0].yticks[1].max() >= 40.0


def test_within_not_drawn_nothing_is_written_but_the_data_are_still_checked(tmp_path, trace):
    t, command, position = trace
    marks = StepMarks(step_time_s=0.5, initial_value=-0.2, final_value=-0.5, settle_band=0.02, overshoot_pct=40.0,
                      peak_time_s=0.7, peak_value=-0.62, rise_start_s=0.52, rise_end_s=0.6, settling_time_s=0.8)
    with not_drawn():
        assert plot_series(tmp_path / "y.png", t, {"v": position}, title="v", ylabel="v") == tmp_path / "y.png"
        plot_command_and_position(tmp_path / "z.png", t, command, position, title="s", unit="m")
        plot_step(tmp_path / "s.png", t, command, position, title="s", unit="m", marks=marks)
        with pytest.raises(ValueError, match="shape"):
            plot_series(tmp_path / "y.png", t, {"v": position[:-1]}, title="v", ylabel="v")
    assert list(tmp_path.iterdir()) == []
    plot_series(tmp_path / "y.png", t, {"v": position}, title="v", ylabel="v")
    assert (tmp_path / "y.png").exists() and (tmp_path / "y.svg").exists()  # drawn again after the block

"""The experiments' figures read back from the SVG written beside each PNG: every axis in the unit of
its joint's type (the 1-DOF robot's prismatic joint in m and N, the arm's revolute joints in rad, mrad
or µrad and N·m), the step figure's marks against the run's own metrics and its theory curve against
the measured response, events where the scenario puts them, and identify's residual panel.

Positions are read off the axis' ticks (a straight line through them), so to a fraction of a pixel:
0.5 ms on a 15 s axis of 700 px is 1/40 px; the tolerances below are a few pixels at most."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from jointctl.identification.identify import identify_on_robot
from jointctl.recording.trace import load_trace
from jointctl.scenario.run import run_scenario
from jointctl.scenario.spec import load_scenario, scenario_for_robot
from tests.recording.svg_figure import SVG, SvgFigure
from tests.scenario.test_step_theory import write_arm

pytestmark = pytest.mark.slow

RUNS = ("one_dof_step", "one_dof_drop_weight", "arm7dof_pose")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("figures")
    return out, {name: run_scenario(load_scenario(name), out / name) for name in RUNS}


def svg(folder, name) -> SvgFigure:
    return SvgFigure(folder / f"{name}.svg")


def line_points(figure: SvgFigure, gid: str, axes_index: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The data points (time [s], value in the axis' shown unit) of the line with id ``gid``."""
    path = next(figure.element(gid).iter(f"{SVG}path")).get("d")
    xy = np.array([[float(v) for v in pair.split()] for pair in re.findall(r"[ML] ([-\d.]+ [-\d.]+)", path)])
    axes = figure.axes[axes_index]
    return np.array([axes.x_value(x) for x in xy[:, 0]]), np.array([axes.y_value(y) for y in xy[:, 1]])


def test_every_png_has_its_svg_beside_it_under_the_same_name(runs):
    out, _ = runs
    pngs = sorted(out.rglob("*.png"))
    assert {p.name for p in (out / "one_dof_step").glob("*.png")} == {"position.png", "position_zoom.png",
                                                                       "effort.png"}
    assert len(pngs) >= 10
    for png in pngs:
        assert png.with_suffix(".svg").is_file(), png


def test_the_one_dof_robots_figures_say_m_and_n(runs):
    out, _ = runs
    step, drop = out / "one_dof_step", out / "one_dof_drop_weight"
    assert svg(step, "position").axes[0].ylabel == "position [m]"
    assert svg(step, "position_zoom").axes[0].ylabel == "position [m]"
    assert svg(step, "effort").axes[0].ylabel == "effort [N]"
    assert svg(drop, "position").axes[0].ylabel == "position [m]"
    assert svg(drop, "effort_and_force").axes[0].ylabel == "force [N]"
    # The joint's effort limit (1000 N) lies far beyond the step's efforts: said, not drawn over them.
    assert "effort limit ±1000 N (off the axis)" in svg(step, "effort").axes[0].legend


def test_the_arms_figures_say_rad_mrad_or_urad_and_n_m(runs):
    out, _ = runs
    arm = out / "arm7dof_pose"
    error = svg(arm, "tracking_error_jointctl").axes[0]
    assert re.fullmatch(r"reference - position \[(mrad|µrad)\]", error.ylabel), error.ylabel
    assert np.max(np.abs(error.yticks[1])) >= 1.0  # no ticks like 0.00005
    effort = svg(arm, "effort").axes[0]
    assert effort.ylabel == "effort [N·m]"
    assert "joint6 limit ±70 N·m" in effort.legend  # near the efforts shown: drawn in joint6's colour
    assert svg(arm, "uncompensated_droop").axes[0].ylabel in ("joint angle [rad]", "joint angle [mrad]")


def test_the_arms_goal_starts_and_ends_where_its_run_says(runs):
    out, metrics = runs
    figure = svg(out / "arm7dof_pose", "tracking_error_jointctl")
    axes = figure.axes[0]
    start = axes.x_value(figure.vertical_line_x("event-goal-start"))
    end = axes.x_value(figure.vertical_line_x("event-goal-end-succeeded"))
    assert start == pytest.approx(0.5, abs=0.01)  # goals[0].at_s
    # The goal ends once the last point's time has passed and the arm is within its tolerances.
    last_point = 0.5 + metrics["arm7dof_pose"]["duration_s"]
    assert last_point - 0.01 <= end <= last_point + 0.5
    assert figure.text_of("event-label-goal-start") == "goal start"


def test_the_step_figure_marks_what_the_metrics_measured(runs):
    out, metrics = runs
    m = metrics["one_dof_step"]
    for name in ("position", "position_zoom"):
        figure = svg(out / "one_dof_step", name)
        axes = figure.axes[0]
        assert {"series-model-the-loop-as-it-runs", "step-settling-band", "level-expected-final-value", "step-overshoot",
                "step-rise-time", "step-settling-time"} <= figure.ids()
        assert f"overshoot {m['overshoot_pct']:.3g} %" in axes.legend
        assert f"rise 10-90 %: {1e3 * m['rise_time_s']:.3g} ms" in axes.legend
        assert "±2 % settling band" in axes.legend and "model: the loop as it runs" in axes.legend
        final = axes.y_value(figure.horizontal_line_y("level-expected-final-value"))
        assert final == pytest.approx(m["theory"]["rest_position"], abs=2e-3)
        settled = axes.x_value(figure.vertical_line_x("step-settling-time"))
        assert settled == pytest.approx(0.5 + m["settling_time_s"], abs=5e-3)


def test_the_theory_curve_follows_the_measured_step(runs):
    # The model is the loop as it runs, from where the run starts (-0.2 m, not its rest: it rings before the
    # step too): it replicates MuJoCo's step to 5e-11 m, far below what the figure draws (a pixel is 0.5 mm).
    out, _ = runs
    figure = svg(out / "one_dof_step", "position_zoom")
    t_theory, theory = line_points(figure, "series-model-the-loop-as-it-runs")
    t_measured, measured = line_points(figure, "series-position")
    difference = np.abs(theory - np.interp(t_theory, t_measured, measured))
    assert np.max(difference[(t_theory > 0.4) & (t_theory < 1.5)]) < 1e-5
    assert theory.min() == pytest.approx(measured.min(), abs=1e-5)  # the overshoot's peak, -0.66 m


def test_the_drop_weight_is_marked_where_it_spawned_and_where_it_hit(runs):
    out, _ = runs
    folder = out / "one_dof_drop_weight"
    trace = load_trace(folder / "trace.csv")
    t, force = trace.time_s, trace["ft_sensor.force_z"]
    unloaded = force[(t < 0.5) & (t >= 0.4)].mean()
    first_change = t[np.flatnonzero((t >= 0.5) & (np.abs(force - unloaded) > 1.0))[0]]
    for name in ("effort_and_force", "position"):
        figure = svg(folder, name)
        axes = figure.axes[0]
        assert figure.text_of("event-label-weight-spawned") == "weight spawned"
        assert axes.x_value(figure.vertical_line_x("event-weight-spawned")) == pytest.approx(0.5, abs=0.01)
        assert axes.x_value(figure.vertical_line_x("event-weight-impact")) == pytest.approx(first_change, abs=0.01)
    # It fell from rest under 5 m/s²: the impact follows the spawn by the free fall's time, ~0.9 s.
    assert 0.5 < first_change - 0.5 < 1.2


def test_a_revolute_step_is_in_rad_and_n_m_with_its_theory_and_limits(tmp_path):
    metrics = run_scenario(load_scenario(write_arm(tmp_path, -0.7, -0.8)), tmp_path / "out")
    position, effort = svg(tmp_path / "out", "position"), svg(tmp_path / "out", "effort")
    assert position.axes[0].ylabel == "position [rad]"
    assert "model: the loop as it runs" in position.axes[0].legend
    final = position.axes[0].y_value(position.horizontal_line_y("level-expected-final-value"))
    assert final == pytest.approx(metrics["theory"]["rest_position"], abs=2e-3)
    assert effort.axes[0].ylabel == "effort [N·m]"
    assert any(text.startswith("effort limit ±60 N·m") for text in effort.axes[0].legend)


@pytest.mark.parametrize("robot, joint, overrides, units", [
    ("one_dof", "joint1", [], ("N", "m")),
    ("arm7dof", "joint1", [f"initial_positions.joint{k}={q}" for k, q in enumerate([0, 1, 0, -2, 0, 1, 0])],
     ("N·m", "rad")),
])
def test_identify_draws_the_residual_below_the_fit(tmp_path, monkeypatch, robot, joint, overrides, units):
    from jointctl.identification import identify as identify_module

    drawn = []

    def keep(path, time_s, panels, **kwargs):
        drawn.append(panels)
        return plot_panels(path, time_s, panels, **kwargs)

    plot_panels = identify_module.plot_panels
    monkeypatch.setattr(identify_module, "plot_panels", keep)
    effort_unit, position_unit = units
    fit, _ = identify_on_robot(scenario_for_robot(robot, "position", overrides), joint, out_dir=tmp_path,
                               f_start_hz=0.2, f_end_hz=1.0)
    figure = svg(tmp_path, f"identify_{joint}")
    top, bottom = figure.axes
    assert top.ylabel == f"effort [{effort_unit}]"
    assert re.fullmatch(rf"residual \[[fpnµmk]?{re.escape(effort_unit)}\]", bottom.ylabel), bottom.ylabel
    assert bottom.legend == ["measured - model"]
    # The drawn residual in SI units, with the unit's prefix read off the label.
    prefix = bottom.ylabel[len("residual ["):-len(effort_unit) - 1]
    factor = {"": 1.0, "f": 1e-15, "p": 1e-12, "n": 1e-9, "µ": 1e-6, "m": 1e-3, "k": 1e3}[prefix]
    _, residual = line_points(figure, "series-measured-model", axes_index=1)
    # What was handed to the figure: the residual is the measured effort minus the model, sample by sample (over
    # every row, the fit's RMS being over the rows where the joint moves: not compared).
    (effort, below), = drawn
    model = next(v for k, v in effort.series.items() if k.startswith("identified model"))
    given = np.asarray(below.series["measured - model"])
    np.testing.assert_array_equal(given, np.asarray(effort.series["measured effort"]) - np.asarray(model))
    # The drawn line goes through each slice's extremes (samples themselves): its highest and lowest points are
    # the residual's, to a fraction of a pixel (the axis' span over its 200-odd px height: 1/200 of the span).
    span = given.max() - given.min()
    assert residual.max() * factor == pytest.approx(given.max(), abs=span / 200)
    assert residual.min() * factor == pytest.approx(given.min(), abs=span / 200)
    assert svg(tmp_path, f"identify_{joint}_position").axes[0].ylabel == f"position [{position_unit}]"


REJECTED_GOAL = """
name: one_dof_rejected_goal
robot: one_dof
controller_file: trajectory
start_controllers: [joint_state_controller, joint1_position_controller, joint1_trajectory_controller]
initial_positions: {joint1: -0.5}
duration_s: 4.0
goals:
  - {controller: joint1_trajectory_controller, at_s: 0.5,
     trajectory: {joint_names: [joint1], points: [{positions: [-0.4], time_from_start: 1.0}]}}
  - {controller: joint1_trajectory_controller, at_s: 2.0,
     trajectory: {joint_names: [joint1], points: [{positions: [5.0], time_from_start: 1.0}]}}
analysis: {type: trajectory_tracking, joint: joint1, controller: joint1_trajectory_controller}
"""


def test_a_rejected_goal_is_marked_where_it_was_sent_said_in_the_metrics_and_the_record(tmp_path):
    import json

    from mcap.reader import make_reader

    path = tmp_path / "rejected.yaml"
    path.write_text(REJECTED_GOAL)
    metrics = run_scenario(load_scenario(path), tmp_path / "out")
    [rejected] = metrics["rejected_goals"]
    assert rejected["time_s"] == pytest.approx(2.0) and "upper limit" in rejected["error"]
    assert "5.0" in rejected["error"]
    trace = load_trace(tmp_path / "out" / "trace.csv")
    q = trace.joint("joint1", "position")
    # The first goal was delivered (-0.5 -> -0.4 m) and the refused one moved nothing after 2 s.
    assert q[trace.time_s >= 1.9][0] == pytest.approx(-0.4, abs=2e-3)
    assert np.ptp(q[trace.time_s >= 1.9]) < 1e-3
    figure = svg(tmp_path / "out", "position")
    axes = figure.axes[0]
    assert axes.x_value(figure.vertical_line_x("event-goal-rejected")) == pytest.approx(2.0, abs=0.01)
    assert figure.text_of("event-label-goal-rejected") == "goal rejected"
    with open(tmp_path / "out" / "run.mcap", "rb") as stream:
        events = [json.loads(message.data) for _, _, message in make_reader(stream).iter_messages(
            topics=["/jointctl/events"])]
    [warning] = [e for e in events if e["message"].startswith("joint1_trajectory_controller: goal 2 rejected: ")]
    assert warning["timestamp"] == {"sec": 2, "nsec": 0} and warning["level"] == 3 and "5.0" in warning["message"]

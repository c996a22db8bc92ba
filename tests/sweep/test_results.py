"""results.csv, summary.json, traces.npz and the figures (their drawn data read back), from rows made by hand."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from jointctl.sweep.criteria import parse_spec
from jointctl.sweep.figures import write_figures
from jointctl.sweep.results import SweepResult, load_traces
from jointctl.sweep.runner import Row
from jointctl.sweep.variations import parse_variation


def step_trace(wn: float, zeta: float) -> dict:
    """A unit step at 0.5 s from -0.2 to -0.5, second order, 300 samples."""
    t = np.linspace(0.0, 3.0, 300)
    tau = np.clip(t - 0.5, 0.0, None)
    wd = wn * math.sqrt(1 - zeta**2)
    u = 1 - np.exp(-zeta * wn * tau) * (np.cos(wd * tau) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * tau))
    return {"joint": "joint1", "time_s": t, "position": -0.2 - 0.3 * u,
            "reference": np.where(t >= 0.5, -0.5, -0.2)}


def row(index, payload, p, overshoot, settling, error=None):
    metrics = {} if error else {"overshoot_pct": overshoot, "settling_time_s": settling, "initial_value": -0.2,
                                "final_value": -0.5}
    zeta = 0.25 - 0.02 * payload
    return Row(index, {"payload_kg": payload, "controllers.c.pid.p": p}, metrics, error,
               None if error else step_trace(20.0 / math.sqrt(1 + payload), zeta))


@pytest.fixture
def result():
    rows = [row(0, 0.0, 200, 30.5, 0.71), row(1, 0.0, 400, 44.7, 0.2), row(2, 5.0, 200, 61.0, None),
            row(3, 5.0, 400, None, None, error="PhysicsError: mjWARN_BADQACC: unstable")]
    spec = parse_spec("overshoot_pct<=50,settling_time_s<=0.8")
    for r in rows:
        r.passed = spec.verdict(r.metrics) if r.error is None else None
    nominal = row(-1, 0.0, 400, 44.7, 0.2)
    variations = (parse_variation("payload_kg=0:5:2"), parse_variation("controllers.c.pid.p=[200, 400]"))
    return SweepResult("one_dof_step", variations, spec, 1, 0, 4, rows, nominal, False, "this process", 1.5)


def test_the_table_has_a_row_a_run_with_values_metrics_verdict_and_error(result, tmp_path):
    result.write(tmp_path)
    with (tmp_path / "results.csv").open() as f:
        table = list(csv.reader(f))
    assert table[0] == ["index", "payload_kg", "controllers.c.pid.p", "overshoot_pct", "settling_time_s",
                        "initial_value", "final_value", "pass", "error"]
    assert table[1] == ["0", "0.0", "200", "30.5", "0.71", "-0.2", "-0.5", "true", ""]
    assert table[3][3:5] == ["61.0", ""] and table[3][7] == "false"  # never settled: not measured, fails
    assert table[4][3:8] == ["", "", "", "", ""] and table[4][8] == "PhysicsError: mjWARN_BADQACC: unstable"


def test_the_summary_counts_and_names_each_metrics_worst_case(result, tmp_path):
    result.write(tmp_path)
    text = (tmp_path / "summary.json").read_text()
    summary = json.loads(text)  # strict JSON: parsed back without NaN
    assert "NaN" not in text and "Infinity" not in text
    assert (summary["runs"], summary["finished"], summary["passed"], summary["failed"], summary["errors"]) == \
        (4, 4, 2, 1, 1)
    assert summary["errors_by_kind"] == {"PhysicsError": 1}
    overshoot = summary["metrics"]["overshoot_pct"]
    assert overshoot["worst"] == {"value": 61.0, "index": 2, "values": {"payload_kg": 5.0, "controllers.c.pid.p": 200},
                                  "by": "--spec overshoot_pct<=50"}
    assert overshoot["min"]["value"] == 30.5 and overshoot["max"]["index"] == 2 and overshoot["nominal"] == 44.7
    settling = summary["metrics"]["settling_time_s"]
    assert settling["worst"]["value"] is None and settling["worst"]["index"] == 2  # never settled is the worst
    assert settling["not_measured"] == 1 and settling["measured"] == 2
    # A metric the spec does not bound: the worst is the furthest from the nominal run's.
    assert summary["metrics"]["initial_value"]["worst"]["by"] == "furthest from the nominal run"


def test_a_bound_from_below_is_worst_at_its_smallest(result):
    result.spec = parse_spec("overshoot_pct>=40")
    value, worst = result.worst("overshoot_pct")
    assert value == 30.5 and worst.index == 0


def test_traces_are_kept_per_run(result, tmp_path):
    result.write(tmp_path)
    traces = load_traces(tmp_path / "traces.npz")
    assert sorted(traces) == [0, 1, 2]
    assert traces[2]["joint"] == "joint1"
    assert np.array_equal(traces[2]["position"], result.rows[2].trace["position"])


def test_the_figures_are_drawn_for_one_field_two_fields_and_the_responses(result, tmp_path):
    written = {p.name for p in write_figures(result, tmp_path)}
    assert written == {"overshoot_pct_vs_payload_kg.png", "overshoot_pct_vs_controllers_c_pid_p.png",
                       "settling_time_s_vs_payload_kg.png", "settling_time_s_vs_controllers_c_pid_p.png",
                       "heatmap_overshoot_pct.png", "heatmap_settling_time_s.png", "responses.png"}
    assert all((tmp_path / name).stat().st_size > 10_000 for name in written)


def test_distributions_are_drawn_as_dots_coloured_by_the_metric(result, tmp_path):
    result.variations = (parse_variation("payload_kg=uniform(0, 5)"), result.variations[1])
    assert "heatmap_overshoot_pct.png" in {p.name for p in write_figures(result, tmp_path)}


def test_without_a_spec_the_first_metrics_are_drawn_and_nothing_is_judged(result, tmp_path):
    result.spec = parse_spec(None)
    for r in result.rows:
        r.passed = None
    result.variations = result.variations[:1]
    written = {p.name for p in write_figures(result, tmp_path)}
    assert "final_value_vs_payload_kg.png" in written and not any(n.startswith("heatmap") for n in written)
    summary = result.summary()
    assert summary["passed"] is None and summary["spec"] is None


def test_a_flag_is_true_or_false_in_the_table_and_its_share_in_the_summary(result, tmp_path):
    for r, moving in zip(result.rows, (False, True, True, None)):
        if r.error is None:
            r.metrics["moving_at_step"] = moving
    result.nominal.metrics["moving_at_step"] = False
    result.write(tmp_path)
    with (tmp_path / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["moving_at_step"] for r in rows] == ["false", "true", "true", ""]
    moving = json.loads((tmp_path / "summary.json").read_text())["metrics"]["moving_at_step"]
    assert moving["measured"] == 3 and moving["mean"] == pytest.approx(2 / 3)  # the share of runs moving
    assert moving["worst"]["value"] is True and moving["worst"]["index"] == 1


def test_a_run_that_did_not_settle_is_drawn_to_its_commanded_step(result, tmp_path):
    from jointctl.sweep import figures

    unsettled = result.rows[2]
    unsettled.metrics["final_value"] = None
    y = figures._normalised(unsettled.trace["position"], unsettled.metrics, unsettled.trace["reference"])
    assert y is not None and y[-1] == pytest.approx(1.0, abs=0.05)  # the trace's -0.5 end over the 0.3 m step


@pytest.fixture
def drawn(monkeypatch):
    """{file name: the matplotlib Figure saved there}: each sweep figure's drawn data, read back."""
    from matplotlib.figure import Figure

    saved = {}
    save = Figure.savefig

    def keep(fig, path, *args, **kwargs):
        saved[Path(path).name] = fig
        return save(fig, path, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    return saved


def _dots(ax) -> np.ndarray:
    """The (x, y) of the first scatter's dots."""
    return np.asarray(ax.collections[0].get_offsets(), dtype=float)


def test_each_figure_draws_its_metric_against_its_field(result, tmp_path, drawn):
    """The finished runs (0, 1, 2 of the fixture; 3 failed) as dots at (field, metric), the nominal run's value
    dashed and the spec's limit dotted; a metric a run did not measure is a cross at the lowest measured value."""
    write_figures(result, tmp_path)
    payloads, gains = [0.0, 0.0, 5.0], [200, 400, 200]
    overshoots, settlings = [30.5, 44.7, 61.0], [0.71, 0.2, math.nan]
    for metric, ys, limit in (("overshoot_pct", overshoots, 50.0), ("settling_time_s", settlings, 0.8)):
        for field, slug, xs in (("payload_kg", "payload_kg", payloads),
                                ("controllers.c.pid.p", "controllers_c_pid_p", gains)):
            ax, = drawn[f"{metric}_vs_{slug}.png"].axes
            assert (ax.get_xlabel(), ax.get_ylabel()) == (field, metric)
            assert ax.get_title() == f"{metric} against {field} (1 run failed, not shown)"
            np.testing.assert_array_equal(_dots(ax), np.column_stack([xs, ys]))
            lines = {line.get_label(): line.get_ydata()[0] for line in ax.get_lines()}
            assert lines[f"spec {metric}<={limit:g}"] == limit
            nominal = {"overshoot_pct": 44.7, "settling_time_s": 0.2}[metric]
            assert lines[f"nominal {nominal:.4g}"] == nominal
    ax, = drawn["settling_time_s_vs_payload_kg.png"].axes
    np.testing.assert_array_equal(ax.collections[1].get_offsets(), [[5.0, 0.2]])  # run 2 never settled


def test_each_heat_map_shows_its_metric_in_the_cells_of_the_two_fields(result, tmp_path, drawn):
    """Payload across (0, 5), the gain up (200, 400); a cell per run, empty where the run failed or did not
    measure; the cells that break the spec framed."""
    write_figures(result, tmp_path)
    for metric, cells, failing in (("overshoot_pct", [[30.5, 61.0], [44.7, math.nan]], {"61"}),
                                   ("settling_time_s", [[0.71, math.nan], [0.2, math.nan]], set())):
        figure = drawn[f"heatmap_{metric}.png"]
        ax = figure.axes[0]
        assert (ax.get_xlabel(), ax.get_ylabel(), ax.get_title()) == ("payload_kg", "controllers.c.pid.p", metric)
        assert [t.get_text() for t in ax.get_xticklabels()] == ["0", "5"]
        assert [t.get_text() for t in ax.get_yticklabels()] == ["200", "400"]
        np.testing.assert_array_equal(ax.images[0].get_array().filled(np.nan), cells)
        texts = {(round(t.get_position()[0]), round(t.get_position()[1])): t.get_text() for t in ax.texts}
        assert texts == {(j, i): f"{v:.3g}" for (i, j), v in np.ndenumerate(cells) if math.isfinite(v)}
        framed = {texts[(round(p.get_x() + 0.5), round(p.get_y() + 0.5))] for p in ax.patches}
        assert framed == failing
        assert figure.axes[1].get_ylabel() == metric  # the colour bar


def test_the_responses_figure_draws_each_finished_run_normalised(result, tmp_path, drawn):
    """Runs 0 to 2 (and the nominal, dashed), each 0 before its step at 0.5 s and 1 at its final value -0.5."""
    write_figures(result, tmp_path)
    ax, = drawn["responses.png"].axes
    assert ax.get_title() == "every run's joint1 response (3 runs)"
    segments = ax.collections[0].get_segments()
    assert len(segments) == 3
    for segment, r in zip(segments, result.rows):
        u = (r.trace["position"] + 0.2) / -0.3  # the fixture's step from -0.2 to -0.5
        np.testing.assert_allclose(segment, np.column_stack([r.trace["time_s"], u]), atol=1e-12)
    nominal, = [line for line in ax.get_lines() if line.get_label() == "nominal"]
    np.testing.assert_allclose(nominal.get_ydata(), (result.nominal.trace["position"] + 0.2) / -0.3, atol=1e-12)

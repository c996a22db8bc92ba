"""The chapter's trajectory example (figs. 11.8, 11.9): jointctl's default against the chapter's mode.

The chapter's mode (linear interpolation of positions streamed at 100 Hz into a P-only
position loop) cannot remove the gravity droop m·g/Kp = 1.01·9.81/400 = 24.8 mm, so its RMS
error is at least that order; the model feed-forward removes droop, damping lag and inertia
lag, leaving only discretisation effects. The issue asks for at least 3x; 10x is required here.
"""

from __future__ import annotations

import json
import math

import pytest

from jointctl.scenario.run import run_scenario
from jointctl.scenario.spec import load_scenario

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("trajectory")
    run_scenario(load_scenario("one_dof_trajectory"), out)
    return out, json.loads((out / "metrics.json").read_text())


def test_the_goal_succeeds_with_the_clients_coarse_points(result):
    _, m = result
    assert m["result"] == "succeeded"
    assert 10 <= m["points"] <= 100  # two periods of 4π s in steps of 0.01-1.00 s
    assert m["duration_s"] == pytest.approx(4 * math.pi, abs=1e-9)  # the last point is at the end


def test_chapter_mode_carries_the_gravity_droop(result):
    _, m = result
    droop = 1.01 * 9.81 / 400
    assert 0.8 * droop <= m["rms_tracking_error_m_chapter_mode"] <= 2 * droop


def test_feedforward_cuts_the_error_more_than_tenfold(result):
    _, m = result
    assert m["rms_tracking_error_m_feedforward"] * 10 <= m["rms_tracking_error_m_chapter_mode"]
    assert m["rms_tracking_error_m_feedforward"] < 0.001
    assert m["error_reduction"] == pytest.approx(
        m["rms_tracking_error_m_chapter_mode"] / m["rms_tracking_error_m_feedforward"])


def test_figures_of_both_modes(result):
    out, _ = result
    names = {p.name for p in out.iterdir()}
    assert {"coarse_points.png", "interpolated_command.png", "position.png", "tracking_error.png",
            "chapter_mode"} <= names

"""The 7-DOF arm's natural admittance control catching a dropped weight (fig. 11.7).

Theory: the chapter's attractor (0, 0, 1.5) m and K = diag(100, 100, 10) N/m; at rest the virtual
force vanishes, so the flange sits at p_att + K⁻¹·F with F the sensed force in the base frame
(tared for the plate): a 10 kg weight at g = 0.5 m/s² pushes 5 N down and sags it 0.5 m.
jointctl's damping B = diag(60, 60, 30) N·s/m catches it with at most 20 mm overshoot and settles
within 10 s; the chapter's B = 10·I overshoots by about 0.2 m (ζ ≈ 0.3 vertically).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from jointctl.scenario.run import run_scenario
from jointctl.scenario.spec import load_scenario

ATTRACTOR = np.array([0.0, 0.0, 1.5])
K = np.array([100.0, 100.0, 10.0])
WEIGHT_KG, G = 10.0, 0.5

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("arm_nac")
    run_scenario(load_scenario("arm7dof_nac_catch"), out)
    return out, json.loads((out / "metrics.json").read_text())


def test_the_flange_rests_at_the_attractor_plus_force_over_stiffness(result):
    _, m = result
    force = np.array(m["steady_sensor_force_base_frame_n"])
    assert force[2] == pytest.approx(-WEIGHT_KG * G, rel=0.01)  # the weight, the plate tared off
    expected = ATTRACTOR + force / K
    np.testing.assert_allclose(m["expected_flange_rest_position_m"], expected, atol=1e-12)
    assert np.linalg.norm(np.array(m["flange_rest_position_m"]) - expected) <= 0.005
    assert m["flange_rest_position_m"][2] == pytest.approx(1.0, abs=0.01)  # about 0.5 m of sag
    assert m["sag_m"] == pytest.approx(WEIGHT_KG * G / K[2], abs=0.01)


def test_the_catch_is_graceful(result):
    _, m = result
    assert 0.0 <= m["overshoot_m"] <= 0.020
    assert 0.0 < m["settling_time_s"] <= 10.0
    assert m["settling_band_m"] == pytest.approx(max(0.02 * m["sag_m"], 0.001))
    assert m["first_contact_s"] == pytest.approx(10.0 + (2 * 0.3 / G) ** 0.5, abs=0.05)  # a 0.3 m fall
    assert m["peak_sensor_force_n"] > WEIGHT_KG * G  # the impact exceeds the static load


def test_the_chapters_damping_overshoots_clearly_more(result):
    _, m = result
    assert m["chapter_damping_n_s_m"] == [10.0, 10.0, 10.0]
    assert m["chapter_damping_overshoot_m"] >= 0.1
    assert m["chapter_damping_overshoot_m"] >= 5 * max(m["overshoot_m"], 0.001)


def test_the_weight_stays_on_the_plate(result):
    _, m = result
    assert m["weight_on_plate"] is True
    x, y, z = m["weight_offset_in_flange_frame_m"]
    assert np.hypot(x, y) <= 0.02  # near the plate's centre (radius 0.1 m)
    assert z == pytest.approx(m["weight_resting_height_m"], abs=0.002)
    assert m["load_lost_s"] is None or np.isnan(m["load_lost_s"])


def test_the_experiment_writes_its_figures_and_the_variant(result):
    out, _ = result
    names = {p.name for p in out.iterdir()}
    assert {"flange_z.png", "flange_xy.png", "force.png", "force_impact.png", "force_after_impact.png",
            "trace.csv", "metrics.json", "chapter_damping"} <= names
    assert (out / "chapter_damping" / "trace.csv").is_file()

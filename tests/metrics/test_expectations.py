"""Margins, the warning sentences and the share of saturated cycles."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.metrics.expectations import (NATURAL_FREQUENCY_MARGIN, OVERSHOOT_MARGIN, expectation_warnings,
                                           margin_for, miss_warning, saturation_share, saturation_warning, share_of)


def test_a_figure_within_its_margin_is_no_warning_and_beyond_it_is_one_sentence_naming_everything():
    # ωn: 5 % of the expected 17.27 rad/s is 0.86 rad/s.
    assert miss_warning("natural_frequency_rad_s", 16.5, 17.27, NATURAL_FREQUENCY_MARGIN) is None
    sentence = miss_warning("natural_frequency_rad_s", 15.04, 17.27, NATURAL_FREQUENCY_MARGIN)
    assert sentence.startswith("natural_frequency_rad_s: measured 15.04, expected 17.27: off by 12.9 %")
    assert "margin of 5 %" in sentence


def test_a_position_margin_is_a_share_of_the_motion():
    margin = share_of(-0.3, "step")
    assert margin.allowed(123.0) == pytest.approx(0.006)  # 2 % of the step, whatever the value
    assert miss_warning("steady_state_error_rad", -0.0299, -0.0349, margin) is None
    sentence = miss_warning("steady_state_error_rad", -0.0299, -0.0, margin)
    assert "off by 0.0299" in sentence and "2 % of the step 0.3, 0.006" in sentence


def test_lists_compare_by_their_largest_difference():
    margin = share_of(0.5, "sag")  # 0.01
    assert miss_warning("p", [0.0, 0.0, 1.0], [0.0, 0.005, 1.0], margin) is None
    assert "off by 0.02" in miss_warning("p", [0.0, 0.0, 1.0], [0.0, 0.02, 1.0], margin)


@pytest.mark.parametrize("measured, expected", [(None, 1.0), (float("nan"), 1.0), (1.0, None), ([1.0], [1.0, 2.0])])
def test_what_is_not_measured_or_not_applicable_is_not_compared(measured, expected):
    assert miss_warning("x_damping_ratio", measured, expected, margin_for("x_damping_ratio")) is None


def test_margins_come_by_the_end_of_the_name_unless_the_analysis_gives_one():
    assert margin_for("book_node_decay_rate_1_per_s").value == 0.10
    assert margin_for("hold_natural_frequency_rad_s") is NATURAL_FREQUENCY_MARGIN
    assert margin_for("steady_position_m") is None  # a position: its margin depends on the motion
    given = share_of(0.1, "sag")
    assert margin_for("steady_position_m", {"steady_position_m": given}) is given
    found = expectation_warnings({"overshoot_pct": 50.0, "steady_position_m": 1.0, "other": 3.0},
                                 {"overshoot_pct": 44.6, "steady_position_m": 0.0, "other": 0.0})
    assert len(found) == 1 and found[0].startswith("overshoot_pct") and OVERSHOOT_MARGIN.describe() in found[0]


def test_saturation_is_the_share_of_samples_at_the_limit():
    effort = np.array([10.0, 60.0, -60.0, 59.9, 0.0])
    assert saturation_share(effort, 60.0) == pytest.approx(0.4)
    assert saturation_share(effort, float("inf")) == 0.0
    assert saturation_warning("shoulder", 0.0, 60.0, "N·m") is None
    assert saturation_warning("shoulder", 0.4, 60.0, "N·m").startswith(
        "shoulder: effort at its 60 N·m limit in 40 % of the cycles of the run")

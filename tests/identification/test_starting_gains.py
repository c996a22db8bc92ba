"""Starting gains from a user's model: each driven joint's inertia and gravity load at home (checked
against the planar arm's closed forms), a loop that holds the load within half a step and whose step
fits the effort limit, and the cases that cannot be met named."""

from __future__ import annotations

import math

import pytest

from jointctl.errors import ConfigError
from jointctl.identification.frequency_response import LoopModel
from jointctl.identification.starting_gains import (EFFORT_FRACTION, SAG_FRACTION, home_pose, starting_gains)
from jointctl.model.loader import load_robot_model
from tests import planar_arm


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    return load_robot_model(planar_arm.write_urdf(tmp_path_factory.mktemp("arm")))


@pytest.fixture(scope="module")
def default_loops(arm):
    """The starting loops at the default spec (2 Hz, ζ 0.7): designed once for the module."""
    return starting_gains(arm)


def test_the_plant_at_home_is_the_planar_arms_closed_form(arm, default_loops) -> None:
    loops = {loop.joint: loop for loop in default_loops}
    assert list(loops) == ["shoulder", "elbow"] and home_pose(arm) == {"shoulder": 0.0, "elbow": 0.0}
    assert loops["shoulder"].inertia == pytest.approx(planar_arm.shoulder_inertia_kg_m2(0.0), rel=1e-3)
    assert loops["elbow"].inertia == pytest.approx(planar_arm.elbow_inertia_kg_m2(), rel=1e-3)
    for name, load in planar_arm.gravity_loads_n_m().items():
        assert loops[name].gravity_load == pytest.approx(load, rel=1e-3)
        assert loops[name].damping == planar_arm.DAMPING[name]
        assert loops[name].effort_limit == planar_arm.EFFORT[name]


def test_every_loop_holds_its_load_and_its_step_fits_the_effort_limit(default_loops) -> None:
    for loop in default_loops:
        p, d = loop.gains["p"], loop.gains["d"]
        assert loop.gravity_load / p <= SAG_FRACTION * loop.step * (1 + 1e-6)  # the sag
        assert p * loop.step + loop.gravity_load <= EFFORT_FRACTION * loop.effort_limit * (1 + 1e-6)
        assert p > 0 and d > 0 and loop.gains["i"] == 0.0
        # 2 Hz is too soft to hold these loads: raised, and said.
        assert loop.bandwidth_hz > 2.0 and "raised from 2" in loop.note


def test_a_loop_stiff_enough_already_keeps_the_bandwidth_asked(arm) -> None:
    elbow = starting_gains(arm, bandwidth_hz=12.0)[1]
    assert elbow.bandwidth_hz == 12.0 and "raised" not in elbow.note and "lowered" not in elbow.note
    # The design's own promise, on its model: the closed loop's -3 dB point at 12 Hz.
    model = LoopModel(elbow.inertia, elbow.damping, elbow.gains["p"], 0.0, elbow.gains["d"], 0.001, "position",
                      "error")
    gain, _ = model.response([12.0])
    assert gain[0] == pytest.approx(-3.0103, abs=0.01)


def test_a_fast_spec_is_lowered_to_what_the_effort_limit_allows(arm) -> None:
    shoulder = starting_gains(arm, bandwidth_hz=40.0)[0]
    assert shoulder.bandwidth_hz < 40.0 and "lowered from 40" in shoulder.note
    need = shoulder.gains["p"] * shoulder.step + shoulder.gravity_load
    assert need == pytest.approx(EFFORT_FRACTION * shoulder.effort_limit, rel=0.05)


def test_a_weak_motor_sags_and_says_by_how_much(tmp_path) -> None:
    text = planar_arm.urdf_text().replace('effort="60.0"', 'effort="18.0"')
    (tmp_path / "weak.urdf").write_text(text)
    shoulder = starting_gains(load_robot_model(tmp_path / "weak.urdf"))[0]
    sag = shoulder.gravity_load / shoulder.gains["p"]
    assert sag > SAG_FRACTION * shoulder.step and f"sags {sag:.3g}" in shoulder.note


@pytest.mark.parametrize("change, fragments", [
    (('effort="60.0"', 'effort="12.0"'), ["gravity load", "effort limit 12", "joint shoulder"]),
    (("<transmission", "<!-- <transmission"), ["transmission", "EffortJointInterface"]),
])
def test_what_cannot_be_met_is_refused(tmp_path, change, fragments) -> None:
    text = planar_arm.urdf_text().replace(*change)
    if change[1].startswith("<!--"):
        text = text.replace("</transmission>", "</transmission> -->")
    (tmp_path / "bad.urdf").write_text(text)
    with pytest.raises(ConfigError) as caught:
        starting_gains(load_robot_model(tmp_path / "bad.urdf"))
    for fragment in fragments:
        assert fragment in str(caught.value), str(caught.value)


@pytest.mark.parametrize("kwargs, field", [({"bandwidth_hz": -1.0}, "--bandwidth-hz"), ({"zeta": 1.2}, "--zeta"),
                                           ({"zeta": math.nan}, "--zeta")])
def test_bad_specs_are_refused(arm, kwargs, field) -> None:
    with pytest.raises(ConfigError) as caught:
        starting_gains(arm, **kwargs)
    assert caught.value.field == field


@pytest.fixture(scope="module")
def vertical_loops(tmp_path_factory):
    """The 3-joint arm vertical at home (tests/user_arms.py), at the default spec."""
    from tests import user_arms

    robot = load_robot_model(user_arms.write(tmp_path_factory.mktemp("vertical"), "vertical_arm"))
    return {loop.joint: loop for loop in starting_gains(robot)}


def _bandwidth_gain_db(loop, p: float, hz: float) -> float:
    model = LoopModel(loop.inertia, loop.damping, p, 0.0, loop.gains["d"], 0.001, "position", "error")
    gain, _ = model.response([hz])
    return float(gain[0])


def test_a_joint_damped_beyond_the_spec_by_its_own_bearing_gets_d_0_and_its_zeta_said(vertical_loops) -> None:
    from tests import user_arms

    yaw = vertical_loops["base_yaw"]
    assert yaw.gains["d"] == 0.0 and yaw.bandwidth_hz == 2.0
    assert _bandwidth_gain_db(yaw, yaw.gains["p"], 2.0) == pytest.approx(-3.0103, abs=0.01)  # still 2 Hz
    zeta = user_arms.YAW_DAMPING / (2 * math.sqrt(yaw.gains["p"] * yaw.inertia))
    assert zeta > 0.7 and f"d = 0" in yaw.note and f"(ζ {zeta:.3g})" in yaw.note


def test_a_joint_balanced_above_its_axis_gets_the_tipping_stiffness_added_to_p(vertical_loops) -> None:
    """The forearm stands on the elbow: gravity pulls it away by m·g·l/2 per radian; the loop's stiffness is p
    less that, so p is that much more than the 2 Hz design (whose -3 dB point the net stiffness keeps)."""
    from tests import user_arms

    elbow = vertical_loops["elbow_pitch"]
    tipping = user_arms.FOREARM[0] * user_arms.GRAVITY * user_arms.FOREARM[1] / 2
    assert elbow.inertia == pytest.approx(user_arms.ELBOW_INERTIA, rel=1e-3)
    assert f"p raised by {tipping:.3g}" in elbow.note
    assert _bandwidth_gain_db(elbow, elbow.gains["p"] - tipping, elbow.bandwidth_hz) == pytest.approx(-3.0103,
                                                                                                       abs=0.05)


def test_a_step_whose_kick_would_clamp_is_ramped_until_it_fits(vertical_loops) -> None:
    for loop in vertical_loops.values():
        allowed = EFFORT_FRACTION * loop.effort_limit
        if loop.gains["d"] * loop.step / 0.001 > allowed:
            assert loop.ramp_s > 0 and "ramps over" in loop.note
            assert loop.gains["d"] * loop.step / loop.ramp_s <= 0.5 * (allowed - loop.gravity_load) * (1 + 1e-9)
        else:
            assert loop.ramp_s == 0.0
        assert 0 < loop.peak_effort <= allowed and loop.step_at_s >= 0.5

"""The page's analyses run on a simulated copy of its robot with the live gains and gravity."""

from __future__ import annotations

import pytest

from jointctl.scenario.spec import scenario_for_robot
from jointctl.tuning.analyses import live_copy, run_analysis
from jointctl.tuning.requests import RequestError, SetGain, SetGravity, parse_request
from jointctl.tuning.tuner import Tuner

CONTROLLER = "joint1_position_controller"


@pytest.fixture
def tuner(tmp_path):
    t = Tuner(scenario_for_robot("one_dof", "position"), out_dir=tmp_path)
    yield t
    t.close()


def test_the_copy_has_the_live_gains_and_gravity(tuner) -> None:
    tuner.handle(SetGain(CONTROLLER, "p", 900.0))
    tuner.handle(SetGravity(-5.0))
    tuner.apply_pending()
    copy = live_copy(tuner, ["controllers.joint1_position_controller.pid.d=12"])
    assert copy.controller_overrides[f"{CONTROLLER}.pid.p"] == 900.0
    assert copy.controller_overrides[f"{CONTROLLER}.pid.d"] == 12
    assert copy.gravity_m_s2 == (0.0, 0.0, -5.0)
    result = run_analysis(tuner, parse_request(f'{{"type": "identify", "controller": "{CONTROLLER}"}}'))["result"]
    assert result["gravity_load_n"] == pytest.approx(1.01 * 5.0, rel=0.01)  # the copy's gravity is the live one


def test_the_copy_starts_where_the_live_robot_is(tuner) -> None:
    tuner.commandable[CONTROLLER].set_reference(-0.3)
    tuner.loop.run(2.0)
    here = tuner.hardware.position[0]
    assert here == pytest.approx(-0.3 - 1.01 * 9.81 / 400, abs=2e-3)  # at rest there, the P loop's droop below
    assert live_copy(tuner).initial_positions["joint1"] == here
    result = run_analysis(tuner, parse_request(f'{{"type": "identify", "controller": "{CONTROLLER}"}}'))["result"]
    assert result["excitation"]["start"] == pytest.approx(here, abs=1e-4)


def test_an_analysis_changes_nothing_live(tuner) -> None:
    time_before = tuner.loop.time_s
    reply = run_analysis(tuner, parse_request(f'{{"type": "autotune", "controller": "{CONTROLLER}", '
                                              '"bandwidth_hz": 5}'))
    assert reply["result"]["gains"]["p"] > 900
    assert tuner.groups[CONTROLLER].values()["p"] == 400.0 and tuner.loop.time_s == time_before


def test_an_unknown_controller_is_refused(tuner) -> None:
    with pytest.raises(RequestError) as info:
        run_analysis(tuner, parse_request('{"type": "bode", "controller": "nope"}'))
    assert info.value.field == "controller"

"""The page's analyses run on a simulated copy of its robot with the live gains and gravity."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.scenario.spec import scenario_for_robot
from jointctl.tuning.analyses import live_copy, run_analysis
from jointctl.tuning.requests import Analyse, RequestError, SetGain, SetGravity, parse_request
from jointctl.tuning.tuner import Tuner
from tests.tuning.conftest import wait_for

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
    # The chapter's file runs ros_controllers' law (derivative on the error), designed at the page's 0.1 m step,
    # whose kick the 1000 N limit clamps: p 525 N/m (385 for small moves' 5 Hz; 961 with the derivative on the
    # measurement). Whatever the gains, the live loop keeps its own.
    assert 300 < reply["result"]["gains"]["p"] < 961 and reply["result"]["derivative"] == "error"
    assert tuner.groups[CONTROLLER].values()["p"] == 400.0 and tuner.loop.time_s == time_before


def test_an_unknown_controller_is_refused(tuner) -> None:
    with pytest.raises(RequestError) as info:
        run_analysis(tuner, parse_request('{"type": "bode", "controller": "nope"}'))
    assert info.value.field == "controller"


@pytest.fixture
def running(tuner):
    """The tuner's loop running on its own thread at 3x the wall clock, as the page runs it."""
    import control  # noqa: F401  (imported now: under a loop paced faster than 1x, an import in the analysis
    import scipy.signal  # noqa: F401  thread waits for the GIL for seconds; at 1x it takes 0.5 s)

    from jointctl.tuning.runner import LiveRunner

    runner = LiveRunner(tuner, speed=3.0)
    runner.start()
    yield tuner
    runner.stop()
    assert runner.error is None


def wait_until_stopped(tuner: Tuner) -> None:
    """Wait until the loop has stopped: a change queued through the tuner's door is applied outside
    any cycle, which only the paused runner does (a running loop applies it at a cycle's start)."""
    in_cycle = False

    def begin(t: float) -> None:
        nonlocal in_cycle
        in_cycle = True

    def end(t: float) -> None:
        nonlocal in_cycle
        in_cycle = False

    tuner.loop.add_input(begin, first=True)  # before the tuner's own input, which applies the changes
    tuner.loop.add_observer(end)
    try:
        def applied_between_cycles() -> bool:
            where: list[bool] = []
            tuner.at_next_cycle(lambda t: where.append(in_cycle))
            wait_for(lambda: where, what="the change to be applied")
            return not where[0]

        wait_for(applied_between_cycles, what="the loop to stop")
    finally:
        tuner.loop.remove_input(begin)
        tuner.loop.remove_observer(end)


def live(kind: str) -> Analyse:
    return parse_request(f'{{"type": "{kind}", "controller": "{CONTROLLER}", "live": true}}')


def test_a_live_identification_excites_the_running_robot_and_gives_its_reference_back(running) -> None:
    controller = running.commandable[CONTROLLER]
    hooks = (running.loop.inputs, running.loop.observers)
    reference, before_s = controller.reference, running.loop.time_s
    seen: list[float] = []
    running.loop.add_observer(lambda t: seen.append(running.hardware.position[0]))
    reply = run_analysis(running, live("identify"))
    assert reply["live"] is True
    result = reply["result"]
    # The running robot carried the excitation, in its own loop time: 1 s settle, 10 s chirp, 2 s settle.
    assert running.loop.time_s - before_s >= 13.0
    assert max(seen) - min(seen) > result["excitation"]["amplitude"]
    assert result["mass_kg"] == pytest.approx(1.01, rel=0.02)
    assert result["damping_n_s_m"] == pytest.approx(10.0, rel=0.02)
    assert result["gravity_load_n"] == pytest.approx(1.01 * 9.81, rel=0.01)
    assert running.loop.inputs == hooks[0] and running.loop.observers[:-1] == hooks[1]  # its hooks are gone
    wait_for(lambda: controller.reference == reference, what="the reference given back")


def test_a_live_bode_sweeps_the_running_loop(running, monkeypatch) -> None:
    import jointctl.tuning.analyses as analyses

    monkeypatch.setattr(analyses, "BODE_POINTS", 3)
    monkeypatch.setattr(analyses, "BODE_BAND_HZ", (2.5, 4.0))
    before_s = running.loop.time_s
    reply = run_analysis(running, live("bode"))
    result = reply["result"]
    assert reply["live"] is True and len(result["gain_db"]) == 3
    assert running.loop.time_s - before_s >= result["simulated_s"]
    # Around the chapter's ωn = sqrt(400/1.01) (3.17 Hz) the running robot follows its loop model.
    for measured, modelled in zip(result["gain_db"], result["model"]["gain_db"]):
        assert measured == pytest.approx(modelled, abs=0.5)


def test_live_analyses_are_refused_when_they_cannot_run(running) -> None:
    with pytest.raises(RequestError) as info:
        parse_request(f'{{"type": "autotune", "controller": "{CONTROLLER}", "bandwidth_hz": 5, "live": true}}')
    assert info.value.field == "live"
    with pytest.raises(RequestError) as info:
        parse_request(f'{{"type": "identify", "controller": "{CONTROLLER}", "live": 1}}')
    assert info.value.field == "live" and info.value.value == 1
    running.handle(parse_request('{"type": "pause"}'))
    wait_until_stopped(running)
    time_s = running.loop.time_s
    with pytest.raises(RequestError, match="paused") as info:
        run_analysis(running, live("identify"))
    assert info.value.field == "live" and running.loop.time_s == time_s


def test_the_bode_reply_has_phase_margins_and_curves_matching_the_mass_damper_loop(tuner) -> None:
    import math

    reply = run_analysis(tuner, parse_request(f'{{"type": "bode", "controller": "{CONTROLLER}"}}'))
    result = reply["result"]
    model, curves = result["model"], result["curves"]
    assert len(result["phase_deg"]) == len(result["gain_db"]) == 16
    # The sampled loop Kp/(m s² + b s) (m 1.01 kg, b 10 N·s/m, Kp 400 N/m, 1 ms hold): the gain crosses
    # 0 dB where Kp = ω·√(m²ω² + b²), with the phase margin atan(b/(mω)) less the hold's ω·h/2; the phase
    # reaches -180° where the hold's lag ω·h/2 takes the damper's b/(mω): ω² = 2b/(m·h).
    m, b, kp, h = 1.01, 10.0, 400.0, 0.001
    assert (model["mass"], model["damping"], model["p"], result["period_s"]) == pytest.approx((m, b, kp, h))
    wc = math.sqrt((-b * b + math.sqrt(b**4 + 4 * m * m * kp * kp)) / (2 * m * m))
    assert model["gain_crossover_hz"] == pytest.approx(wc / (2 * math.pi), rel=1e-3)
    assert model["phase_margin_deg"] == pytest.approx(math.degrees(math.atan(b / (m * wc)) - wc * h / 2), abs=0.05)
    wp = math.sqrt(2 * b / (m * h))
    assert model["phase_crossover_hz"] == pytest.approx(wp / (2 * math.pi), rel=0.01)
    assert model["gain_margin_db"] == pytest.approx(-20 * math.log10(kp / (wp * math.hypot(m * wp, b))), abs=0.1)
    # The curves span the sweep (0.5 to 20 Hz), widened just past the -180° crossing (22.4 Hz), not to 100 Hz.
    low, high = curves["band_hz"]
    assert low == pytest.approx(0.5) and 20.0 < model["phase_crossover_hz"] < high < 30.0
    f = curves["frequencies_hz"]
    assert f[0] == pytest.approx(low) and f[-1] == pytest.approx(high)
    # The open loop's gain is 0 dB and its phase -180° + the phase margin at the gain crossover, and its
    # phase -180° at the phase crossover; the closed loop's curve passes through the model's points.
    at = lambda key, hz: float(np.interp(math.log(hz), np.log(f), curves[key]))  # noqa: E731
    assert at("loop_gain_db", model["gain_crossover_hz"]) == pytest.approx(0.0, abs=0.05)
    assert at("loop_phase_deg", model["gain_crossover_hz"]) == pytest.approx(model["phase_margin_deg"] - 180, abs=0.1)
    assert at("loop_phase_deg", model["phase_crossover_hz"]) == pytest.approx(-180.0, abs=0.1)
    assert at("loop_gain_db", model["phase_crossover_hz"]) == pytest.approx(-model["gain_margin_db"], abs=0.05)
    for hz, gain in zip(result["frequencies_hz"], model["gain_db"]):
        assert at("closed_gain_db", hz) == pytest.approx(gain, abs=0.05)

"""The loop: order of the cycle, determinism, stopping, pacing."""

from __future__ import annotations

import time

import pytest

from jointctl.runtime.clock import SimulatedClock, WallClockPacer
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from tests.conftest import step_scenario


def _session(write_scenario, tmp_path, **changes):
    return Session(load_scenario(write_scenario(step_scenario(**changes))), out_dir=tmp_path / "out")


def test_loop_time_is_cycle_times_period(write_scenario, tmp_path):
    session = _session(write_scenario, tmp_path)
    seen = []
    session.loop.add_input(seen.append)
    assert session.loop.run(cycles=5) == 5
    assert seen == [k * 0.001 for k in range(5)]
    assert session.loop.time_s == pytest.approx(0.005)
    assert session.world.time_s == pytest.approx(0.005)


def test_cycle_order_input_read_update_write_observe_step(write_scenario, tmp_path):
    session = _session(write_scenario, tmp_path)
    events = []
    hw = session.hardware
    for name in ("read", "write", "advance"):
        original = getattr(hw, name)

        def traced(*args, _name=name, _original=original):
            events.append(_name)
            return _original(*args)

        setattr(hw, name, traced)
    controller = session.manager.controller("joint1_position_controller")
    original_update = controller.update

    def update(t, dt):
        events.append("update")
        original_update(t, dt)

    session.manager.update_calls = (update,)
    session.loop.add_input(lambda t: events.append("input"), first=True)
    session.loop.add_observer(lambda t: events.append("observe"))
    session.loop.run(cycles=1)
    assert events == ["input", "read", "update", "write", "observe", "advance"]


def test_same_inputs_give_the_same_trace_bit_for_bit(write_scenario, tmp_path):
    traces = []
    for run in range(2):
        scenario = load_scenario(write_scenario(step_scenario()))
        with Session(scenario, out_dir=tmp_path / f"run{run}") as session:
            session.run()
        traces.append((tmp_path / f"run{run}" / "trace.csv").read_bytes())
    assert traces[0] == traces[1]
    assert len(traces[0].splitlines()) == 501  # header + 0.5 s at 1 kHz


def test_request_stop_ends_the_run_after_the_current_cycle(write_scenario, tmp_path):
    session = _session(write_scenario, tmp_path)
    session.loop.add_observer(lambda t: session.loop.request_stop() if t >= 0.0099 else None)
    assert session.loop.run() == 11


def test_wall_clock_pacer_never_runs_ahead():
    pacer = WallClockPacer(speed=2.0)
    pacer.start()
    start = time.perf_counter()
    for k in range(1, 21):
        pacer.wait_for(k * 0.005)  # 0.1 s of loop time at 2x: at least 0.05 s of wall time
    assert time.perf_counter() - start >= 0.05


def test_realtime_run_takes_at_least_the_loop_time(write_scenario, tmp_path):
    scenario = load_scenario(write_scenario(step_scenario(duration_s=0.2)))
    session = Session(scenario, realtime=True)
    start = time.perf_counter()
    session.run()
    assert time.perf_counter() - start >= 0.2
    assert isinstance(session.loop.clock, WallClockPacer)


def test_pacer_refuses_non_positive_speed():
    with pytest.raises(ValueError, match="speed"):
        WallClockPacer(0.0)


def test_simulated_clock_does_not_wait():
    clock = SimulatedClock()
    clock.start()
    start = time.perf_counter()
    clock.wait_for(1000.0)
    assert time.perf_counter() - start < 10.0  # a hang guard: waiting would take 1000 s

"""One run of a sweep in this process: its row, its failures named, and the 1-DOF theory across payloads."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from jointctl.sweep.runner import NOT_ROW_METRICS, RunTask, evaluate, numbers, task_scenario
from tests.conftest import step_scenario
from tests.faulty_controllers import FAULTY_TYPE

M_KG, B, KP, DT = 1.01, 10.0, 400.0, 0.001


def test_a_row_holds_the_analysis_numbers_and_the_analysed_joints_response():
    row = evaluate(RunTask(3, "one_dof_step", {"payload_kg": 1.0}, overrides=("duration_s=1.5",)))
    assert row.error is None and row.index == 3 and row.values == {"payload_kg": 1.0}
    assert {"natural_frequency_rad_s", "damping_ratio", "overshoot_pct", "settling_time_s"} <= set(row.metrics)
    assert not any(name.split(".")[0] in NOT_ROW_METRICS for name in row.metrics)
    assert all(v is None or isinstance(v, (float, bool)) for v in row.metrics.values())
    trace = row.trace
    assert trace["joint"] == "joint1" and len(trace["time_s"]) <= 400
    assert trace["time_s"][-1] == pytest.approx(1.5, abs=0.01)
    assert trace["reference"][0] == -0.2 and trace["reference"][-1] == -0.5
    assert row.run_s > 0 and row.passed is None


def test_numbers_flatten_and_keep_only_numbers_and_flags():
    flat = numbers({"a": 1, "b": {"c": 2.5, "d": "text", "e": [1, 2]}, "f": math.inf, "g": None, "h": True,
                    "expected": {"a": 3.0}, "real_time_factor": 150.0, "i": np.float32(0.5), "j": np.bool_(False)})
    assert flat == {"a": 1.0, "b.c": 2.5, "f": None, "g": None, "h": True, "i": 0.5, "j": False}
    assert type(flat["h"]) is bool and type(flat["j"]) is bool


@pytest.mark.parametrize("values, kind, says", [
    ({"duration_s": 0.4}, "AnalysisError", "step_time_s must lie inside the record"),
    ({"gravity": -1e12}, "PhysicsError", "mjWARN_BADQACC"),
    ({"controllers.joint1_position_controller.pid.p": -5.0}, "ConfigError", "pid.p: must not be negative"),
    ({"payload_kg": -0.3}, "ConfigError", "payload_kg: must be a mass"),
    ({"latency_cycles": -1}, "ConfigError", "latency_cycles: must not be negative"),
    ({"model.joint1.damping": -2.0}, "ConfigError", "model.joint1.damping: must not be negative"),
])
def test_a_failing_run_is_a_row_naming_its_failure(values, kind, says):
    row = evaluate(RunTask(5, "one_dof_step", values))
    assert row.error is not None and row.error.startswith(f"{kind}: ") and says in row.error
    assert row.index == 5 and row.values == values and row.metrics == {} and row.trace is None


def test_a_refused_goal_fails_its_run(write_scenario):
    goal = {"controller": "joint1_trajectory_controller", "at_s": 0.1,
            "trajectory": {"joint_names": ["joint1"], "points": [{"positions": [2.0], "time_from_start": 1.0}]}}
    path = write_scenario(step_scenario(
        controller_file="trajectory", commands={}, goals=[goal],
        start_controllers=["joint_state_controller", "joint1_position_controller", "joint1_trajectory_controller"]))
    row = evaluate(RunTask(0, str(path), {}))
    assert row.error is not None and row.error.startswith("InvalidTrajectory: "), row.error


def test_a_controller_that_fails_during_the_run_fails_its_row(write_scenario):
    # The failure-policy double raises once its reference passes fail_above: here from the first cycle on.
    controllers = {"joint1_position_controller": {"type": FAULTY_TYPE, "fail_above": -0.3}}
    row = evaluate(RunTask(0, str(write_scenario(step_scenario(controllers=controllers))), {}))
    assert row.error is not None and row.error.startswith("ControllerFailed: "), row.error
    assert "deliberate fault" in row.error


def test_every_value_is_a_scenario_field_and_the_runs_noise_is_seeded_by_the_sweep_and_the_run():
    scenario = task_scenario(RunTask(4, "one_dof_step", {"payload_kg": 2, "latency_cycles": 2.0, "noise.velocity": 1e-3,
                                                        "model.joint1.damping": 3, "gravity": -5}, seed=9))
    assert scenario.payload_kg == 2.0 and scenario.model_changes == {"model.joint1.damping": 3.0}
    assert scenario.latency_cycles == 2 and scenario.noise.velocity == 1e-3 and scenario.noise.position == 0.0
    assert scenario.gravity_m_s2 == (0.0, 0.0, -5.0)
    assert scenario.noise.seed == (9, 5, 1)  # noise_seed(seed, index)


@pytest.mark.parametrize("payload_kg", [0.0, 1.5, 5.0])
def test_one_dof_step_follows_the_second_order_theory_for_each_payload(payload_kg):
    # P control of the piston (Kp 400, Kd 0, b 10) carrying m = 1.01 kg + payload: ωn = √(Kp/m),
    # ζ = (b + Kd)/(2√(Kp m)). The 1 kHz loop deviates from the continuous theory by terms of order ωn·dt
    # (2 % at 19.9 rad/s, 0.8 % with 5 kg): that is the tolerance. The fit does not mind the start's sag.
    row = evaluate(RunTask(0, "one_dof_step", {"payload_kg": payload_kg}, overrides=("duration_s=2",)))
    assert row.error is None, row.error
    m = M_KG + payload_kg
    wn = math.sqrt(KP / m)
    zeta = B / (2 * math.sqrt(KP * m))
    assert row.metrics["natural_frequency_rad_s"] == pytest.approx(wn, rel=wn * DT)
    assert row.metrics["damping_ratio"] == pytest.approx(zeta, rel=wn * DT)


def test_the_step_controllers_gains_are_what_the_theory_assumes():
    from jointctl.paths import robots_dir

    config = yaml.safe_load((robots_dir() / "one_dof" / "config" / "one_dof_pos_ctl_params.yaml").read_text())
    pid = config["one_DOF_robot"]["joint1_position_controller"]["pid"]
    assert (pid["p"], pid["d"]) == (KP, 0.0)


@pytest.mark.parametrize("payload_kg", [0.0, 5.0])
def test_a_row_says_whether_the_run_was_still_moving_at_its_step(payload_kg):
    # The loop starts holding -0.2 m and drops m·g/Kp under gravity, ringing with (m·g/Kp)·exp(-ζωn·t)/√(1 - ζ²):
    # at the step (0.5 s) 2.1 mm nominally, inside the 6 mm band (2 % of the 0.3 m step); 98 mm with 5 kg.
    m = M_KG + payload_kg
    zeta = B / (2 * math.sqrt(KP * m))
    left = m * 9.81 / KP * math.exp(-B / (2 * m) * 0.5) / math.sqrt(1 - zeta**2)
    row = evaluate(RunTask(0, "one_dof_step", {"payload_kg": payload_kg}, overrides=("duration_s=1",)))
    assert row.error is None, row.error
    assert row.metrics["moving_at_step"] is (left > 0.02 * 0.3)


# -- worlds kept between the runs of a sweep ----------------------------------------------------------------------
P = "controllers.joint1_position_controller.pid.p"
CONTROLLER = "controllers.joint1_position_controller"


def same_rows(reused, fresh) -> None:
    """The rows of the same task, one on a kept world and one built whole: every figure, the error, the loop and
    the decimated trace equal, to the last bit (the same operations on the same state)."""
    assert reused.error == fresh.error
    assert reused.metrics == fresh.metrics  # floats compared exactly, None (not measured) where both have None
    assert (reused.loop, reused.loop_reason) == (fresh.loop, fresh.loop_reason)
    if fresh.trace is None:
        assert reused.trace is None
        return
    assert reused.trace["joint"] == fresh.trace["joint"]
    for name in ("time_s", "position", "reference"):
        assert np.array_equal(reused.trace[name], fresh.trace[name]), name


def run_reused(monkeypatch, values_list, overrides=("duration_s=1.5",)):
    """Each values' run on worlds kept in this process (one sweep's key; a clean cache), in order, then the same
    task built whole; and the worlds built and reused by the first."""
    from jointctl.sweep import runner

    kept = runner.BuiltWorlds()
    monkeypatch.setattr(runner, "WORLDS", kept)
    tasks = [RunTask(k, "one_dof_step", values, overrides=overrides, reuse="a sweep")
             for k, values in enumerate(values_list)]
    reused = [evaluate(task) for task in tasks]
    fresh = [evaluate(RunTask(t.index, t.target, t.values, overrides=t.overrides)) for t in tasks]
    return reused, fresh, (kept.built, kept.reused)


@pytest.mark.slow
def test_a_run_on_a_kept_world_gives_the_row_of_a_fresh_build(monkeypatch):
    # Gains, model fields (payload, joint damping) and the initial pose vary; runs 2 and 4 restart worlds built for
    # runs 0 and 1 after a run on another world (3 kg then none: the kept world's masses are its own).
    values = [
        {"payload_kg": 3.0, P: 600.0, "initial_positions.joint1": -0.1},
        {"payload_kg": 0.0, P: 300.0, "initial_positions.joint1": -0.25},
        {"payload_kg": 3.0, P: 450.0, "initial_positions.joint1": -0.3},
        {"payload_kg": 0.0, P: 300.0, "initial_positions.joint1": -0.25, "model.joint1.damping": 20.0},
        {"payload_kg": 0.0, P: 800.0, "initial_positions.joint1": -0.15},
    ]
    reused, fresh, (built, restarted) = run_reused(monkeypatch, values)
    assert (built, restarted) == (3, 2)
    for r, f in zip(reused, fresh):
        assert r.error is None, r.error
        same_rows(r, f)
    # The theory still holds on the restarted worlds: ωn = √(Kp/m) with the run's own mass and gain.
    for row, m in ((reused[2], M_KG + 3.0), (reused[4], M_KG)):
        wn = math.sqrt(row.values[P] / m)
        assert row.metrics["natural_frequency_rad_s"] == pytest.approx(wn, rel=wn * DT)


@pytest.mark.slow
def test_nothing_of_a_failed_run_leaks_into_the_next_on_its_world(monkeypatch):
    import tests.faulty_controllers  # noqa: F401  (registers FAULTY_TYPE in this process)

    normal = {P: 500.0}
    values = [
        normal,
        {"gravity": -1e12},  # MuJoCo warns (BADQACC) mid-run: a world of its own
        {"gravity": -1e12, P: 100.0},  # ... restarted after it blew up: the same warning at the same time
        {f"{CONTROLLER}.type": FAULTY_TYPE, f"{CONTROLLER}.fail_above": -0.3},  # fails at the step, the run goes on
        {P: -5.0},  # refused while the session is built, its world already restarted
        {"duration_s": 0.4},  # the run ends; its analysis fails
        {P: 500.0, "initial_positions.joint1": -0.3},
        normal,
    ]
    reused, fresh, (built, restarted) = run_reused(monkeypatch, values)
    assert (built, restarted) == (2, 6)
    kinds = [r.error.split(":")[0] if r.error else None for r in reused]
    assert kinds == [None, "PhysicsError", "PhysicsError", "ControllerFailed", "ConfigError", "AnalysisError", None,
                     None]
    for r, f in zip(reused, fresh):
        same_rows(r, f)
    same_rows(reused[-1], reused[0])  # the last run is the first again, after everything


def test_a_rows_loop_says_the_one_dof_step_ran_compiled():
    row = evaluate(RunTask(0, "one_dof_step", {P: 500.0}, overrides=("duration_s=1",), reuse="a sweep"))
    assert row.error is None and (row.loop, row.loop_reason) == ("compiled", None)
    row = evaluate(RunTask(0, "one_dof_step", {"loop": "python"}, overrides=("duration_s=1",)))
    assert row.loop == "python" and "loop: python" in row.loop_reason


def test_kept_worlds_are_bounded_and_belong_to_one_sweep():
    from jointctl.scenario.session import simulated_world
    from jointctl.scenario.spec import load_scenario
    from jointctl.sweep.runner import BuiltWorlds

    kept = BuiltWorlds(size=2)
    scenario = load_scenario("one_dof_step")
    worlds = {}
    for payload in (0.0, 1.0, 2.0):
        task = RunTask(0, "one_dof_step", {}, reuse="a")
        changed = load_scenario("one_dof_step", [f"payload_kg={payload}"])
        robot, world, key = kept.take(task, changed)
        assert world is None
        worlds[payload] = simulated_world(robot, changed)
        kept.keep(key, worlds[payload])
    assert len(kept._worlds) == 2 and len(kept._robots) == 1
    _, world, _ = kept.take(RunTask(0, "one_dof_step", {}, reuse="a"), scenario)
    assert world is None  # payload 0 was the least recently used: dropped
    _, world, _ = kept.take(RunTask(0, "one_dof_step", {}, reuse="a"),
                            load_scenario("one_dof_step", ["payload_kg=2.0"]))
    assert world is worlds[2.0]
    _, world, _ = kept.take(RunTask(0, "one_dof_step", {}, reuse="another sweep"),
                            load_scenario("one_dof_step", ["payload_kg=1.0"]))
    assert world is None  # another sweep reads the files again

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

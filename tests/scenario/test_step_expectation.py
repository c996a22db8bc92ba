"""The step analysis expects what the loop as it runs gives: the joint's own law (the derivative kick and its
clamp), the effort clamp, gravity over the move, the feed-forward, the latency; the same numbers autotune
promises for the same gains and step, and a sweep row's theory is its own plant's.

The model (:class:`~jointctl.metrics.step_loop.JointLoop`, MuJoCo's semi-implicit Euler with implicit damping)
replicates the simulated 1-DOF robot to 5e-11 m: its figures, read as the run's are, agree with the run's to that
share of the 0.3 m step (2e-8 %), so 1e-6 relative leaves room only for the fit's convergence. On a revolute joint
the gravity load is interpolated between 721 samples over the joint's range (a spacing Δ of 6.9 mrad over the
yaw/pitch arm's ±2.5 rad): its error, at most Δ²/8·m·g·l/2 = 1.1e-5 N·m, moves the joint by that over the loop's
stiffness (8 N·m/rad): 1.3e-6 rad, 1.3e-3 % of a 0.1 rad step.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from jointctl.identification.autotune import autotune, check_after_s
from jointctl.scenario.run import run_scenario
from jointctl.scenario.spec import load_scenario
from jointctl.scenario.targets import resolve_target
from jointctl.sweep.runner import RunTask, evaluate
from tests.user_arms import SHOULDER_LOAD_NM, UPPER_ARM
from tests.user_arms import write as write_urdf

pytestmark = pytest.mark.slow

M_KG = 1.01          # the 1-DOF robot's piston and sensor disk
KP = 400.0
B = 10.0
G = 9.81
#: The yaw/pitch arm's shoulder: its inertia about the joint, m·l²/3, its damping and effort limit.
SHOULDER_INERTIA = UPPER_ARM[0] * UPPER_ARM[1] ** 2 / 3
SHOULDER_LIMIT = 15.0
#: How far the gravity profile's interpolation moves the arm (the module docstring): 1.3e-6 rad.
ARM_REPLICA_RAD = (2 * 2.5 / 720) ** 2 / 8 * SHOULDER_LOAD_NM / 8.0
FIGURES = ("overshoot_pct", "settling_time_s", "natural_frequency_rad_s", "damping_ratio")


def one_dof_step(tmp_path, *settings):
    return run_scenario(load_scenario("one_dof_step", list(settings)), tmp_path / "out")


def test_the_derivative_on_the_error_is_expected_with_its_clamped_kick(tmp_path):
    # d 18: the kick d·Δr/h = 5400 N is clamped at the 1000 N limit in the step's first cycle, so the linear loop
    # (which takes the whole kick) does not describe the step; the loop as it runs does.
    metrics = one_dof_step(tmp_path, "controllers.joint1_position_controller.pid.d=18")
    assert metrics["effort_saturated_share_after_step"] > 0
    assert metrics["peak_effort_n"] == pytest.approx(1000.0, rel=1e-12)
    expected = metrics["expected"]
    assert "not_applicable" not in metrics
    for key in FIGURES:
        assert expected[key] == pytest.approx(metrics[key], rel=1e-6), key
    assert expected["steady_state_error_m"] == pytest.approx(metrics["steady_state_error_m"], abs=1e-9)
    assert expected["steady_state_error_m"] == pytest.approx(M_KG * G / KP, rel=1e-6)
    assert expected["peak_effort_n"] == pytest.approx(1000.0, rel=1e-12)
    assert 4.0 < metrics["overshoot_pct"] < 6.0
    assert metrics["warnings"] == [w for w in metrics["warnings"] if "limit" in w]  # the kick's clamp only


def test_latency_and_a_payload_are_the_simulated_robots(tmp_path):
    # Three cycles of latency and 1 kg the controllers do not know: ζ falls to 0.48, the overshoot to 18 %. The
    # trace keeps every fifth cycle: the kick's cycle is not among them, in the run's figures nor in the model's.
    metrics = one_dof_step(tmp_path, "controllers.joint1_position_controller.pid.d=18", "latency_cycles=3",
                           "payload_kg=1", "record.every=5")
    for key in FIGURES:
        assert metrics["expected"][key] == pytest.approx(metrics[key], rel=1e-6), key
    assert metrics["expected"]["peak_effort_n"] == pytest.approx(metrics["peak_effort_n"], rel=1e-9)
    assert metrics["peak_effort_n"] < 1000.0
    assert metrics["theory"]["inertia"] == pytest.approx(M_KG + 1.0, rel=1e-9)
    assert metrics["expected"]["steady_state_error_m"] == pytest.approx((M_KG + 1.0) * G / KP, rel=1e-6)
    assert metrics["overshoot_pct"] > 15.0


def test_an_overshoot_of_the_laws_zero_is_not_reported_as_critical_damping(tmp_path):
    # No joint damping, d 80 on the error, a 1 cm step (its kick, 800 N, within the limit): the poles are real
    # (ζ = 80/(2√(400·1.01)) = 1.99) and the zero alone carries the piston 4.9 % past its rest. The fit ran to
    # ζ 0.9999995; the step's figures are those of the second-order loop that overshoots as much.
    metrics = one_dof_step(tmp_path, "controllers.joint1_position_controller.pid.d=80", "model.joint1.damping=0",
                           "gravity=0", "commands.joint1_position_controller.to=-0.21")
    overshoot = metrics["overshoot_pct"]
    assert 4.5 < overshoot < 5.2
    log = math.log(overshoot / 100)
    assert metrics["damping_ratio"] == pytest.approx(-log / math.hypot(math.pi, log), rel=1e-9)  # 0.69
    assert "does not oscillate" in metrics["fit_note"]
    for key in FIGURES:
        assert metrics["expected"][key] == pytest.approx(metrics[key], rel=1e-6), key


# -- a loaded revolute joint: the yaw/pitch arm's shoulder -------------------------------------------------------

ARM_CONTROLLERS = """yaw_pitch_arm:
  joint_state_controller:
    type: joint_state_controller/JointStateController
    publish_rate: 50
  base_yaw_position_controller:
    type: effort_controllers/JointPositionController
    joint: base_yaw
    pid: {p: 50.0, i: 0.0, d: 2.0}
  shoulder_pitch_position_controller:
    type: effort_controllers/JointPositionController
    joint: shoulder_pitch
    pid: {p: 8.0, i: 0.0, d: 0.6}
"""


def write_arm(folder) -> str:
    """The yaw/pitch arm's folder (tests/user_arms.py's URDF, both joints under position loops); its path."""
    write_urdf(folder, "yaw_pitch_arm")
    (folder / "config").mkdir(exist_ok=True)
    (folder / "config" / "position.yaml").write_text(ARM_CONTROLLERS)
    (folder / "robot.yaml").write_text("description: yaw_pitch_arm.urdf\ncontrollers:\n  position: "
                                       "config/position.yaml\n")
    return str(folder)


def p_rest(reference: float, p: float) -> float:
    """Where the shoulder's P loop holds the arm against its weight: p·(r - q) = -load·cos q (the arm along +x
    at 0, a positive angle turning it down)."""
    q = reference
    for _ in range(100):
        q = reference + SHOULDER_LOAD_NM * math.cos(q) / p
    return q


def shoulder_step(folder, start: float, end: float, *, pid: dict, feedforward: bool = False, at: float = 0.5,
                  duration_s: float = 3.0, derivative: str = "error", initial: float | None = None) -> str:
    """A scenario stepping the shoulder from ``start`` to ``end`` [rad] at ``at`` [s], from ``initial`` (default:
    where its P loop rests)."""
    robot = write_arm(folder)
    if initial is None:
        initial = start if feedforward else p_rest(start, pid["p"])
    controller = {"pid": pid, "derivative": derivative}
    if feedforward:
        controller["feedforward"] = {"gravity": True}
    scenario = {
        "name": "yaw_pitch_shoulder_step", "robot": robot, "controller_file": "position",
        "start_controllers": ["joint_state_controller", "base_yaw_position_controller",
                              "shoulder_pitch_position_controller"],
        "controllers": {"shoulder_pitch_position_controller": controller},
        "gravity": [0.0, 0.0, -G], "timestep_s": 0.001, "initial_positions": {"shoulder_pitch": initial},
        "duration_s": duration_s,
        "commands": {"shoulder_pitch_position_controller": {"type": "step", "from": start, "to": end, "at": at}},
        "analysis": {"type": "step_response", "joint": "shoulder_pitch"},
    }
    path = folder / "step.yaml"
    path.write_text(json.dumps(scenario))
    return str(path)


def test_a_loaded_shoulders_kick_is_clamped_and_expected_so(tmp_path):
    # p 8, d 0.6 on the error: the kick d·0.1/h = 60 N·m meets the 15 N·m limit; the arm sags 0.2 rad under its
    # weight (p·e = load·cos q).
    scenario = shoulder_step(tmp_path, 0.0, 0.1, pid={"p": 8.0, "i": 0.0, "d": 0.6})
    metrics = run_scenario(load_scenario(scenario), tmp_path / "out")
    assert metrics["effort_saturated_share_after_step"] > 0
    expected = metrics["expected"]
    step = 0.1
    assert expected["overshoot_pct"] == pytest.approx(metrics["overshoot_pct"], abs=100 * 2 * ARM_REPLICA_RAD / step)
    assert expected["settling_time_s"] == pytest.approx(metrics["settling_time_s"], abs=2e-3)
    assert expected["steady_state_error_rad"] == pytest.approx(metrics["steady_state_error_rad"],
                                                               abs=2 * ARM_REPLICA_RAD)
    assert expected["steady_state_error_rad"] == pytest.approx(0.1 - p_rest(0.1, 8.0), abs=2 * ARM_REPLICA_RAD)
    assert expected["peak_effort_n_m"] == pytest.approx(SHOULDER_LIMIT, rel=1e-12)
    for key in ("natural_frequency_rad_s", "damping_ratio"):
        assert expected[key] == pytest.approx(metrics[key], rel=1e-4), key  # ~1e-6 rad of ~0.1 rad
    assert "not_applicable" not in metrics


def test_a_step_that_saturates_is_expected_by_the_loop_that_saturates(tmp_path):
    # p 30 asks 30 N·m of a 1 rad step, twice the 15 N·m limit: the effort sits at its limit for the first part
    # of the move, which no linear loop describes (these figures were "not applicable").
    scenario = shoulder_step(tmp_path, 0.0, 1.0, pid={"p": 30.0, "i": 0.0, "d": 1.6})
    metrics = run_scenario(load_scenario(scenario), tmp_path / "out")
    assert metrics["effort_saturated_share_after_step"] > 0.01
    expected = metrics["expected"]
    assert "not_applicable" not in metrics
    assert expected["overshoot_pct"] == pytest.approx(metrics["overshoot_pct"], abs=100 * 2 * ARM_REPLICA_RAD)
    assert expected["settling_time_s"] == pytest.approx(metrics["settling_time_s"], abs=2e-3)
    assert expected["steady_state_error_rad"] == pytest.approx(metrics["steady_state_error_rad"],
                                                               abs=2 * ARM_REPLICA_RAD)
    for key in ("natural_frequency_rad_s", "damping_ratio"):
        assert expected[key] == pytest.approx(metrics[key], rel=1e-4), key  # ~1e-6 rad of ~0.1 rad
    assert not [w for w in metrics["warnings"] if "expected" in w]


def test_autotune_promises_what_the_step_analysis_expects(tmp_path):
    # autotune designs on the loop as it runs; the step analysis of a run with its gains, at its step, from its
    # rest, expects the same numbers: the same model (the figures read as autotune reads them are equal to the
    # last digits), and read as the run is read (overshoot and the rest: the same definitions).
    folder = tmp_path / "arm"
    folder.mkdir()
    robot = write_arm(folder)

    def scenario_for(overrides=()):
        return resolve_target(robot, overrides=list(overrides), robot_defaults=["duration_s=5"]).scenario

    result = autotune(scenario_for, "shoulder_pitch_position_controller", bandwidth_hz=2.0, zeta=0.7, step=0.1,
                      check_on_robot=False, alternatives=False)
    gains, model = result["gains"], result["model"]
    after = check_after_s(result["spec"]["step_settling_s"])
    scenario = shoulder_step(folder, result["reference"], result["reference"] + result["step"], pid=gains,
                             derivative=result["derivative"], initial=result["model_rest"], at=0.5,
                             duration_s=0.5 + after)
    metrics = run_scenario(load_scenario(scenario), tmp_path / "out")
    promised = metrics["theory"]["model_step"]
    for key in ("overshoot_pct", "settling_s", "final", "final_error", "peak_effort", "saturated_share"):
        assert promised[key] == pytest.approx(model[key], rel=1e-9, abs=1e-12), key
    assert metrics["expected"]["overshoot_pct"] == pytest.approx(model["overshoot_pct"], rel=1e-6)
    assert metrics["expected"]["steady_state_error_rad"] == pytest.approx(model["final_error"], rel=1e-6)
    assert metrics["expected"]["peak_effort_n_m"] == pytest.approx(model["peak_effort"], rel=1e-12)
    # ... and the run gives them, to the gravity profile's interpolation.
    assert metrics["overshoot_pct"] == pytest.approx(model["overshoot_pct"], abs=100 * 2 * ARM_REPLICA_RAD / 0.1)


def test_a_sweep_rows_theory_is_its_own_payloads():
    # Without gravity (the sag would ring at the step): m = 1.01 kg + payload, d 18 on the error.
    rows = {payload: evaluate(RunTask(0, "one_dof_step", {"payload_kg": payload},
                                      overrides=("gravity=0", "duration_s=3",
                                                 "controllers.joint1_position_controller.pid.d=18")))
            for payload in (0.0, 2.0)}
    for payload, row in rows.items():
        assert row.error is None
        metrics = row.metrics
        assert metrics["theory.inertia"] == pytest.approx(M_KG + payload, rel=1e-9)
        for key in ("overshoot_pct", "natural_frequency_rad_s", "damping_ratio", "settling_time_s"):
            assert metrics[f"theory.model.{key}"] == pytest.approx(metrics[key], rel=1e-6), (payload, key)
    light, heavy = rows[0.0].metrics, rows[2.0].metrics
    # A heavier piston rings more: ζ = (b + d)/(2√(Kp·m)) falls as 1/√m (0.70 -> 0.40).
    assert heavy["theory.model.damping_ratio"] < 0.7 * light["theory.model.damping_ratio"]
    assert heavy["theory.model.natural_frequency_rad_s"] == pytest.approx(math.sqrt(KP / (M_KG + 2.0)), rel=0.01)

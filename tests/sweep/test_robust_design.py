"""Robust autotune on the 1-DOF robot (a vertical piston, 1.01 kg, damping 10 N·s/m, 1000 N) at the user's step,
against its theory: a P loop rests (m + payload)·g/p below its reference; with PD on the measurement ωn = sqrt(p/m)
and ζ = (b + d)/(2 sqrt(p m)) per payload, so the nominal design for 1.01 kg rings with a 5 kg payload. Every
figure asserted is one measured on the simulated robot, plant by plant, at the step asked."""

from __future__ import annotations

import json
import math

import pytest
import yaml

from jointctl.cli import main
from jointctl.errors import ConfigError
from jointctl.identification.autotune import spec_from_step
from jointctl.identification.step_loop import JointLoop
from jointctl.scenario.targets import resolve_target
from jointctl.sweep.robust_design import (Plant, design_family, family, family_binds, family_damping,
                                          integral_hold_s, member, parse_range, robust_autotune)

MEASUREMENT = ["controllers.joint1_position_controller.derivative=measurement"]
MASS_KG, DAMPING, LIMIT_N, G = 1.01, 10.0, 1000.0, 9.81
OVERSHOOT_PCT, SETTLING_S = 10.0, 0.3


def scenario_for(extra=()):
    return lambda overrides: resolve_target("one_dof", overrides=[*extra, *overrides]).scenario


def continuous_overshoot_pct(p: float, d: float, m: float, b: float = DAMPING) -> float:
    zeta = (b + d) / (2 * math.sqrt(p * m))
    return 100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)) if zeta < 1 else 0.0


def design(step: float, extra=(), **kwargs) -> dict:
    zeta, bandwidth = spec_from_step(OVERSHOOT_PCT, SETTLING_S)
    return robust_autotune(scenario_for(extra), "joint1_position_controller", ["payload_kg=0:5"],
                           overshoot_pct=OVERSHOOT_PCT, settling_s=SETTLING_S, zeta=zeta, bandwidth_hz=bandwidth,
                           step=step, target="one_dof", overrides=list(extra), **kwargs)


def assert_dynamics_meet_the_spec(rows: list[dict], step: float) -> None:
    """Every plant's step, as measured: the user's step (a constant load moves the rest, not the move), its
    overshoot at most 3 points above and its settling at most 15 % beyond the spec; the worst plant lands on
    the spec (within 3 points and 15 % either way)."""
    for row in rows:
        assert "error" not in row, row
        assert row["final"] - row["start"] == pytest.approx(step, abs=0.02 * step)
        assert row["overshoot_pct"] <= OVERSHOOT_PCT + 3 and row["settling_s"] <= SETTLING_S * 1.15, row
        assert row["moving_at_step"] is not True, row  # at rest when the step came
    assert max(r["overshoot_pct"] for r in rows) == pytest.approx(OVERSHOOT_PCT, abs=3.0)
    assert max(r["settling_s"] for r in rows) == pytest.approx(SETTLING_S, rel=0.15)


def row_at(rows: list[dict], payload: float) -> dict:
    return next(r for r in rows if r["values"]["payload_kg"] == payload)


def test_the_family_is_the_corners_the_centre_and_the_draws() -> None:
    scenario = scenario_for()(())
    plants = family(scenario, "joint1", [parse_range("payload_kg=0:5"), parse_range("model.joint1.damping=7:13")],
                    samples=4, seed=3)
    assert len(plants) == 4 + 1 + 4
    corners = {(p.values["payload_kg"], p.values["model.joint1.damping"]): p for p in plants[:4]}
    assert set(corners) == {(0.0, 7.0), (0.0, 13.0), (5.0, 7.0), (5.0, 13.0)}
    # A payload on the piston adds its mass to the joint's inertia and its weight to the load over the whole
    # stroke; the joint's damping is the varied one.
    assert corners[(5.0, 13.0)].inertia == pytest.approx(MASS_KG + 5.0, rel=1e-9)
    assert corners[(0.0, 7.0)].inertia == pytest.approx(MASS_KG, rel=1e-9) and corners[(0.0, 7.0)].damping == 7.0
    assert corners[(5.0, 7.0)].gravity_load == pytest.approx((MASS_KG + 5.0) * G, rel=1e-6)
    for q in (-0.9, -0.5, -0.1):
        assert corners[(5.0, 7.0)].hold(q) == pytest.approx((MASS_KG + 5.0) * G, rel=1e-6)
        assert corners[(0.0, 7.0)].hold(q) == pytest.approx(MASS_KG * G, rel=1e-6)
    again = family(scenario, "joint1", [parse_range("payload_kg=0:5"), parse_range("model.joint1.damping=7:13")],
                   samples=4, seed=3)
    assert [p.values for p in again] == [p.values for p in plants]  # the seed decides the draws


@pytest.mark.slow
def test_the_issue_case_at_03_m_says_gravity_binds_and_the_integral_holds_every_payload() -> None:
    """1-DOF, payload 0-5 kg, 10 % in 0.3 s, a 0.3 m step with ros_controllers' law: the dynamics meet the spec
    on every plant at that step, but no P loop that settles in 0.3 s holds 6 kg within 6 mm; said, and the
    integral (checked on the robot) ends every plant at its reference."""
    result = design(0.3)
    robust = result["robust"]
    rows = robust["robot"]
    assert result["spec"]["step"] == 0.3 and robust["derivative"] == "error"
    assert_dynamics_meet_the_spec(rows, 0.3)
    # The promise is the measurement: the model (MuJoCo's integration, the clamped kick) and the robot agree.
    assert robust["robot_worst"]["overshoot_pct"] == pytest.approx(robust["model_worst"]["overshoot_pct"], abs=0.1)
    assert robust["robot_worst"]["settling_s"] == pytest.approx(robust["model_worst"]["settling_s"], rel=0.01)
    # Gravity binds: the 5 kg plant rests (m + 5)·g/p short of its reference, beyond the 2 % band of 0.3 m.
    p = robust["gains"]["p"]
    heavy = row_at(rows, 5.0)
    assert heavy["final_error"] == pytest.approx((MASS_KG + 5.0) * G / p, rel=0.01)
    assert heavy["final_error"] > 0.02 * 0.3 and "gravity" in heavy["binds"]
    assert {"payload_kg": 5.0} in result["binds"]["gravity"] and not result["meets_spec"]
    assert any("the gravity load at payload_kg 5" in w for w in result["warnings"])
    # The nominal design (for the bare piston) rings with the payload, measured at the same step.
    assert result["nominal"]["robot_worst"]["overshoot_pct"] > OVERSHOOT_PCT + 3
    assert result["nominal"]["robot_worst"]["overshoot_pct_at"] == {"payload_kg": 5.0}
    # The remedies for gravity, each checked on the robot. The integral holds every payload at the reference.
    alternatives = result["alternatives"]
    assert set(alternatives) == {"feedforward", "integral"}
    integral = alternatives["integral"]
    assert integral["meets_spec"] and integral["gains"]["i"] > 0 and integral["gains"]["antiwindup"] is True
    worst = integral["robot_worst"]
    assert abs(worst["final_error"]) <= 0.02 * 0.3  # every plant within the band (and 5 % of the step)
    assert worst["overshoot_pct"] == pytest.approx(OVERSHOOT_PCT, abs=3.0)
    assert worst["settling_s"] == pytest.approx(SETTLING_S, rel=0.15)
    assert any(w.startswith("--remedy integral: ") and "(meets the spec on every plant)" in w
               for w in result["warnings"])
    # The feed-forward is the controller's nominal model: the payload's own weight is still the P term's.
    feedforward = alternatives["feedforward"]
    assert feedforward["robot_worst"]["final_error_at"] == {"payload_kg": 5.0}
    assert feedforward["robot_worst"]["final_error"] == pytest.approx(5.0 * G / feedforward["gains"]["p"], rel=0.01)
    assert not feedforward["meets_spec"] and feedforward["binds"] == ["gravity"]


@pytest.mark.slow
def test_with_the_integral_asked_every_payload_ends_at_its_reference_and_the_yaml_says_so(tmp_path, capsys) -> None:
    out = tmp_path / "robust"
    assert main(["autotune", "one_dof", "--controller", "joint1_position_controller", "--overshoot-pct", "10",
                 "--settling-s", "0.3", "--step", "0.3", "--robust", "payload_kg=0:5", "--robust-samples", "2",
                 "--remedy", "integral", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    printed = json.loads(captured.out)
    assert "warning" not in captured.err
    assert printed["meets_spec"] and printed["remedies"] == ["integral"] and "alternatives" not in printed
    rows = printed["robust"]["robot"]
    assert len(rows) == 2 + 1 + 2
    assert_dynamics_meet_the_spec(rows, 0.3)
    for row in rows:  # the loaded joint ends at its reference: within the 2 % band, and so within 5 % of the step
        assert abs(row["final_error"]) <= 0.02 * 0.3, row
    gains = printed["robust"]["gains"]
    # The integral holds the heaviest load: its clamp twice that, (1.01 + 5)·g·2.
    assert gains["i_clamp"] == pytest.approx(2 * (MASS_KG + 5.0) * G, rel=1e-3)
    assert json.loads((out / "metrics.json").read_text())["robust"]["gains"] == gains
    written = yaml.safe_load((out / "one_dof_pos_ctl_params.yaml").read_text())
    pid = written["one_DOF_robot"]["joint1_position_controller"]["pid"]
    assert pid == pytest.approx({k: v if isinstance(v, bool) else round(v, 6) for k, v in gains.items()})


@pytest.mark.slow
def test_the_nominal_design_rings_with_a_payload_as_theory_says_and_the_robust_one_does_not() -> None:
    """Derivative on the measurement, a 0.1 m step: the nominal design's overshoot at 5 kg is the continuous
    theory's (ζ falls as 1/sqrt(m)), measured on the robot; the robust gains damp the heaviest plant."""
    result = design(0.1, MEASUREMENT, remedies=("integral",), alternatives=False)
    nominal, robust = result["nominal"], result["robust"]
    assert robust["derivative"] == "measurement"
    p, d = nominal["gains"]["p"], nominal["gains"]["d"]
    heavy = continuous_overshoot_pct(p, d, MASS_KG + 5.0)
    assert heavy > 40  # "about 45 %"
    assert nominal["robot_worst"]["overshoot_pct_at"] == {"payload_kg": 5.0}
    # The nominal design carries its own integral (for the bare piston's load): its slow tail is within a point.
    assert nominal["robot_worst"]["overshoot_pct"] == pytest.approx(heavy, abs=2.0)
    assert result["meets_spec"] and result["meets_spec_on_model"]
    assert_dynamics_meet_the_spec(robust["robot"], 0.1)
    assert continuous_overshoot_pct(robust["gains"]["p"], robust["gains"]["d"], MASS_KG + 5.0) <= OVERSHOOT_PCT + 3


@pytest.mark.parametrize("item, fragment", [("payload_kg=5:0", "LOW below HIGH"), ("payload_kg=1", "FIELD=LOW:HIGH"),
                                            ("latency_cycles=0:3", "varies the plant"),
                                            ("payload_kg=a:b", "numbers")])
def test_bad_ranges_are_refused(item, fragment) -> None:
    with pytest.raises(ConfigError) as caught:
        parse_range(item)
    assert caught.value.field == "--robust" and fragment in str(caught.value)


def test_a_field_the_robot_does_not_have_is_refused_before_anything_is_written(tmp_path, capsys) -> None:
    assert main(["autotune", "one_dof", "--controller", "joint1_position_controller", "--overshoot-pct", "10",
                 "--settling-s", "0.3", "--robust", "model.nothing.mass=1:2", "--out", str(tmp_path / "x")]) == 2
    assert "nothing" in capsys.readouterr().err and not (tmp_path / "x").exists()


# -- the family's search on the loop model alone (no robot) ------------------------------------------------------

def plants_without_load(*masses: float) -> list[Plant]:
    return [Plant({"mass": m}, m, DAMPING, 0.0, None) for m in masses]


def test_the_family_damping_gives_the_largest_overshoot_asked() -> None:
    """With PD on the measurement, each plant's overshoot falls as d grows: the heaviest one sets d."""
    from jointctl.identification.step_loop import reference_step

    plants = plants_without_load(1.0, 3.0, 6.0)
    loop = JointLoop(1.0, DAMPING, 0.001, p=2000.0, derivative="measurement", integrator="euler")
    reference = reference_step(0.0, 0.1, hold_s=0.05, after_s=2.0)
    found = family_damping(loop, plants, reference, OVERSHOOT_PCT)
    overshoots = [member(found, plant).step(reference).overshoot_pct for plant in plants]
    assert max(overshoots) == pytest.approx(OVERSHOOT_PCT, abs=0.1)
    assert overshoots.index(max(overshoots)) == 2
    # Continuous theory at the heaviest plant: ζ of 10 %, 0.59, within the hold's few percent.
    assert (DAMPING + found.d) / (2 * math.sqrt(2000.0 * 6.0)) == pytest.approx(0.591, rel=0.03)


def test_an_effort_that_binds_is_said_and_lower_bandwidth_relaxes_the_settling_to_what_it_allows() -> None:
    # 0.4 m on 6 kg with 1000 N: no sooner than 2·sqrt(0.4·6/1000) = 98 ms (accelerating half-way, braking the
    # rest); 30 ms asked.
    plants = plants_without_load(1.0, 6.0)
    base = JointLoop(1.0, DAMPING, 0.001, LIMIT_N, p=2000.0, derivative="measurement", integrator="euler")
    found = design_family(base, plants, 0.0, 0.4, overshoot_pct=OVERSHOOT_PCT, settling_s=0.03)
    assert not found.met and "effort" in found.binds[1]
    relaxed = design_family(base, plants, 0.0, 0.4, overshoot_pct=OVERSHOOT_PCT, settling_s=0.03,
                            remedies=("lower-bandwidth",))
    assert relaxed.met and relaxed.settling_s > 2 * math.sqrt(0.4 * 6 / LIMIT_N)
    worst = max(f.settling_s for f in relaxed.figures)
    assert worst == pytest.approx(relaxed.settling_s, rel=0.15)


def test_a_ramp_keeps_every_plants_kick_inside_half_the_effort() -> None:
    """ros_controllers' law kicks d·step/h on a step; the ramp spreads it: d·step/ramp ≤ half the limit."""
    plants = plants_without_load(1.0, 6.0)
    base = JointLoop(1.0, DAMPING, 0.001, LIMIT_N, p=2000.0, derivative="error", integrator="euler")
    found = design_family(base, plants, 0.0, 0.3, overshoot_pct=OVERSHOOT_PCT, settling_s=0.3, remedies=("ramp",))
    assert found.ramp_s > 0
    assert found.loop.d * 0.3 / found.ramp_s <= 0.5 * LIMIT_N * (1 + 1e-9)


def test_the_worst_plant_is_held_to_the_spec_from_below_too() -> None:
    from jointctl.identification.step_loop import StepFigures

    def figures(overshoot: float, settling: float) -> StepFigures:
        return StepFigures(overshoot, settling, 0.0, 0.1, 0.0, 0.0, 0.0)

    # Every plant better than asked: the worst one says the plant's own damping binds (with d = 0) ...
    binds = family_binds([figures(1.0, 0.3), figures(5.0, 0.3)], 0.0, 0.1, OVERSHOOT_PCT, SETTLING_S)
    assert binds == ((), ("damping",))
    # ... a plant of the family may do better than the worst; the worst one too slow is the spec's.
    binds = family_binds([figures(1.0, 0.1), figures(10.0, 0.4)], 5.0, 0.1, OVERSHOOT_PCT, SETTLING_S)
    assert binds == ((), ("spec",))


def test_a_run_whose_integral_starts_empty_holds_until_its_slowest_mode_has_taken_the_sag_out() -> None:
    # m s³ + (b + d) s² + p s + i with a slow integral: its slowest root is close to -i/p.
    loop = JointLoop(1.0, DAMPING, 0.001, p=2000.0, i=200.0, d=50.0)
    rate = 200.0 / 2000.0
    hold = integral_hold_s(loop, 0.01, 0.1)
    assert hold == pytest.approx(0.5 + math.log(0.01 / (0.002 * 0.1)) / rate, rel=0.01)


@pytest.mark.slow
def test_a_ramped_step_is_designed_and_measured_as_it_runs() -> None:
    """ros_controllers' law with --remedy ramp: the step's kick d·step/ramp within half of what the load leaves
    on every plant, and each plant's ramped move measured on the robot (its settling from the ramp's start)."""
    result = design(0.3, remedies=("ramp", "integral"), samples=0, alternatives=False)
    robust = result["robust"]
    ramp = robust["ramp_s"]
    assert ramp > 0 and robust["derivative"] == "error"
    assert robust["gains"]["d"] * 0.3 / ramp <= 0.5 * (LIMIT_N - (MASS_KG + 5.0) * G) * (1 + 1e-9)
    assert result["meets_spec"] and len(robust["robot"]) == 3
    assert_dynamics_meet_the_spec(robust["robot"], 0.3)
    for row in robust["robot"]:
        assert abs(row["final_error"]) <= 0.02 * 0.3, row


def test_a_step_that_would_take_some_plant_beyond_the_joints_range_is_refused_naming_it() -> None:
    """The piston's stroke is [-1, 0] m: 0.45 m up from -0.5 m with an undamped loop (d = 0, ζ = b/(2 sqrt(p m))
    about 0.1 for the bare piston) swings well past the top."""
    from jointctl.identification.plant_fit import IdentificationError
    from jointctl.model.loader import load_robot_model
    from jointctl.sweep.robust_design import FamilyDesign, check_limits

    scenario = scenario_for()(())
    plants = family(scenario, "joint1", [parse_range("payload_kg=0:5")], samples=0)
    loop = JointLoop(MASS_KG, DAMPING, 0.001, LIMIT_N, p=2000.0, d=0.0, derivative="measurement",
                     integrator="euler")
    design_ = FamilyDesign(loop, (), (), False, SETTLING_S, 0.0)
    robot = load_robot_model(scenario.robot.description)
    with pytest.raises(IdentificationError) as caught:
        check_limits(design_, plants, robot, "joint1", {"joint1": -0.5}, -0.5, 0.45)
    assert "at payload_kg 0:" in str(caught.value) and caught.value.field == "--step"
    check_limits(design_, plants, robot, "joint1", {"joint1": -0.5}, -0.5, 0.05)  # a small step fits


@pytest.mark.slow
def test_a_pid_controller_is_designed_against_the_family_and_written_as_its_ros2_parameters(tmp_path, capsys) -> None:
    """The robot's ROS 2 file (pid_controller on the piston's effort): every plant runs under pid_controller on the
    simulated robot (a fresh PID: its first cycle differentiates the error from 0) and meets the spec at the step;
    the gains go into its parameters as doubles, the integral's clamp both ways."""
    out = tmp_path / "robust"
    assert main(["autotune", "one_dof", "--controllers", "ros2", "--controller", "pid_controller", "--overshoot-pct",
                 "10", "--settling-s", "0.3", "--step", "0.3", "--robust", "payload_kg=0:5", "--robust-samples", "2",
                 "--remedy", "integral", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    printed = json.loads(captured.out)
    assert "warning" not in captured.err
    robust = printed["robust"]
    assert printed["meets_spec"] and robust["law"] == "control_toolbox" and robust["derivative"] == "error"
    assert_dynamics_meet_the_spec(robust["robot"], 0.3)
    for row in robust["robot"]:
        assert abs(row["final_error"]) <= 0.02 * 0.3, row
    # The promise is the measurement: the model and the runs under pid_controller agree.
    assert robust["robot_worst"]["overshoot_pct"] == pytest.approx(robust["model_worst"]["overshoot_pct"], abs=0.2)
    gains = robust["gains"]
    assert gains["i_clamp"] == pytest.approx(2 * (MASS_KG + 5.0) * G, rel=1e-3)
    written = yaml.safe_load((out / "one_dof_ros2_controllers.yaml").read_text())
    joint1 = written["pid_controller"]["ros__parameters"]["gains"]["joint1"]
    assert joint1 == pytest.approx({"p": round(gains["p"], 6), "i": round(gains["i"], 6), "d": round(gains["d"], 6),
                                    "i_clamp_max": round(gains["i_clamp"], 6), "i_clamp_min": -round(gains["i_clamp"], 6),
                                    "antiwindup": True})
    assert all(isinstance(v, float) for k, v in joint1.items() if k != "antiwindup")

"""jointctl's identification on its simulated robots, against the models' own numbers: the 1-DOF
robot's moving mass 1.01 kg (link2 1 kg + the sensor disk 0.01 kg), damping 10 N·s/m and gravity
load m·g; a Coulomb friction added to a copy of it; the arm's joint 1 around the pre-pose."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from jointctl.errors import ConfigError
from jointctl.identification.identify import identify_on_robot, identify_states, identify_trace
from jointctl.identification.plant_fit import IdentificationError
from jointctl.model import load_robot_model
from jointctl.model.dynamics import RobotDynamics
from jointctl.paths import robots_dir
from jointctl.scenario.spec import load_scenario, scenario_for_robot

MASS_KG, DAMPING, G = 1.01, 10.0, 9.81
DT = 0.001


@pytest.fixture(scope="module")
def one_dof(tmp_path_factory):
    out = tmp_path_factory.mktemp("identify")
    fit, metrics = identify_on_robot(scenario_for_robot("one_dof", "position"), "joint1", out_dir=out)
    return fit, metrics, out


def test_the_one_dof_robots_mass_damping_and_gravity_load(one_dof) -> None:
    fit, metrics, out = one_dof
    # MuJoCo's Euler step integrates damping implicitly: the joint behaves as a mass m + dt·b.
    assert metrics["mass_kg"] == pytest.approx(MASS_KG, rel=0.02)
    assert metrics["mass_kg"] == pytest.approx(MASS_KG + DT * DAMPING, rel=1e-3)
    assert metrics["damping_n_s_m"] == pytest.approx(DAMPING, rel=0.02)
    assert metrics["gravity_load_n"] == pytest.approx(MASS_KG * G, rel=0.01)
    assert abs(metrics["friction_n"]) < 0.01  # the URDF has none
    assert metrics["r_squared"] > 0.9999


def test_the_excitation_starts_and_ends_at_rest_where_it_started_inside_the_limits(one_dof) -> None:
    _, metrics, out = one_dof
    excitation = metrics["excitation"]
    assert excitation["lower"] < excitation["position_min"] < excitation["start"] < excitation["position_max"] \
        < excitation["upper"]
    written = json.loads((out / "metrics.json").read_text())
    assert written["mass_kg"] == metrics["mass_kg"]
    assert (out / "identify_joint1.png").stat().st_size > 10_000 and (out / "trace.csv").is_file()
    from jointctl.recording.trace import load_trace

    trace = load_trace(out / "trace.csv")
    q, qd = trace.joint("joint1", "position"), trace.joint("joint1", "velocity")
    assert abs(qd[-1]) < 1e-3  # at rest again
    assert excitation["rest_after"] == pytest.approx(excitation["rest_before"], abs=1e-3)  # where it rested
    assert q[-1] == pytest.approx(excitation["rest_after"], abs=1e-9)


def test_the_recorded_trace_identifies_the_same_joint(one_dof) -> None:
    fit, _, out = one_dof
    again, metrics = identify_trace(out / "trace.csv", "joint1", "prismatic")
    assert again.inertia == pytest.approx(fit.inertia, rel=1e-6)
    assert again.gravity_load == pytest.approx(fit.gravity_load, rel=1e-6)


def test_joint_states_with_lost_stretches_are_identified_and_the_cuts_reported(tmp_path) -> None:
    # States of every cycle (1 kHz) of a joint 1 kg, 10 N·s/m, 0.5 N friction, 9.81 N load, stamped a
    # little off the period, of which 10 ms at t = 3 s and 50 ms at t = 6.7 s were lost.
    t = np.arange(0.0, 10.0, DT)
    q = 0.3 * np.sin(2 * np.pi * 0.7 * t) + 0.1 * np.sin(2 * np.pi * 2.3 * t + 0.4)
    qd = np.gradient(q, DT)
    u = np.append(np.diff(qd) / DT, 0.0) + 10.0 * qd + 0.5 * np.sign(qd) + 9.81
    lost = ((t >= 3.0) & (t < 3.01)) | ((t >= 6.7) & (t < 6.75))
    stamps = t + np.where(np.arange(t.size) % 5 == 0, 1e-6, 0.0)  # jitter: 0.1 % of a period
    fit, metrics = identify_states(stamps[~lost], q[~lost], qd[~lost], u[~lost], "joint1", "prismatic",
                                   source="test", out_dir=tmp_path)
    data = metrics["data"]
    assert data["samples_received"] == t.size - 60 and data["samples_given"] == t.size - 60
    assert [g["at_s"] for g in data["gaps_cut"]] == pytest.approx([2.999, 6.699], abs=2e-6)
    assert [g["length_s"] for g in data["gaps_cut"]] == pytest.approx([0.011, 0.051], abs=2e-6)
    assert data["span_s"] == pytest.approx(10.0) and data["share_used"] == pytest.approx(0.994, abs=1e-6)
    assert fit.acceleration == "forward" and metrics["coupling"] == "none"
    # no difference spans a gap: the fit is the joint's (the jitter's interpolation error aside)
    assert metrics["mass_kg"] == pytest.approx(1.0, rel=1e-3)
    assert metrics["damping_n_s_m"] == pytest.approx(10.0, rel=1e-3)
    assert json.loads((tmp_path / "metrics.json").read_text())["data"]["gaps_cut"] == data["gaps_cut"]


def test_a_coulomb_friction_added_to_the_robot_is_recovered(tmp_path) -> None:
    source = (robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro").read_text()
    assert '<dynamics damping="10.0"/>' in source
    (tmp_path / "robot.xacro").write_text(source.replace('<dynamics damping="10.0"/>',
                                                         '<dynamics damping="10.0" friction="2.0"/>'))
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump({
        "name": "friction", "robot": "robot.xacro",
        "controller_file": str(robots_dir() / "one_dof" / "config" / "one_dof_pos_ctl_params.yaml"),
        "start_controllers": ["joint1_position_controller"], "initial_positions": {"joint1": -0.5},
        "duration_s": 1.0}))
    _, metrics = identify_on_robot(load_scenario(tmp_path / "scenario.yaml"), "joint1")
    assert metrics["friction_n"] == pytest.approx(2.0, rel=0.05)
    assert metrics["mass_kg"] == pytest.approx(MASS_KG, rel=0.02)
    assert metrics["damping_n_s_m"] == pytest.approx(DAMPING, rel=0.05)


def test_an_amplitude_beyond_the_limits_is_refused_before_anything_moves() -> None:
    # A 1 Hz sine (windowed) through the P loop: |T| = 1/sqrt((1 - r²)² + (2ζr)²) = 1.094 (r = 1/3.167, ζ 0.249);
    # the swing A·|T| and the droop m·g/p = 24.8 mm may use 0.3 of the 0.5 m to the nearer limit.
    with pytest.raises(IdentificationError, match="the joint's range binds") as info:
        identify_on_robot(scenario_for_robot("one_dof", "position"), "joint1", amplitude=0.4, f_start_hz=1.0,
                          f_end_hz=1.0)
    assert info.value.field == "amplitude"
    safe = float(str(info.value).split("at most ")[1].split()[0])
    # 0.3 of the room from where the piston rests (its droop m·g/p below the reference), over the peak gain.
    assert safe == pytest.approx(0.3 * (0.5 - MASS_KG * G / 400.0) / 1.0944, rel=0.03)


def test_the_guard_returns_the_joint_before_a_limit(tmp_path) -> None:
    # Resonance: planned on the chapter's plant (ζ 0.25: |T| 2 at 3.17 Hz), a copy of the robot damped by
    # 2 N·s/m (ζ 0.05: |T| 10) swings five times more than planned. Resting at -0.85 m (0.15 m from the
    # lower limit, 25 mm droop), it reaches the guard's 0.05 m band; the reference ramps back to the start.
    from tests.identification.variants import one_dof_variant, plant

    scenario = one_dof_variant(tmp_path, damping=2.0, initial=-0.85)
    with pytest.raises(IdentificationError, match="came within 0.05 of a limit") as info:
        identify_on_robot(scenario, "joint1", f_start_hz=3.17, f_end_hz=3.17, out_dir=tmp_path, plant=plant())
    from jointctl.recording.trace import load_trace

    q = load_trace(tmp_path / "trace.csv").joint("joint1", "position")
    assert -1.0 < q.min() and q.max() < 0.0  # never beyond the limits
    assert info.value.field == "position"


def test_a_joint_without_a_position_controller_is_refused() -> None:
    with pytest.raises(ConfigError, match="JointPositionController"):
        identify_on_robot(scenario_for_robot("one_dof", "velocity"), "joint1")
    with pytest.raises(ConfigError, match="movable: joint1"):
        identify_on_robot(scenario_for_robot("one_dof", "position"), "joint9")


@pytest.mark.slow
def test_the_arms_joint1_around_the_pre_pose() -> None:
    pre_pose = [0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0]
    scenario = scenario_for_robot("arm7dof", "position",
                                  [f"initial_positions.joint{k}={q}" for k, q in enumerate(pre_pose)])
    _, metrics = identify_on_robot(scenario, "joint1", f_start_hz=0.2, f_end_hz=1.0)
    robot = load_robot_model(robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro")
    dynamics = RobotDynamics(robot)
    dynamics.set_pose(pre_pose)
    inertia = dynamics.mass_matrix()[1, 1]  # joint 1 sees M11 (armature included) at the others' pose
    swing = metrics["excitation"]["amplitude"]
    # The held joints' small motions load joint 1 through the inertia matrix; the fit subtracts that
    # load (computed from the model) and scales by M11(q)/M11(rest), so what is left is M11 at rest plus
    # the implicit damping's dt·b = 0.01 kg·m² (not scaled with M11: 1e-8 of it), and the URDF's damping.
    assert metrics["coupling"] == "model"
    assert metrics["inertia_kg_m2"] == pytest.approx(inertia + DT * 10.0, rel=1e-6)
    assert metrics["damping_n_m_s_rad"] == pytest.approx(10.0, rel=1e-6)
    load = metrics["gravity_sin_n_m"] * math.sin(1.0) + metrics["gravity_cos_n_m"] * math.cos(1.0)
    assert load == pytest.approx(dynamics.gravity_at_pose()[1], rel=0.02)
    assert 0 < swing <= 0.5 * 0.2 / (2 * math.pi * 1.0)  # half the 0.2 rad/s limit at 1 Hz

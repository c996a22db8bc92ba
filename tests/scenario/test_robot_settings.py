"""The scenario's settings of the simulated robot (payload_kg, model.*, latency_cycles, noise.*): read and checked by
the scenario loader, applied by the session to the simulated robot only, reachable by ``--set`` from every command.

Theory on the 1-DOF robot (P loop, Kp 400, Kd 0, joint damping b 10, no feed-forward): the piston and its sensor
disk move m = 1.01 kg; a payload p adds to it. At rest the loop holds the weight, Kp·e = (m + p)·g; about the rest
it rings at ωn = √(Kp/(m + p)) with ζ = b/(2√(Kp·(m + p)))."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from jointctl.cli import main
from jointctl.errors import ConfigError
from jointctl.hardware.imperfect import ImperfectHardware
from jointctl.hardware.mujoco_hardware import MujocoHardware
from jointctl.recording.trace import load_trace
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from jointctl.sim.mjcf_builder import WorldSettings
from jointctl.sim.world import MujocoWorld
from tests.conftest import step_scenario

M_KG, B, KP, G, DT = 1.01, 10.0, 400.0, 9.81, 0.001


def test_a_scenario_holds_the_simulated_robots_settings(write_scenario):
    scenario = load_scenario(write_scenario(step_scenario(
        payload_kg=2.5, model={"joint1": {"damping": 3, "friction": 0.5}, "link2": {"mass": 2}}, latency_cycles=2,
        noise={"position": 1e-4, "velocity": 2e-3, "seed": 7})))
    assert scenario.payload_kg == 2.5 and scenario.latency_cycles == 2
    assert scenario.model_changes == {"model.joint1.damping": 3.0, "model.joint1.friction": 0.5,
                                      "model.link2.mass": 2.0}
    assert (scenario.noise.position, scenario.noise.velocity, scenario.noise.seed) == (1e-4, 2e-3, 7)
    nominal = load_scenario(write_scenario(step_scenario(), "nominal.yaml"))
    assert (nominal.payload_kg, nominal.model_changes, nominal.latency_cycles) == (0.0, {}, 0)
    assert (nominal.noise.position, nominal.noise.velocity) == (0.0, 0.0)


@pytest.mark.parametrize("item, field, says", [
    ("payload_kg=-1", "payload_kg", "must be a mass, 0 or more [kg]"),
    ("payload_kg=heavy", "payload_kg", "must be a mass"),
    ("latency_cycles=-1", "latency_cycles", "must not be negative"),
    ("latency_cycles=1.5", "latency_cycles", "whole number of control cycles"),
    ("noise.position=-1e-3", "noise.position", "standard deviation, 0 or more"),
    ("noise.velocity=.nan", "noise.velocity", "standard deviation"),
    ("noise.postion=1e-3", "noise.postion", "did you mean 'position'"),
    ("noise.seed=-3", "noise.seed", "whole number"),
    ("noise=0.1", "noise", "must be a mapping"),
    ("model.joint1.dampin=3", "model.joint1.dampin", "did you mean 'damping'"),
    ("model.joint1.damping=-2", "model.joint1.damping", "must not be negative"),
    ("model.link2.mass=0", "model.link2.mass", "a mass must be positive"),
    ("model.joint1=3", "model.joint1", "must be a mapping"),
    ("payload=5", "payload", "did you mean 'payload_kg'"),
])
def test_bad_settings_are_refused_naming_the_field_and_the_value(item, field, says):
    with pytest.raises(ConfigError) as caught:
        load_scenario("one_dof_step", [item])
    assert caught.value.field == field and says in caught.value.message, str(caught.value)
    assert caught.value.source.endswith("one_dof_step.yaml")


def test_a_link_or_joint_the_robot_lacks_is_refused_with_the_nearest_when_the_session_reads_the_robot():
    for item, says in (("model.jont1.damping=3", "did you mean 'joint1'"),
                       ("model.link2.damping=3", "unknown field (known: ixx, ixy, ixz, iyy, iyz, izz, mass)")):
        with pytest.raises(ConfigError) as caught:
            Session(load_scenario("one_dof_step", [item]))
        assert caught.value.field == item.partition("=")[0] and says in caught.value.message
        assert caught.value.source.endswith("one_dof_step.yaml")


def test_the_session_simulates_the_changed_robot_and_gives_the_controllers_the_nominal_model():
    scenario = load_scenario("one_dof_step", ["model.joint1.damping=3", "payload_kg=5"])
    with Session(scenario) as session:
        assert session.robot.joint("joint1").damping == 10.0
        assert session.plant.joint("joint1").damping == 3.0
        disk = "ft_sensor_link"  # the 1-DOF robot's last link carries the payload
        assert session.plant.link(disk).inertial.mass_kg == pytest.approx(
            session.robot.link(disk).inertial.mass_kg + 5.0)
        assert session.world.robot is session.plant
        assert session.manager.robot is session.robot
        assert session.manager.controller("joint1_position_controller").joint_damping == 10.0


def test_latency_and_noise_put_the_simulated_hardware_behind_its_imperfections():
    with Session(load_scenario("one_dof_step", ["latency_cycles=3", "noise.velocity=1e-3"])) as session:
        assert isinstance(session.hardware, ImperfectHardware)
        assert session.hardware.latency_cycles == 3 and session.hardware.velocity_noise == 1e-3
    with Session(load_scenario("one_dof_step")) as session:
        assert not isinstance(session.hardware, ImperfectHardware)


def test_the_settings_of_a_simulated_robot_are_refused_on_given_hardware():
    nominal = load_scenario("one_dof_step")
    for item in ("payload_kg=1", "model.joint1.damping=3", "latency_cycles=1", "noise.position=1e-3"):
        scenario = load_scenario("one_dof_step", [item])
        world = MujocoWorld(Session(nominal).robot, WorldSettings(0.001, (0.0, 0.0, -9.81), True))
        with pytest.raises(ConfigError) as caught:
            Session(scenario, hardware=MujocoHardware(world))
        assert caught.value.field == item.partition("=")[0] and "simulated robot" in caught.value.message


def test_an_imperfect_hardware_that_changes_nothing_gives_the_same_run_bit_for_bit(tmp_path):
    scenario = load_scenario("one_dof_step", ["duration_s=1"])
    robot = Session(scenario).robot
    traces = []
    for k, wrap in enumerate((lambda hw: hw, ImperfectHardware)):
        world = MujocoWorld(robot, WorldSettings(scenario.timestep_s, scenario.gravity_m_s2, scenario.floor),
                            initial_positions=scenario.initial_positions)
        with Session(scenario, out_dir=tmp_path / str(k), hardware=wrap(MujocoHardware(world))) as session:
            session.run()
        traces.append(load_trace(session.trace_path))
    assert traces[0].columns.keys() == traces[1].columns.keys()
    assert all(np.array_equal(traces[0][c], traces[1][c]) for c in traces[0].columns)


def test_an_analysis_that_runs_its_scenario_again_runs_it_on_the_same_changed_robot(tmp_path):
    from jointctl.scenario.analyses.common import run_variant

    scenario = load_scenario("one_dof_step", ["duration_s=1", "model.joint1.damping=30"])
    with Session(scenario, out_dir=tmp_path / "run") as session:
        session.run()
    again = run_variant(session, tmp_path / "again", {})
    with Session(load_scenario("one_dof_step", ["duration_s=1"]), out_dir=tmp_path / "nominal") as nominal:
        nominal.run()
    varied, plain = load_trace(session.trace_path), load_trace(nominal.trace_path)
    assert np.array_equal(again.joint("joint1", "position"), varied.joint("joint1", "position"))
    assert not np.array_equal(plain.joint("joint1", "position"), varied.joint("joint1", "position"))


@pytest.mark.slow
def test_run_with_a_payload_rests_where_the_heavier_mass_sags_to(tmp_path, capsys):
    # The run starts at rest (the reference -0.2 m less the sag), so only the step rings. 11.5 s after the step the
    # ringing has decayed to 0.3 m·e^(-b/(2(m+p))·11.5 s) < 20 µm; the final value is the mean of the last 1.2 s,
    # smaller still. The fitted ωn and ζ of the 1 kHz loop are within ωn·dt.
    payload = 5.0
    m = M_KG + payload
    sag = m * G / KP
    out = tmp_path / "run"
    assert main(["run", "one_dof_step", "--set", f"payload_kg={payload}", "--set", "duration_s=12",
                 "--set", f"initial_positions.joint1={-0.2 - sag!r}", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["steady_state_error_m"] == pytest.approx(sag, abs=2e-5)
    assert metrics["final_value"] == pytest.approx(-0.5 - sag, abs=2e-5)
    wn = math.sqrt(KP / m)
    assert metrics["natural_frequency_rad_s"] == pytest.approx(wn, rel=wn * DT)
    assert metrics["damping_ratio"] == pytest.approx(B / (2 * math.sqrt(KP * m)), rel=wn * DT)
    # The analysis's theory is the simulated robot's: it expects what was measured, and warns of nothing.
    # The expectation is the model read like the run: the sag, and what is left of the ringing at 12 s.
    assert metrics["expected"]["steady_state_error_m"] == pytest.approx(sag, abs=2e-5)
    assert metrics["plant"]["moving_mass_kg"] == pytest.approx(m, rel=1e-3)
    assert metrics["warnings"] == [] and "warning" not in captured.err


@pytest.mark.slow
def test_run_with_a_joints_damping_changes_the_simulated_robot_not_the_controllers_model(tmp_path):
    # ζ = b/(2√(Kp·m)) with the simulated robot's b = 3 (the nominal 10 would give 0.249).
    out = tmp_path / "run"
    assert main(["run", "one_dof_step", "--set", "model.joint1.damping=3", "--set", "duration_s=4",
                 "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    wn = math.sqrt(KP / M_KG)
    assert metrics["damping_ratio"] == pytest.approx(3.0 / (2 * math.sqrt(KP * M_KG)), rel=wn * DT)
    assert metrics["expected"]["damping_ratio"] == pytest.approx(3.0 / (2 * math.sqrt(KP * M_KG)), rel=1e-3)


def test_an_unknown_setting_is_refused_in_one_line_with_the_nearest_name(tmp_path, capsys):
    assert main(["run", "one_dof_step", "--set", "payload_k=5", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("jointctl: error: ") and err.count("\n") == 1
    assert "payload_k: unknown field (did you mean 'payload_kg'?" in err
    assert not (tmp_path / "o").exists()

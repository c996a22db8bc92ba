"""Scenarios naming a ROS 2 controller file: the controller manager's update_rate is the loop's rate, and the 1-DOF
robot under ros2_controllers' pid_controller moves as control_toolbox's PID and the piston's equation say.

The piston (1.01 kg, 10 N·s/m, g 9.81 m/s²) is integrated here as MuJoCo does (semi-implicit Euler, damping
implicit, :mod:`tests.metrics.test_step_loop`); that replica follows the simulated robot to about 5e-11 m
(tests/scenario/test_step_expectation.py), so 1e-9 m leaves room for rounding only.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.errors import ConfigError
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario, scenario_for_robot

M_KG, B, G = 1.01, 10.0, 9.81
P, D = 400.0, 20.0
LIMIT_N = 1000.0


def ros2_step(write_scenario, *settings, **changes):
    scenario = {"name": "ros2_step", "robot": "one_dof", "controller_file": "ros2",
                "start_controllers": ["joint_state_broadcaster", "pid_controller"],
                "initial_positions": {"joint1": -0.2}, "duration_s": 0.5,
                "commands": {"pid_controller": {"type": "step", "from": -0.2, "to": -0.5, "at": 0.1}}}
    scenario.update(changes)
    return load_scenario(write_scenario(scenario), list(settings))


def test_the_update_rate_is_the_loop_rate_with_the_physics_at_the_scenarios_step(write_scenario):
    assert ros2_step(write_scenario).loop_period_s == pytest.approx(0.001)
    scenario = ros2_step(write_scenario, "timestep_s=0.0002")
    assert scenario.loop_period_s == pytest.approx(0.001) and scenario.timestep_s == 0.0002
    assert ros2_step(write_scenario, "loop_rate_hz=500").loop_period_s == pytest.approx(0.002)  # the scenario's wins


def test_an_update_rate_that_is_not_whole_physics_steps_is_refused_in_the_controller_file(write_scenario, tmp_path):
    controllers = tmp_path / "controllers.yaml"
    controllers.write_text("controller_manager:\n  ros__parameters:\n    update_rate: 300\n"
                           "    joint_state_broadcaster: {type: joint_state_broadcaster/JointStateBroadcaster}\n")
    with pytest.raises(ConfigError) as info:
        ros2_step(write_scenario, controller_file=str(controllers), start_controllers=["joint_state_broadcaster"],
                  commands={})
    assert info.value.source == str(controllers)
    assert info.value.field == "controller_manager.ros__parameters.update_rate" and info.value.value == 300


def test_serving_a_ros2_file_starts_every_controller_it_declares():
    scenario = scenario_for_robot("one_dof", "ros2")
    assert scenario.start_controllers == ("joint_state_broadcaster", "pid_controller")
    assert scenario.loop_period_s == pytest.approx(0.001)


def euler(q: float, v: float, force: float, h: float, n: int) -> tuple[float, float]:
    dt = h / n
    for _ in range(n):
        v = (v + dt * force / M_KG) / (1 + dt * B / M_KG)
        q = q + dt * v
    return q, v


@pytest.mark.slow
@pytest.mark.parametrize("substeps", [1, 4])
def test_a_step_under_pid_controller_is_control_toolboxs_pid_on_the_piston(write_scenario, tmp_path, substeps):
    scenario = ros2_step(write_scenario, f"timestep_s={0.001 / substeps!r}", "duration_s=3.0")
    with Session(scenario, out_dir=tmp_path / "out") as session:
        session.run()
    data = np.genfromtxt(session.trace_path, delimiter=",", names=True)
    h = 0.001
    q, v, e_last = -0.2, 0.0, 0.0  # the PID was just configured: its last error is 0
    expected, commands = [], []
    for r in data["joint1reference"]:
        e = r - q
        u = P * e + D * (e - e_last) / h  # no values_dot given: the rate is the error's difference
        e_last = e
        expected.append(q)
        commands.append(u)
        q, v = euler(q, v, min(LIMIT_N, max(-LIMIT_N, u)) - M_KG * G, h, substeps)
    step = int(np.argmax(data["joint1reference"] < -0.3))
    assert commands[step] < 5 * -LIMIT_N  # the kick d·Δr/h = -6000 N (and p·e), clamped at the limit
    assert np.max(np.abs(data["joint1position"] - np.array(expected))) < 1e-9
    # At rest the P term holds the load: the piston sits m·g/p below its reference.
    assert data["joint1position"][-1] == pytest.approx(-0.5 - M_KG * G / P, abs=1e-6)


JTC_FILE = """
controller_manager:
  ros__parameters:
    update_rate: 1000
    joint_state_broadcaster: {type: joint_state_broadcaster/JointStateBroadcaster}
    joint_trajectory_controller: {type: joint_trajectory_controller/JointTrajectoryController}
joint_trajectory_controller:
  ros__parameters:
    joints: [joint1]
    command_interfaces: [effort]
    state_interfaces: [position, velocity]
    gains: {joint1: {p: 400.0, d: 40.0}}
"""


@pytest.mark.slow
def test_a_goal_under_joint_trajectory_controller_is_its_pid_on_the_linear_path_from_where_the_piston_is(
        write_scenario, tmp_path):
    controllers = tmp_path / "jtc.yaml"
    controllers.write_text(JTC_FILE)
    t0, q_goal, duration = 0.2, -0.3, 1.0
    goal = {"joint_names": ["joint1"], "points": [{"positions": [q_goal], "time_from_start": duration}]}
    scenario = ros2_step(write_scenario, controller_file=str(controllers), commands={}, duration_s=3.0,
                         start_controllers=["joint_state_broadcaster", "joint_trajectory_controller"],
                         goals=[{"controller": "joint_trajectory_controller", "at_s": t0, "trajectory": goal}])
    rows = []
    with Session(scenario) as session:
        hw, references = session.hardware, session.manager.references
        session.loop.add_observer(lambda t: rows.append((t, hw.position[0], hw.velocity[0], references[0])))
        session.run()
    time, position, velocity, reference = (np.array(column) for column in zip(*rows))
    h, d = 0.001, 40.0
    start = int(round(t0 / h))
    q0 = position[start]  # the measured position the trajectory starts from
    slope = (q_goal - q0) / duration
    q, v = -0.2, 0.0
    expected = []
    for k, t in enumerate(time):
        desired = reference[k]
        if k >= start:  # the linear path from the measured position, then its last point held
            assert desired == pytest.approx(q0 + slope * min(t - t0, duration), abs=1e-12)
        v_desired = slope if start <= k < start + round(duration / h) else 0.0
        u = P * (desired - q) + d * (v_desired - v)
        expected.append(q)
        q, v = euler(q, v, min(LIMIT_N, max(-LIMIT_N, u)) - M_KG * G, h, 1)
    assert np.max(np.abs(position - np.array(expected))) < 1e-9
    # Done once the piston moves slower than stopped_velocity_tolerance after the last point (no goal tolerance).
    (handle,) = session.goals
    end = start + round(duration / h)
    stopped = end + int(np.argmax(np.abs(velocity[end:]) <= 0.01))
    assert handle.result.error_code == 0 and handle.result.time_s == pytest.approx(time[stopped])
    assert position[-1] == pytest.approx(q_goal - M_KG * G / P, abs=1e-6)  # held by the P term


def test_an_analysis_of_a_joint_a_ros2_type_commands_is_refused_before_the_run(write_scenario, tmp_path):
    from jointctl.scenario.run import run_scenario

    scenario = ros2_step(write_scenario, analysis={"type": "step_response", "joint": "joint1"})
    with pytest.raises(ConfigError) as info:
        run_scenario(scenario, tmp_path / "out")
    assert info.value.field == "analysis.joint" and "pid_controller" in str(info.value)

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


def toolbox_step(reference, start, p, d, *, i=0.0, i_max=0.0, i_min=0.0, antiwindup=False, rates=None,
                 substeps=1):
    """The piston under control_toolbox 3.4.0's PID as pid_controller runs it (written here from its
    computeCommand, not taken from jointctl): from ``start`` with the PID just configured (last error 0, so the
    first cycle differentiates e₀ from 0), the integral ``i_error += h·e`` (clamped to [i_min/i, i_max/i] with
    antiwindup, else the term i·i_error clamped to [i_min, i_max]), the derivative on the error's difference, or
    on ``rates[k] - v`` when the reference carries values_dot; no output limit: the actuator clamps at 1000 N."""
    h = 0.001
    q, v = start
    e_last = i_error = 0.0
    out = []
    for k, r in enumerate(reference):
        e = r - q
        if rates is None:
            e_dot = (e - e_last) / h
            e_last = e
        else:
            e_dot = rates[k] - v
        i_error += h * e
        if antiwindup and i:
            i_error = min(max(i_error, i_min / i), i_max / i)
        i_term = i * i_error if antiwindup else min(max(i * i_error, i_min), i_max)
        u = p * e + i_term + d * e_dot
        out.append(q)
        q, v = euler(q, v, min(LIMIT_N, max(-LIMIT_N, u)) - M_KG * G, h, substeps)
    return np.array(out)



@pytest.mark.slow
def test_the_step_analysis_expects_pid_controllers_run_with_its_first_cycle_kick(write_scenario, tmp_path):
    """A piston started 5 cm off the reference its pid_controller is given: the first cycle asks d·0.05/h (900 N)
    on top of p·e, the step's first cycle d·0.3/h (clamped at 1000 N). The loop as it runs (JointLoop, law
    control_toolbox) replicates the run to the model's 5e-11 m, and the analysis expects its figures to 1e-6; the
    ros_controllers law (first rate 0) misses the start by the kick's motion."""
    from jointctl.metrics.step_loop import JointLoop
    from jointctl.scenario.run import run_scenario

    d = 18.0
    scenario = ros2_step(write_scenario, f"controllers.pid_controller.gains.joint1.d={d!r}", initial_positions={
        "joint1": -0.25}, duration_s=3.0, commands={"pid_controller": {"type": "step", "from": -0.2, "to": -0.5,
                                                                       "at": 0.5}},
        analysis={"type": "step_response", "joint": "joint1"})
    metrics = run_scenario(scenario, tmp_path / "out")
    data = np.genfromtxt(tmp_path / "out" / "trace.csv", delimiter=",", names=True)
    reference, position = data["joint1reference"], data["joint1position"]
    written = toolbox_step(reference, (-0.25, 0.0), P, d)
    assert np.max(np.abs(position - written)) < 1e-9
    loop = JointLoop(M_KG, B, 0.001, LIMIT_N, lambda q: M_KG * G, p=P, d=d, integrator="euler",
                     law="control_toolbox")
    q, _, u = loop.run(reference, start=(-0.25, 0.0))
    assert np.max(np.abs(q - position)) < 1e-9
    assert u[0] == pytest.approx(P * 0.05 + d * 0.05 / 0.001, rel=1e-9)  # 920 N: the first cycle's kick
    ros_control, _, _ = loop.with_gains(law="ros_control").run(reference, start=(-0.25, 0.0))
    assert np.max(np.abs(ros_control - position)) > 1e-3  # without the kick the start is another motion
    assert "not_applicable" not in metrics
    for key in ("overshoot_pct", "settling_time_s", "natural_frequency_rad_s", "damping_ratio"):
        assert metrics["expected"][key] == pytest.approx(metrics[key], rel=1e-6), key
    assert metrics["expected"]["steady_state_error_m"] == pytest.approx(M_KG * G / P, rel=1e-6)
    assert metrics["expected"]["peak_effort_n"] == pytest.approx(LIMIT_N, rel=1e-12)
    assert metrics["theory"]["kd"] == d


@pytest.mark.slow
@pytest.mark.parametrize("clamps, antiwindup", [((0.0, 0.0), False), ((-5.0, 5.0), False), ((-5.0, 5.0), True),
                                                ((0.0, 20.0), True)])
def test_pid_controllers_integral_is_its_clamped_term_and_the_default_clamps_leave_none(write_scenario, tmp_path,
                                                                                       clamps, antiwindup):
    """i 2000 under gravity (m·g = 9.9 N; the loop's slowest root -9.9/s: settled in the 3.9 s after the step):
    with the default clamps 0/0 the integral does nothing (the piston rests m·g/p short), clamped to ±5 N it holds
    5 N of the load ((m·g - 5)/p short), clamped to [0, 20] it holds it all (at the reference). JointLoop follows
    each run to 1e-9 m."""
    from jointctl.control.position_loop import position_loop
    from jointctl.metrics.step_loop import JointLoop
    from jointctl.scenario.session import Session

    low, high = clamps
    settings = [f"controllers.pid_controller.gains.joint1.{k}={v!r}" for k, v in
                (("i", 2000.0), ("i_clamp_min", low), ("i_clamp_max", high), ("antiwindup", antiwindup))]
    scenario = ros2_step(write_scenario, *settings, "duration_s=4.0")
    with Session(scenario, out_dir=tmp_path / "out") as session:
        view = position_loop(session.manager.controller("pid_controller"))
        assert view.pid.gains.i == (0.0 if clamps == (0.0, 0.0) else 2000.0)
        session.run()
    data = np.genfromtxt(session.trace_path, delimiter=",", names=True)
    reference, position = data["joint1reference"], data["joint1position"]
    written = toolbox_step(reference, (-0.2, 0.0), P, D, i=2000.0, i_max=high, i_min=low, antiwindup=antiwindup)
    assert np.max(np.abs(position - written)) < 1e-9
    gains = view.pid.gains
    loop = JointLoop(M_KG, B, 0.001, LIMIT_N, lambda q: M_KG * G, p=P, i=gains.i, d=D, i_clamp=gains.i_clamp_max,
                     i_clamp_min=gains.i_clamp_min, antiwindup=antiwindup, integrator="euler", law="control_toolbox")
    q, _, _ = loop.run(reference, start=(-0.2, 0.0))
    assert np.max(np.abs(q - position)) < 1e-9
    held = min(high, M_KG * G)
    assert position[-1] == pytest.approx(-0.5 - (M_KG * G - held) / P, abs=1e-9)


@pytest.mark.slow
def test_a_reference_with_values_dot_puts_the_derivative_on_its_rate_less_the_velocity(write_scenario, tmp_path):
    """[position, velocity] interfaces and values_dot given each cycle: no kick, d·(ṙ - q̇) (a ramp of -0.6 m/s
    for 0.5 s), as JointLoop with the reference's rate."""
    from jointctl.metrics.step_loop import JointLoop
    from jointctl.scenario.session import Session

    scenario = ros2_step(write_scenario, "duration_s=2.0", commands={})
    h = 0.001

    def ramp(t: float) -> tuple[float, float]:
        moving = 0.5 <= t < 1.0
        return -0.2 - 0.6 * min(max(t - 0.5, 0.0), 0.5), (-0.6 if moving else 0.0)

    rows = []
    with Session(scenario) as session:
        controller = session.manager.controller("pid_controller")
        hardware = session.hardware
        session.loop.add_input(lambda t: controller.set_reference([ramp(t)[0]], [ramp(t)[1]]))
        session.loop.add_observer(lambda t: rows.append((t, hardware.position[0])))
        session.run()
    t, position = (np.array(c) for c in zip(*rows))
    reference = np.array([ramp(x)[0] for x in t])
    rates = np.array([ramp(x)[1] for x in t])
    written = toolbox_step(reference, (-0.2, 0.0), P, D, rates=rates)
    assert np.max(np.abs(position - written)) < 1e-9
    loop = JointLoop(M_KG, B, h, LIMIT_N, lambda q: M_KG * G, p=P, d=D, integrator="euler", law="control_toolbox")
    q, _, u = loop.run(reference, start=(-0.2, 0.0), reference_rate=rates)
    assert np.max(np.abs(q - position)) < 1e-9
    assert np.max(np.abs(u)) < 0.5 * LIMIT_N  # no kick at the ramp's corners


def test_an_analysis_of_a_joint_a_forward_command_controller_commands_is_refused_before_the_run(write_scenario,
                                                                                              tmp_path):
    from jointctl.scenario.run import run_scenario

    scenario = ros2_step(write_scenario, controller_file="ros2_forward", start_controllers=[
        "joint_state_broadcaster", "effort_controller"], commands={
        "effort_controller": {"type": "constant", "value": 0.0}},
        analysis={"type": "step_response", "joint": "joint1"})
    with pytest.raises(ConfigError) as info:
        run_scenario(scenario, tmp_path / "out")
    assert info.value.field == "analysis.joint" and "effort_controller" in str(info.value)

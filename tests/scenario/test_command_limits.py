"""Nothing clamped silently: a command source that would ask a joint controller for a reference outside the
joint's range (a position loop) or its speed limit (a velocity loop) is refused before anything moves, naming
the source's field, its value and the limit; a command whose values are known only as the run goes (an
expression) and is clamped by the controller, as ros_control's JointPositionController clamps its command to
the URDF's limits (``enforceJointLimits``), is a warning naming the furthest value and the limit.

The 1-DOF robot's joint1 is prismatic, range [-1, 0] m, speed limit 100 m/s (robots/one_dof); the planar
arm's shoulder (tests/scenario/test_step_theory.py) is revolute, range [-3, 3] rad.
"""

from __future__ import annotations

import pytest

from jointctl.errors import ConfigError
from jointctl.scenario.run import run_scenario
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from tests.conftest import step_scenario

POSITION = "joint1_position_controller"


def build(write_scenario, tmp_path, **changes):
    return Session(load_scenario(write_scenario(step_scenario(**changes))), out_dir=tmp_path / "out")


@pytest.mark.parametrize("command, key, value, says", [
    ({"type": "step", "from": -0.2, "to": 0.5, "at": 0.1}, "to", 0.5, "joint1's range [-1, 0] m"),
    ({"type": "step", "from": -1.5, "to": -0.5, "at": 0.1}, "from", -1.5, "joint1's range [-1, 0] m"),
    ({"type": "constant", "value": 0.25}, "value", 0.25, "joint1's range [-1, 0] m"),
    ({"type": "sine", "amplitude": 0.7, "frequency_hz": 1, "offset": -0.5}, "amplitude", 0.2,
     "joint1's range [-1, 0] m"),
    ({"type": "sine", "amplitude": 0.1, "frequency_hz": 1, "offset": 0.5}, "offset", 0.5,
     "joint1's range [-1, 0] m"),
])
def test_a_position_command_outside_the_joints_range_is_refused_before_anything_moves(
        write_scenario, tmp_path, command, key, value, says):
    with pytest.raises(ConfigError) as caught:
        build(write_scenario, tmp_path, commands={POSITION: command})
    error = caught.value
    assert error.field == f"commands.{POSITION}.{key}" and error.value == pytest.approx(value)
    assert says in str(error) and "clamp" in str(error)
    assert not (tmp_path / "out" / "trace.csv").exists()


def test_commands_inside_the_range_and_its_ends_are_accepted(write_scenario, tmp_path):
    for command in ({"type": "step", "from": 0.0, "to": -1.0, "at": 0.1},
                    {"type": "sine", "amplitude": 0.5, "frequency_hz": 1, "offset": -0.5}):
        build(write_scenario, tmp_path, commands={POSITION: command}).close()


def test_a_velocity_command_beyond_the_speed_limit_is_refused(write_scenario, tmp_path):
    changes = {"controller_file": "velocity", "start_controllers": ["joint_state_controller",
                                                                    "joint1_velocity_controller"]}
    with pytest.raises(ConfigError) as caught:
        build(write_scenario, tmp_path, **changes,
              commands={"joint1_velocity_controller": {"type": "constant", "value": -150.0}})
    assert caught.value.field == "commands.joint1_velocity_controller.value" and caught.value.value == -150.0
    assert "joint1's speed limit ±100 m/s" in str(caught.value)
    # A velocity sine (derivative: true) peaks at 2π·f·amplitude: 2π·20·1 = 126 m/s.
    sine = {"type": "sine", "amplitude": 1.0, "frequency_hz": 20, "derivative": True}
    with pytest.raises(ConfigError, match="amplitude"):
        build(write_scenario, tmp_path, **changes, commands={"joint1_velocity_controller": sine})


def test_the_issues_step_to_10_rad_on_a_3_rad_joint_is_one_line_and_exit_2(tmp_path, capsys):
    from jointctl.cli import main
    from tests.scenario.test_step_theory import write_arm

    assert main(["run", write_arm(tmp_path, -0.7, 10.0), "--out", str(tmp_path / "out")]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("jointctl: error")]
    assert len(errors) == 1
    err = errors[0]
    assert "commands.shoulder_position_controller.to" in err
    assert "shoulder's range [-3, 3] rad" in err and "(got 10" in err


def test_an_expression_clamped_as_the_run_goes_is_a_warning_naming_value_and_limit(write_scenario, tmp_path):
    # -0.2 m until 98 ms, 0 m (the upper end: not clamped) at 99 ms, 0.2 m from 100 ms on: beyond joint1's upper
    # end in the 200 cycles from 0.1 s to the end of the 0.3 s run (1 kHz).
    command = {"type": "expression", "expression": "0.2*clip(t*1000 - 99, -1, 1)", "rate_hz": 1000}
    scenario = load_scenario(write_scenario(step_scenario(commands={POSITION: command}, duration_s=0.3)))
    metrics = run_scenario(scenario, tmp_path / "out", mcap=False)
    clamped = [w for w in metrics["warnings"] if w.startswith(f"{POSITION}: ")]
    assert len(clamped) == 1
    assert "0.2 m" in clamped[0] and "joint1's range [-1, 0] m" in clamped[0]
    assert "in 200 cycles" in clamped[0]

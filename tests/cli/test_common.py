"""What the command families share: the industrial hardware's settings from the command line, else from
the robot's robot.yaml (``industrial: {points, message, default_speed}``), else ROS-I's defaults."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from jointctl.cli.common import industrial_arguments, industrial_hardware
from jointctl.errors import JointCtlError
from jointctl.scenario.spec import scenario_for_robot
from tests.hardware.controller_doubles import ControllerDouble

pytestmark = pytest.mark.wall_clock


def parsed(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    industrial_arguments(parser)
    return parser.parse_args(["--robot-ip", "127.0.0.1", *argv])


@pytest.fixture
def double():
    d = ControllerDouble("duration", [-0.5], [0.5])
    yield d
    d.close()


def scenario_with(industrial):
    scenario = scenario_for_robot("one_dof", "industrial")
    extras = dict(scenario.robot.extras)
    if industrial is not None:
        extras["industrial"] = industrial
    return dataclasses.replace(scenario, robot=dataclasses.replace(scenario.robot, extras=extras))


def connect(double, scenario, *argv):
    args = parsed("--motion-port", str(double.motion_port), "--state-port", str(double.state_port), *argv)
    hardware = industrial_hardware(args, scenario)
    hardware.close()
    return hardware


def test_ros_is_defaults_then_the_robots_then_the_command_lines(double) -> None:
    hw = connect(double, scenario_with(None))
    assert (hw.points, hw.message, hw.default_speed) == ("goal", "pt", 0.1)
    assert hw.max_velocities == (100.0,)  # joint1's <limit velocity="100.0"/> in the URDF
    robot = scenario_with({"points": "resampled", "message": "full", "default_speed": 0.25})
    hw = connect(double, robot)
    assert (hw.points, hw.message, hw.default_speed) == ("resampled", "full", 0.25)
    assert hw.trajectory_sample_period_s == pytest.approx(0.02)
    hw = connect(double, robot, "--stream-points", "goal", "--message", "pt", "--default-speed", "0.5")
    assert (hw.points, hw.message, hw.default_speed) == ("goal", "pt", 0.5)


@pytest.mark.parametrize(("industrial", "field"), [
    ({"speed": 0.5}, "industrial"),            # an unknown key
    ("fast", "industrial"),                    # not a mapping
    ({"points": "sparse"}, "points"),          # refused by the hardware, naming the setting
    ({"default_speed": 0.0}, "default_speed"),
    ({"default_speed": "fast"}, "default_speed"),  # not a number: refused, not a traceback
])
def test_bad_robot_settings_are_refused_naming_the_field(double, industrial, field) -> None:
    with pytest.raises(JointCtlError) as info:
        connect(double, scenario_with(industrial))
    assert info.value.field == field


def test_a_default_speed_outside_zero_to_one_from_the_command_line_is_refused(double) -> None:
    with pytest.raises(JointCtlError) as info:
        connect(double, scenario_with(None), "--default-speed", "1.5")
    assert info.value.field == "default_speed" and info.value.value == 1.5

"""The simulated world standing in for a ``<ros2_control>`` hardware plugin: effort-commanded joints get
actuators, initial values are where the joints start, other command interfaces are refused by name."""

from __future__ import annotations

import pytest

from jointctl.errors import ModelError
from jointctl.hardware.interface import EFFORT
from jointctl.hardware.mujoco_hardware import MujocoHardware
from jointctl.model.loader import load_robot_model
from jointctl.model.urdf_parser import parse_urdf
from jointctl.sim import MujocoWorld
from tests.model.test_ros2_control import CONTROL_DEMO, SYSTEM, urdf

VELOCITY_ELBOW = SYSTEM.replace('<joint name="elbow">\n      <command_interface name="effort"/>',
                                '<joint name="elbow">\n      <command_interface name="velocity"/>')


def test_effort_joints_are_actuated_and_start_at_their_initial_value():
    world = MujocoWorld(parse_urdf(urdf(SYSTEM), source="arm.urdf"))
    hardware = MujocoHardware(world)
    assert world.initial_positions == {"shoulder": 0.3}
    hardware.read()
    assert hardware.position == pytest.approx([0.3, 0.0], abs=0.0)
    assert all(hardware.command_interfaces(j) == {EFFORT} for j in ("shoulder", "elbow"))


def test_a_scenario_initial_position_wins_over_the_initial_value():
    world = MujocoWorld(parse_urdf(urdf(SYSTEM), source="arm.urdf"), initial_positions={"shoulder": -0.2})
    assert world.initial_positions == {"shoulder": -0.2}


def test_a_joint_with_only_a_velocity_command_interface_is_refused_by_name():
    with pytest.raises(ModelError) as info:
        MujocoWorld(parse_urdf(urdf(VELOCITY_ELBOW), source="arm.urdf"))
    assert info.value.field == "ros2_control[ArmSystem].joint[elbow].command_interface"
    assert info.value.value == "velocity"


def test_the_control_demo_is_refused_at_its_velocity_joint():
    with pytest.raises(ModelError) as info:
        MujocoWorld(load_robot_model(CONTROL_DEMO))
    assert info.value.field == "ros2_control[MockSystem].joint[joint1].command_interface"
    assert info.value.value == "velocity"


def test_a_velocity_interface_beside_an_effort_transmission_is_simulated_through_the_transmission():
    transmission = """<transmission name="t_elbow"><type>transmission_interface/SimpleTransmission</type>
      <joint name="elbow"><hardwareInterface>EffortJointInterface</hardwareInterface></joint></transmission>"""
    world = MujocoWorld(parse_urdf(urdf(transmission + VELOCITY_ELBOW), source="arm.urdf"))
    assert MujocoHardware(world).command_interfaces("elbow") == {EFFORT}

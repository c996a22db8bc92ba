"""The ``<ros2_control>`` tags of a URDF: what the parser reads (hardware_interface's component_parser
format) and every way it refuses a tag, naming the element and the value."""

from __future__ import annotations

from pathlib import Path

import pytest

from jointctl.errors import ModelError
from jointctl.model.loader import load_robot_model
from jointctl.model.urdf_parser import parse_urdf

#: The reference's demo (robot.urdf and controllers.yaml that Jazzy's ros2_control_node loads on mock hardware).
CONTROL_DEMO = Path(__file__).resolve().parent / "data" / "control_demo" / "robot.urdf"
SOURCE = "arm.urdf"

ROBOT = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/>
  <link name="upper"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"/></inertial></link>
  <link name="lower"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"/></inertial></link>
  <link name="tool"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="50" velocity="3"/>
  </joint>
  <joint name="elbow" type="continuous">
    <parent link="upper"/><child link="lower"/><origin xyz="0 0 0.5"/><axis xyz="0 1 0"/>
  </joint>
  <joint name="tool_mount" type="fixed"><parent link="lower"/><child link="tool"/></joint>
  {extra}
</robot>
"""

SYSTEM = """
  <ros2_control name="ArmSystem" type="system">
    <hardware>
      <plugin>gz_ros2_control/GazeboSimSystem</plugin>
      <param name="hold_joints">true</param>
    </hardware>
    <joint name="shoulder">
      <command_interface name="effort"><param name="min">-40</param><param name="max">40</param></command_interface>
      <state_interface name="position"><param name="initial_value">0.3</param></state_interface>
      <state_interface name="velocity"/>
      <state_interface name="effort"/>
    </joint>
    <joint name="elbow">
      <command_interface name="effort"/>
      <state_interface name="position"/>
      <state_interface name="velocity"/>
    </joint>
    <sensor name="wrist_ft">
      <state_interface name="force.z"/>
      <param name="frame_id">tool</param>
    </sensor>
    <gpio name="flange_io"><command_interface name="vacuum"/><state_interface name="vacuum"/></gpio>
  </ros2_control>
"""


def urdf(extra: str) -> str:
    return ROBOT.replace("{extra}", extra)


def test_a_system_is_read_with_its_plugin_joints_interfaces_sensors_and_gpios():
    robot = parse_urdf(urdf(SYSTEM), source=SOURCE)
    (system,) = robot.ros2_control
    assert (system.name, system.type, system.plugin) == ("ArmSystem", "system", "gz_ros2_control/GazeboSimSystem")
    assert system.hardware_params == (("hold_joints", "true"),)
    shoulder, elbow = system.joints
    assert shoulder.command_names == ("effort",) and shoulder.state_names == ("position", "velocity", "effort")
    assert (shoulder.command_interfaces[0].minimum, shoulder.command_interfaces[0].maximum) == (-40.0, 40.0)
    assert shoulder.initial_position == 0.3 and elbow.initial_position is None
    assert [s.name for s in system.sensors] == ["wrist_ft"] and system.sensors[0].params == (("frame_id", "tool"),)
    assert [g.name for g in system.gpios] == ["flange_io"]
    assert robot.initial_positions == {"shoulder": 0.3}
    assert robot.effort_commanded == ("shoulder", "elbow")
    assert robot.ros2_control_joint("elbow")[1] is elbow and robot.ros2_control_joint("tool_mount") is None


def test_effort_joints_are_driven_as_through_an_effort_transmission():
    robot = parse_urdf(urdf(SYSTEM), source=SOURCE)
    driven = {t.joint: t for t in robot.transmissions}
    assert set(driven) == {"shoulder", "elbow"}
    assert driven["shoulder"].hardware_interfaces == ("EffortJointInterface",)
    assert driven["shoulder"].ros2_control == "ArmSystem" and driven["shoulder"].mechanical_reduction == 1.0


def test_a_joint_a_transmission_already_drives_keeps_that_transmission():
    transmission = """<transmission name="t_shoulder"><type>transmission_interface/SimpleTransmission</type>
      <joint name="shoulder"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
      <actuator name="m"><mechanicalReduction>50</mechanicalReduction></actuator></transmission>"""
    robot = parse_urdf(urdf(transmission + SYSTEM), source=SOURCE)
    by_joint = {t.joint: t for t in robot.transmissions}
    assert by_joint["shoulder"].name == "t_shoulder" and by_joint["shoulder"].mechanical_reduction == 50
    assert by_joint["elbow"].ros2_control == "ArmSystem"
    assert len(robot.transmissions) == 2


def test_the_control_demo_reads_as_ros2_control_loads_it():
    robot = load_robot_model(CONTROL_DEMO)
    (system,) = robot.ros2_control
    assert (system.name, system.type, system.plugin) == ("MockSystem", "system", "mock_components/GenericSystem")
    assert system.hardware_params == (("calculate_dynamics", "true"),)
    assert [(j.name, j.command_names, j.state_names) for j in system.joints] == [
        ("joint1", ("velocity",), ("position", "velocity")), ("joint2", ("position",), ("position", "velocity"))]
    assert robot.initial_positions == {"joint1": 0.0, "joint2": 0.0}
    assert robot.transmissions == () and robot.effort_commanded == ()
    assert "mock_components/GenericSystem" in system.stand_in()


def test_a_robot_without_ros2_control_has_none():
    robot = parse_urdf(urdf(""), source=SOURCE)
    assert robot.ros2_control == () and robot.initial_positions == {}


def _one(joint: str = '<joint name="shoulder"><command_interface name="effort"/></joint>',
         attributes: str = 'name="S" type="system"',
         hardware: str = "<hardware><plugin>mock_components/GenericSystem</plugin></hardware>") -> str:
    return f"<ros2_control {attributes}>{hardware}{joint}</ros2_control>"


REFUSALS = [
    ("no name", _one(attributes='type="system"'), "ros2_control", None),
    ("no type", _one(attributes='name="S"'), "ros2_control[S].type", None),
    ("unknown type", _one(attributes='name="S" type="robot"'), "ros2_control[S].type", "robot"),
    ("no hardware", _one(hardware=""), "ros2_control[S].hardware", None),
    ("no plugin", _one(hardware="<hardware><param name='a'>1</param></hardware>"), "ros2_control[S].hardware.plugin",
     None),
    ("unknown child", _one(joint="<actuator name='a'/>"), "ros2_control[S]", "actuator"),
    ("param without a name", _one(hardware="<hardware><plugin>p</plugin><param>1</param></hardware>"),
     "ros2_control[S].hardware.param", None),
    ("joint not in the URDF", _one(joint='<joint name="wrist"/>'), "ros2_control[S].joint", "wrist"),
    ("fixed joint", _one(joint='<joint name="tool_mount"/>'), "ros2_control[S].joint[tool_mount]", "fixed"),
    ("interface without a name", _one(joint='<joint name="shoulder"><command_interface/></joint>'),
     "ros2_control[S].joint[shoulder].command_interface", None),
    ("interface twice", _one(joint='<joint name="shoulder"><state_interface name="position"/>'
                                   '<state_interface name="position"/></joint>'),
     "ros2_control[S].joint[shoulder].state_interface", "position"),
    ("initial value not a number", _one(joint='<joint name="shoulder"><state_interface name="position">'
                                              '<param name="initial_value">up</param></state_interface></joint>'),
     "ros2_control[S].joint[shoulder].state_interface[position].initial_value", "up"),
    ("initial value outside the limits",
     _one(joint='<joint name="shoulder"><state_interface name="position">'
                '<param name="initial_value">2.0</param></state_interface></joint>'),
     "ros2_control[S].joint[shoulder].state_interface[position].initial_value", 2.0),
    ("min above max", _one(joint='<joint name="shoulder"><command_interface name="effort"><param name="min">5</param>'
                                 '<param name="max">-5</param></command_interface></joint>'),
     "ros2_control[S].joint[shoulder].command_interface[effort].min", "5"),
    ("mimic with a command", _one(joint='<joint name="shoulder" mimic="true"><command_interface name="effort"/>'
                                        '</joint>'),
     "ros2_control[S].joint[shoulder].command_interface", "effort"),
    ("joint twice", _one(joint='<joint name="shoulder"/><joint name="shoulder"/>'), "ros2_control[S].joint",
     "shoulder"),
    ("joint in two components", _one() + _one(attributes='name="T" type="system"'), "ros2_control[T].joint",
     "shoulder"),
    ("two components of one name", _one(joint="") + _one(joint=""), "ros2_control", "S"),
]


@pytest.mark.parametrize(("case", "extra", "field", "value"), REFUSALS, ids=[r[0] for r in REFUSALS])
def test_a_bad_tag_is_refused_naming_its_element_and_value(case, extra, field, value):
    with pytest.raises(ModelError) as info:
        parse_urdf(urdf(extra), source=SOURCE)
    error = info.value
    assert error.source == SOURCE and error.field == field, str(error)
    if value is None:
        assert not error.has_value, str(error)
    else:
        assert error.value == value, str(error)


def test_a_continuous_joint_takes_any_initial_value():
    extra = _one(joint='<joint name="elbow"><state_interface name="position"><param name="initial_value">4.0</param>'
                       '</state_interface></joint>')
    assert parse_urdf(urdf(extra), source=SOURCE).initial_positions == {"elbow": 4.0}

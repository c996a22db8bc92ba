"""Tests of the URDF parser: what it reads, and every way it refuses a description."""

from __future__ import annotations

import math

import pytest

from jointctl.errors import ModelError
from jointctl.model.robot_model import Geometry, Pose
from jointctl.model.urdf_parser import parse_urdf

SOURCE = "test_robot.urdf"

# A small but complete description: a fixed base, a revolute arm, a fixed tool,
# a transmission, the ros_control plugin and a force-torque sensor plugin.
BASE = """<?xml version="1.0"?>
<robot name="tester">
  <link name="base"/>
  <link name="arm">
    <inertial>
      <origin xyz="0 0 0.5" rpy="0 0 0"/>
      <mass value="2.0"/>
      <inertia ixx="0.2" iyy="0.3" izz="0.04" ixy="0.01"/>
    </inertial>
    <visual>
      <origin xyz="0 0 0.5" rpy="0.1 0.2 0.3"/>
      <geometry><box size="0.1 0.2 1.0"/></geometry>
    </visual>
    <collision>
      <geometry><cylinder radius="0.05" length="1.0"/></geometry>
    </collision>
  </link>
  <link name="tool">
    <visual><geometry><sphere radius="0.03"/></geometry></visual>
    <collision><geometry><mesh filename="package://tools/meshes/tool.stl" scale="2 2 2"/></geometry></collision>
  </link>
  <joint name="j1" type="revolute">
    <parent link="base"/>
    <child link="arm"/>
    <origin xyz="0 0 1" rpy="0 0 0"/>
    <axis xyz="0 2 0"/>
    <limit lower="-1.5" upper="1.5" effort="10" velocity="2"/>
    <dynamics damping="0.5" friction="0.1"/>
  </joint>
  <joint name="tool_joint" type="fixed">
    <parent link="arm"/>
    <child link="tool"/>
    <origin xyz="0 0 1"/>
  </joint>
  <transmission name="t1">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="j1">
      <hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>
    </joint>
    <actuator name="m1">
      <hardwareInterface>VelocityJointInterface</hardwareInterface>
      <mechanicalReduction>2</mechanicalReduction>
    </actuator>
  </transmission>
  <gazebo>
    <plugin name="gazebo_ros_control" filename="libgazebo_ros_control.so">
      <robotNamespace>/tester_ns</robotNamespace>
    </plugin>
  </gazebo>
  <gazebo>
    <plugin name="ft" filename="libgazebo_ros_ft_sensor.so">
      <updateRate>250</updateRate>
      <topicName>ft_topic</topicName>
      <jointName>tool_joint</jointName>
    </plugin>
  </gazebo>
</robot>
"""


def replaced(old: str, new: str, text: str = BASE) -> str:
    """BASE with one occurrence of ``old`` replaced; fails loudly if ``old`` is absent."""
    assert text.count(old) == 1, f"{old!r} must occur exactly once in the base URDF"
    return text.replace(old, new)


def refused(text: str) -> ModelError:
    with pytest.raises(ModelError) as info:
        parse_urdf(text, source=SOURCE)
    error = info.value
    assert error.code == "model"
    assert error.source == SOURCE
    assert str(error).startswith(SOURCE)
    return error


# -- what is read --------------------------------------------------------------


def test_base_description_is_read_completely() -> None:
    robot = parse_urdf(BASE, source=SOURCE)
    assert robot.name == "tester"
    assert robot.source == SOURCE
    assert robot.namespace == "tester_ns"
    assert [lk.name for lk in robot.links] == ["base", "arm", "tool"]
    assert [j.name for j in robot.joints] == ["j1", "tool_joint"]
    assert robot.root_link == "base"

    j1 = robot.joint("j1")
    assert (j1.type, j1.parent, j1.child) == ("revolute", "base", "arm")
    assert j1.origin == Pose((0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
    assert j1.axis == (0.0, 1.0, 0.0)  # normalised
    assert j1.limits is not None
    assert (j1.limits.lower, j1.limits.upper, j1.limits.effort, j1.limits.velocity) == (-1.5, 1.5, 10.0, 2.0)
    assert (j1.damping, j1.friction) == (0.5, 0.1)

    tool_joint = robot.joint("tool_joint")
    assert tool_joint.type == "fixed"
    assert tool_joint.limits is None
    assert tool_joint.origin.rpy == (0.0, 0.0, 0.0)


def test_links_inertial_and_shapes() -> None:
    robot = parse_urdf(BASE)
    assert robot.link("base").inertial is None
    arm = robot.link("arm")
    assert arm.inertial is not None
    assert arm.inertial.mass_kg == 2.0
    assert arm.inertial.origin.xyz == (0.0, 0.0, 0.5)
    # (ixx, iyy, izz, ixy, ixz, iyz); missing off-diagonal terms default to 0
    assert arm.inertial.inertia == (0.2, 0.3, 0.04, 0.01, 0.0, 0.0)
    (visual,) = arm.visuals
    assert visual.geometry == Geometry("box", size_m=(0.1, 0.2, 1.0))
    assert visual.origin == Pose((0.0, 0.0, 0.5), (0.1, 0.2, 0.3))
    (collision,) = arm.collisions
    assert collision.geometry == Geometry("cylinder", radius_m=0.05, length_m=1.0)
    tool = robot.link("tool")
    assert tool.visuals[0].geometry == Geometry("sphere", radius_m=0.03)
    mesh = tool.collisions[0].geometry
    assert (mesh.kind, mesh.mesh_path, mesh.scale) == ("mesh", "package://tools/meshes/tool.stl", (2.0, 2.0, 2.0))


def test_transmission_interfaces_are_short_names_from_joint_and_actuator() -> None:
    (tr,) = parse_urdf(BASE).transmissions
    assert tr.name == "t1"
    assert tr.type == "transmission_interface/SimpleTransmission"
    assert tr.joint == "j1"
    assert tr.actuator == "m1"
    assert tr.hardware_interfaces == ("EffortJointInterface", "VelocityJointInterface")
    assert tr.mechanical_reduction == 2.0


def test_transmission_defaults() -> None:
    text = replaced(
        """<actuator name="m1">
      <hardwareInterface>VelocityJointInterface</hardwareInterface>
      <mechanicalReduction>2</mechanicalReduction>
    </actuator>""",
        "",
    )
    text = replaced("<type>transmission_interface/SimpleTransmission</type>", "", text)
    (tr,) = parse_urdf(text).transmissions
    assert tr.type == "transmission_interface/SimpleTransmission"
    assert tr.actuator is None
    assert tr.mechanical_reduction == 1.0
    assert tr.hardware_interfaces == ("EffortJointInterface",)


def test_force_torque_sensor_plugin() -> None:
    (sensor,) = parse_urdf(BASE).sensors
    assert sensor.name == "ft"
    assert sensor.kind == "force_torque"
    assert sensor.joint == "tool_joint"
    assert sensor.link == "tool"  # the joint's child link measures
    assert sensor.topic == "ft_topic"
    assert sensor.update_rate_hz == 250.0


def test_no_gazebo_means_no_namespace_and_no_sensor() -> None:
    start = BASE.index("  <gazebo>")
    end = BASE.index("</robot>")
    robot = parse_urdf(BASE[:start] + BASE[end:])
    assert robot.namespace is None
    assert robot.sensors == ()


def test_defaults_of_joint_elements() -> None:
    text = replaced('<origin xyz="0 0 1" rpy="0 0 0"/>\n    <axis xyz="0 2 0"/>', "")
    text = replaced('<dynamics damping="0.5" friction="0.1"/>', "", text)
    j1 = parse_urdf(text).joint("j1")
    assert j1.origin == Pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert j1.axis == (1.0, 0.0, 0.0)  # URDF default axis
    assert (j1.damping, j1.friction) == (0.0, 0.0)


def test_continuous_joint_has_no_position_limits_but_keeps_effort() -> None:
    text = replaced('type="revolute"', 'type="continuous"')
    j1 = parse_urdf(text).joint("j1")
    assert j1.limits is not None
    assert (j1.limits.lower, j1.limits.upper) == (None, None)
    assert (j1.limits.effort, j1.limits.velocity) == (10.0, 2.0)
    assert j1.is_movable and not j1.is_locked
    no_limit = replaced('<limit lower="-1.5" upper="1.5" effort="10" velocity="2"/>', "", text)
    assert parse_urdf(no_limit).joint("j1").limits is None


def test_prismatic_joint_with_equal_limits_is_locked() -> None:
    text = replaced('type="revolute"', 'type="prismatic"')
    text = replaced('lower="-1.5" upper="1.5"', 'lower="0" upper="0"', text)
    robot = parse_urdf(text)
    j1 = robot.joint("j1")
    assert j1.is_prismatic
    assert j1.is_locked
    assert not j1.is_movable
    assert robot.movable_joints == ()


def test_lower_and_upper_default_to_zero() -> None:
    text = replaced('lower="-1.5" upper="1.5" ', "")
    limits = parse_urdf(text).joint("j1").limits
    assert (limits.lower, limits.upper) == (0.0, 0.0)


def test_fixed_joint_may_have_zero_axis() -> None:
    text = replaced('<origin xyz="0 0 1"/>\n  </joint>', '<axis xyz="0 0 0"/>\n  </joint>')
    assert parse_urdf(text).joint("tool_joint").type == "fixed"


def test_control_plugin_namespace_slashes_are_stripped() -> None:
    text = replaced("<robotNamespace>/tester_ns</robotNamespace>", "<robotNamespace>/a/b/</robotNamespace>")
    assert parse_urdf(text).namespace == "a/b"


# -- refusals ------------------------------------------------------------------

JOINT_LIMIT = '<limit lower="-1.5" upper="1.5" effort="10" velocity="2"/>'
DYNAMICS = '<dynamics damping="0.5" friction="0.1"/>'
EXTRA_LINKS = '<link name="base"/>'

REFUSALS = [
    # (id, old, new, substrings that must appear in str(error))
    ("missing-robot-name", '<robot name="tester">', "<robot>", ["robot", "needs a name"]),
    ("empty-robot-name", '<robot name="tester">', '<robot name="">', ["robot", "needs a name"]),
    ("duplicate-link", EXTRA_LINKS, '<link name="base"/><link name="arm"/>', ["duplicate link name", "'arm'"]),
    ("duplicate-joint", "</robot>",
     '<link name="x"/><joint name="j1" type="fixed"><parent link="base"/><child link="x"/></joint></robot>',
     ["duplicate joint name", "'j1'"]),
    ("unknown-joint-type", 'type="revolute"', 'type="hinge"', ["joint[j1].type", "'hinge'"]),
    ("missing-joint-type", ' type="revolute"', "", ["joint[j1].type", "None"]),
    ("missing-parent-link", '<parent link="base"/>\n    <child link="arm"/>', '<child link="arm"/>',
     ["joint[j1]", "<parent"]),
    ("parent-link-unknown", '<parent link="base"/>\n    <child link="arm"/>',
     '<parent link="nowhere"/>\n    <child link="arm"/>', ["joint[j1].parent", "does not exist", "'nowhere'"]),
    ("child-link-unknown", '<child link="tool"/>', '<child link="ghost"/>',
     ["joint[tool_joint].child", "does not exist", "'ghost'"]),
    ("two-roots", EXTRA_LINKS, '<link name="base"/><link name="orphan"/>',
     ["robot", "single root", "'base'", "'orphan'"]),
    ("two-parents", "</robot>",
     '<joint name="j2" type="fixed"><parent link="base"/><child link="tool"/></joint></robot>',
     ["joint[j2].child", "two parent", "'tool'"]),
    ("loop-beside-a-tree", "</robot>",
     '<link name="x"/><link name="y"/>'
     '<joint name="jx" type="fixed"><parent link="y"/><child link="x"/></joint>'
     '<joint name="jy" type="fixed"><parent link="x"/><child link="y"/></joint></robot>',
     ["robot", "loop"]),
    ("loop-without-root", "</robot>",
     '<joint name="back" type="fixed"><parent link="tool"/><child link="base"/></joint></robot>',
     ["robot", "single root", "[]"]),
    ("no-links", BASE[BASE.index("<link name=\"base\"/>"):BASE.index("</robot>")], "",
     ["robot", "no <link>"]),
    ("revolute-without-limit", JOINT_LIMIT, "", ["joint[j1]", "revolute joint needs <limit>"]),
    ("lower-above-upper", 'lower="-1.5" upper="1.5"', 'lower="2" upper="1"',
     ["joint[j1].limit.lower", "above upper", "2.0"]),
    ("negative-effort", 'effort="10"', 'effort="-10"', ["joint[j1].limit.effort", "negative", "-10.0"]),
    ("negative-velocity", 'velocity="2"', 'velocity="-2"', ["joint[j1].limit.velocity", "negative", "-2.0"]),
    ("missing-effort", ' effort="10"', "", ["joint[j1].limit", "'effort'"]),
    ("negative-damping", 'damping="0.5"', 'damping="-0.5"', ["joint[j1].dynamics.damping", "negative", "-0.5"]),
    ("negative-friction", 'friction="0.1"', 'friction="-0.1"',
     ["joint[j1].dynamics.friction", "negative", "-0.1"]),
    ("effort-not-a-number", 'effort="10"', 'effort="abc"', ["joint[j1].limit", "'effort'", "not a number", "'abc'"]),
    ("effort-infinite", 'effort="10"', 'effort="inf"', ["joint[j1].limit", "'effort'", "not finite", "'inf'"]),
    ("upper-nan", 'upper="1.5"', 'upper="nan"', ["joint[j1].limit", "'upper'", "not finite", "'nan'"]),
    ("damping-not-a-number", 'damping="0.5"', 'damping="lots"', ["joint[j1].dynamics", "'damping'", "'lots'"]),
    ("origin-xyz-nan", '<origin xyz="0 0 1" rpy="0 0 0"/>', '<origin xyz="0 0 nan" rpy="0 0 0"/>',
     ["joint[j1].origin", "'xyz'", "not finite", "'0 0 nan'"]),
    ("origin-rpy-not-numbers", '<origin xyz="0 0 1" rpy="0 0 0"/>', '<origin xyz="0 0 1" rpy="0 zero 0"/>',
     ["joint[j1].origin", "'rpy'", "'0 zero 0'"]),
    ("origin-xyz-two-numbers", '<origin xyz="0 0 1" rpy="0 0 0"/>', '<origin xyz="0 1" rpy="0 0 0"/>',
     ["joint[j1].origin", "'xyz'", "3 numbers", "'0 1'"]),
    ("zero-axis", '<axis xyz="0 2 0"/>', '<axis xyz="0 0 0"/>', ["joint[j1].axis", "zero", "'0 0 0'"]),
    ("axis-inf", '<axis xyz="0 2 0"/>', '<axis xyz="0 inf 0"/>', ["joint[j1].axis", "not finite", "'0 inf 0'"]),
    ("zero-mass", '<mass value="2.0"/>', '<mass value="0"/>', ["link[arm].inertial.mass", "positive", "0.0"]),
    ("negative-mass", '<mass value="2.0"/>', '<mass value="-2"/>', ["link[arm].inertial.mass", "positive", "-2.0"]),
    ("mass-nan", '<mass value="2.0"/>', '<mass value="nan"/>', ["link[arm].inertial.mass", "not finite", "'nan'"]),
    ("missing-mass", '<mass value="2.0"/>', "", ["link[arm].inertial", "<mass>"]),
    ("missing-inertia", '<inertia ixx="0.2" iyy="0.3" izz="0.04" ixy="0.01"/>', "",
     ["link[arm].inertial", "<inertia>"]),
    ("negative-inertia", 'iyy="0.3"', 'iyy="-0.3"', ["link[arm].inertial.inertia", "iyy", "negative", "-0.3"]),
    ("inertia-not-a-number", 'izz="0.04"', 'izz="big"', ["link[arm].inertial.inertia", "'izz'", "'big'"]),
    ("unsupported-geometry", '<sphere radius="0.03"/>', '<capsule radius="0.03" length="0.1"/>',
     ["link[tool].visual.geometry", "unsupported", "'capsule'"]),
    ("empty-geometry", '<geometry><sphere radius="0.03"/></geometry>', "<geometry/>",
     ["link[tool].visual", "<geometry>"]),
    ("mesh-without-filename", 'filename="package://tools/meshes/tool.stl" ', "",
     ["link[tool].collision.geometry.mesh", "filename"]),
    ("box-non-positive-size", 'size="0.1 0.2 1.0"', 'size="0.1 0 1.0"',
     ["link[arm].visual.geometry.box", "size", "positive", "(0.1, 0.0, 1.0)"]),
    ("cylinder-negative-radius", 'radius="0.05"', 'radius="-0.05"',
     ["link[arm].collision.geometry.cylinder", "radius", "positive"]),
    ("sphere-radius-nan", '<sphere radius="0.03"/>', '<sphere radius="nan"/>',
     ["link[tool].visual.geometry.sphere", "'radius'", "not finite", "'nan'"]),
    ("transmission-unknown-joint", '<joint name="j1">\n      <hardwareInterface>',
     '<joint name="j9">\n      <hardwareInterface>', ["transmission[t1].joint", "does not exist", "'j9'"]),
    ("transmission-without-interface",
     "<hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>\n    </joint>\n"
     "    <actuator name=\"m1\">\n      <hardwareInterface>VelocityJointInterface</hardwareInterface>",
     "</joint>\n    <actuator name=\"m1\">", ["transmission[t1].joint", "<hardwareInterface>"]),
    ("reduction-not-a-number", "<mechanicalReduction>2</mechanicalReduction>",
     "<mechanicalReduction>two</mechanicalReduction>",
     ["transmission[t1].actuator.mechanicalReduction", "not a number", "'two'"]),
    ("reduction-empty", "<mechanicalReduction>2</mechanicalReduction>", "<mechanicalReduction/>",
     ["transmission[t1].actuator.mechanicalReduction", "None"]),
    ("reduction-zero", "<mechanicalReduction>2</mechanicalReduction>", "<mechanicalReduction>0</mechanicalReduction>",
     ["transmission[t1].actuator.mechanicalReduction", "non-zero", "0.0"]),
    ("reduction-infinite", "<mechanicalReduction>2</mechanicalReduction>",
     "<mechanicalReduction>inf</mechanicalReduction>",
     ["transmission[t1].actuator.mechanicalReduction", "finite", "inf"]),
    ("ft-sensor-unknown-joint", "<jointName>tool_joint</jointName>", "<jointName>no_joint</jointName>",
     ["gazebo.plugin[ft].jointName", "does not exist", "'no_joint'"]),
    ("ft-sensor-rate-not-a-number", "<updateRate>250</updateRate>", "<updateRate>fast</updateRate>",
     ["gazebo.plugin[ft].updateRate", "not a number", "'fast'"]),
    ("ft-sensor-rate-nan", "<updateRate>250</updateRate>", "<updateRate>nan</updateRate>",
     ["gazebo.plugin[ft].updateRate", "positive", "'nan'"]),
    ("ft-sensor-rate-negative", "<updateRate>250</updateRate>", "<updateRate>-5</updateRate>",
     ["gazebo.plugin[ft].updateRate", "positive", "'-5'"]),
]


@pytest.mark.parametrize(("old", "new", "expected"), [r[1:] for r in REFUSALS], ids=[r[0] for r in REFUSALS])
def test_refusals_name_element_attribute_and_value(old: str, new: str, expected: list[str]) -> None:
    text = replaced(old, new)
    message = str(refused(text))
    for part in expected:
        assert part in message, f"{part!r} not in {message!r}"


def test_refusal_carries_field_and_value() -> None:
    error = refused(replaced('effort="10"', 'effort="abc"'))
    assert error.field == "joint[j1].limit"
    assert error.value == "abc"
    error = refused(replaced('velocity="2"', 'velocity="-2"'))
    assert error.field == "joint[j1].limit.velocity"
    assert error.value == -2.0


def test_loop_names_a_link_of_the_loop() -> None:
    text = replaced(
        "</robot>",
        '<link name="x"/><link name="y"/>'
        '<joint name="jx" type="fixed"><parent link="y"/><child link="x"/></joint>'
        '<joint name="jy" type="fixed"><parent link="x"/><child link="y"/></joint></robot>',
    )
    assert refused(text).value in ("x", "y")


def test_root_must_be_robot() -> None:
    text = replaced('<robot name="tester">', '<model name="tester">').replace("</robot>", "</model>")
    error = refused(text)
    assert error.field == "robot"
    assert "<robot>" in str(error)
    assert "'model'" in str(error)


def test_malformed_xml() -> None:
    message = str(refused(BASE.replace("</robot>", "")))
    assert "not well-formed XML" in message
    assert "line" in message


@pytest.mark.parametrize("text", ["", "not xml at all", "<robot name='r'><link name='a'></robot>"])
def test_malformed_xml_variants(text: str) -> None:
    assert "not well-formed XML" in str(refused(text))


def test_parsed_numbers_are_finite_floats() -> None:
    robot = parse_urdf(BASE)
    values = [*robot.joint("j1").origin.xyz, *robot.joint("j1").axis, robot.joint("j1").damping]
    assert all(isinstance(v, float) and math.isfinite(v) for v in values)


COLOURED = """<?xml version="1.0"?>
<robot name="painted">
  <material name="blue"><color rgba="0 0 0.8 1"/></material>
  <link name="base">
    <visual><geometry><box size="1 1 1"/></geometry><material name="blue"/></visual>
    <visual><geometry><sphere radius="0.1"/></geometry>
      <material name="red"><color rgba="1 0 0 0.5"/></material></visual>
    <visual><geometry><sphere radius="0.2"/></geometry></visual>
  </link>
</robot>"""


def test_visual_colours_come_from_their_material_or_a_named_one() -> None:
    link = parse_urdf(COLOURED, source=SOURCE).link("base")
    assert [v.rgba for v in link.visuals] == [(0.0, 0.0, 0.8, 1.0), (1.0, 0.0, 0.0, 0.5), None]


def test_a_colour_out_of_range_is_refused_naming_it() -> None:
    with pytest.raises(ModelError, match=r"material\.color\.rgba") as info:
        parse_urdf(COLOURED.replace('rgba="1 0 0 0.5"', 'rgba="1 0 0 2"'), source=SOURCE)
    assert "1 0 0 2" in str(info.value)


def test_the_colours_reach_the_simulated_world() -> None:
    from jointctl.model.mjcf import ROOT_LINK_COLOUR, compile_robot

    model = compile_robot(parse_urdf(COLOURED, source=SOURCE))
    visible = [tuple(round(float(c), 3) for c in model.geom_rgba[g]) for g in range(model.ngeom)
               if model.geom_rgba[g][3] > 0]
    assert (0.0, 0.0, 0.8, 1.0) in visible and (1.0, 0.0, 0.0, 0.5) in visible
    assert ROOT_LINK_COLOUR in visible  # the root link's default where the URDF names no colour


def test_links_without_colours_get_one_each_so_a_plain_urdf_is_not_a_grey_robot() -> None:
    import mujoco

    from jointctl.model.mjcf import LINK_COLOURS, ROOT_LINK_COLOUR, compile_robot
    from tests.planar_arm import urdf_text  # world -> base post -> upper_arm -> forearm, no materials

    model = compile_robot(parse_urdf(urdf_text(), source=SOURCE))
    colours = {}
    for g in range(model.ngeom):
        if model.geom_rgba[g][3] > 0:
            body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g]))
            colours[body] = tuple(round(float(c), 3) for c in model.geom_rgba[g])
    # The base post is fixed to the "world" link: the base's grey; the moving links the palette in turn.
    assert colours == {"base": ROOT_LINK_COLOUR, "upper_arm": LINK_COLOURS[0], "forearm": LINK_COLOURS[1]}
    assert len(set(colours.values())) == 3

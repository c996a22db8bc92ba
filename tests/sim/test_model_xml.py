"""SDF / URDF model text (what Gazebo's spawn_model sends) read into one spawned object, and such
objects in the world: the book's weight file loads as it is, what jointctl cannot represent is
refused naming the element, and the weight dropped on the 1-DOF robot rests at the theoretical load."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from jointctl.errors import ConfigError
from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot
from jointctl.sim.mjcf_builder import rpy_to_matrix
from jointctl.sim.model_xml import FRICTION_MAX, UnsupportedModel, parse_model_xml
from jointctl.sim.objects import solid_inertia

BOOK_WEIGHT = Path(__file__).with_name("data") / "cylinder_model-1_4.sdf"


def sdf(link: str, *, model_extra: str = "", version: str = "1.6") -> str:
    return f'<sdf version="{version}"><model name="m">{model_extra}<link name="l">{link}</link></model></sdf>'


BOX_COLLISION = '<collision name="c"><geometry><box><size>0.2 0.4 0.6</size></box></geometry></collision>'


# -- the book's weight ------------------------------------------------------------------------------

def test_the_books_weight_file_loads_as_it_is() -> None:
    model = parse_model_xml(BOOK_WEIGHT.read_text(), name="cyl_weight", position=(0, 0, 4))
    spec = model.spec
    assert (spec.name, spec.shape, spec.size_m, spec.mass_kg) == ("cyl_weight", "cylinder", (0.5, 0.2), 10.0)
    assert spec.xyz == (0.0, 0.0, 4.0) and spec.rpy == pytest.approx((0.0, 0.0, 0.0))
    assert spec.inertia is None  # a homogeneous solid: (0.658, 0.658, 1.25), not the file's 0.01
    assert spec.principal_inertia == pytest.approx((10 * (3 * 0.25 + 0.04) / 12,) * 2 + (1.25,))
    assert spec.friction == FRICTION_MAX
    assert model.format == "SDF 1.4"
    assert model.frame_xyz == (0.0, 0.0, 0.0) and model.frame_quat == pytest.approx((1, 0, 0, 0))
    notes = " | ".join(model.notes)
    assert "inertia (0.01, 0.01, 0.01)" in notes and "(0.6583, 0.6583, 1.25) used" in notes
    assert "radius and length read from attributes" in notes
    assert "mu 50 capped at 1" in notes
    assert "kp, kd, max_vel, min_depth not used" in notes
    assert "mu2" not in notes  # equal to mu
    line = model.describe()
    assert line.startswith("cyl_weight: cylinder r 0.5 m, length 0.2 m, 10 kg, centre at (0, 0, 4) m (SDF 1.4)")
    assert "adapted for MuJoCo" in line


def test_the_proper_child_element_form_reads_the_same() -> None:
    text = BOOK_WEIGHT.read_text().replace('<cylinder length="0.2" radius="0.5"/>',
                                           "<cylinder><radius>0.5</radius><length>0.2</length></cylinder>")
    model = parse_model_xml(text, name="w", position=(0, 0, 4))
    book = parse_model_xml(BOOK_WEIGHT.read_text(), name="w", position=(0, 0, 4))
    assert model.spec == book.spec
    assert not any("attributes" in note for note in model.notes)


def test_a_consistent_model_is_taken_without_adaptations() -> None:
    i = solid_inertia("box", (0.2, 0.4, 0.6), 3.0)
    text = sdf(f"<inertial><mass>3</mass><inertia><ixx>{i[0]}</ixx><iyy>{i[1]}</iyy><izz>{i[2]}</izz>"
               f"</inertia></inertial>{BOX_COLLISION}")
    model = parse_model_xml(text, name="crate", position=(1, 2, 3))
    assert model.notes == ()
    assert (model.spec.shape, model.spec.size_m, model.spec.mass_kg) == ("box", (0.2, 0.4, 0.6), 3.0)
    assert "adapted" not in model.describe()


def test_sdf_defaults_mass_and_friction() -> None:
    model = parse_model_xml(sdf('<collision name="c"><geometry><sphere><radius>0.1</radius></sphere></geometry>'
                                "</collision>"), name="ball", position=(0, 0, 1))
    assert model.spec.mass_kg == 1.0 and model.spec.friction == 1.0
    assert any("default mass of 1 kg" in n for n in model.notes)


# -- refusals name the element ----------------------------------------------------------------------

@pytest.mark.parametrize(("text", "field", "fragment"), [
    (sdf(BOX_COLLISION, model_extra='<joint name="j" type="revolute"><parent>l</parent><child>l</child></joint>'),
     "sdf/model/joint", "joint"),
    ('<sdf version="1.6"><model name="m"><link name="a">' + BOX_COLLISION + '</link><link name="b">'
     + BOX_COLLISION + "</link></model></sdf>", "sdf/model/link[2]", "several links"),
    (sdf('<collision name="c"><geometry><mesh><uri>model://m.dae</uri></mesh></geometry></collision>'),
     "sdf/model/link/collision/geometry/mesh", "boxes, cylinders or spheres"),
    (sdf('<collision name="c"><geometry><capsule><radius>1</radius><length>1</length></capsule></geometry>'
         "</collision>"), "sdf/model/link/collision/geometry/capsule", "boxes, cylinders or spheres"),
    (sdf('<collision name="c"><geometry><plane><normal>0 0 1</normal></plane></geometry></collision>'),
     "sdf/model/link/collision/geometry/plane", "boxes"),
    (sdf(BOX_COLLISION, model_extra='<plugin name="p" filename="libp.so"/>'), "sdf/model/plugin", "plugins"),
    (sdf(BOX_COLLISION + '<visual name="v"><plugin name="p" filename="libv.so"/></visual>'),
     "sdf/model/link/visual/plugin", "plugins"),
    (sdf(BOX_COLLISION + '<sensor name="s" type="contact"/>'), "sdf/model/link/sensor", "sensors"),
    (sdf(BOX_COLLISION, model_extra="<static>true</static>"), "sdf/model/static", "static"),
    (sdf(BOX_COLLISION + "<gravity>false</gravity>"), "sdf/model/link/gravity", "gravity"),
    (sdf(BOX_COLLISION + "<kinematic>1</kinematic>"), "sdf/model/link/kinematic", "kinematic"),
    (sdf(BOX_COLLISION + "<wobble/>"), "sdf/model/link/wobble", "cannot represent"),
    (sdf(BOX_COLLISION, model_extra='<include><uri>model://x</uri></include>'), "sdf/model/include", "included"),
    ('<sdf version="1.6"><world name="w"/></sdf>', "sdf/world", "worlds"),
    ('<sdf version="1.6"><model name="a">' + "<link name='l'>" + BOX_COLLISION + "</link></model>"
     '<model name="b"/></sdf>', "sdf/model[2]", "one <model>"),
    (sdf("<inertial><mass>1</mass></inertial>"), "sdf/model/link/collision", "collision"),
    (sdf(BOX_COLLISION + BOX_COLLISION), "sdf/model/link/collision[2]", "one collision"),
    (sdf('<collision name="c"><geometry><box><size>1 1 1</size></box><sphere><radius>1</radius></sphere>'
         "</geometry></collision>"), "sdf/model/link/collision/geometry", "exactly one shape"),
    (sdf('<collision name="c"><geometry><cylinder radius="-0.5" length="0.2"/></geometry></collision>'),
     "sdf/model/link/collision/geometry/cylinder/radius", "positive"),
    (sdf('<collision name="c"><geometry><cylinder radius="0.5"/></geometry></collision>'),
     "sdf/model/link/collision/geometry/cylinder/length", "required"),
    (sdf('<collision name="c"><geometry><box><size>1 1</size></box></geometry></collision>'),
     "sdf/model/link/collision/geometry/box/size", "3 numbers"),
    (sdf('<pose relative_to="other">0 0 0 0 0 0</pose>' + BOX_COLLISION), "sdf/model/link/pose@relative_to",
     "named frames"),
    (sdf("<inertial><mass>nan</mass></inertial>" + BOX_COLLISION), "sdf/model/link/inertial/mass", "finite"),
    ("<sdf version='1.6'><model name='m'><link name='l'>", "model_xml", "well-formed"),
    ('<!DOCTYPE x [<!ENTITY a "aaaa">]><sdf/>', "model_xml", "entities"),
    ("", "model_xml", "empty"),
    ("<mujoco/>", "mujoco", "<sdf> or a URDF <robot>"),
    ('<robot name="r"><link name="a"/><link name="b"/></robot>', "robot/link[2]", "several links"),
    (('<robot name="r"><link name="a"><collision><geometry><box size="1 1 1"/></geometry></collision></link>'
     '<joint name="j" type="fixed"><parent link="a"/><child link="a"/></joint></robot>'), "robot/joint", "joint"),
    (('<robot name="r"><link name="a"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1"/></inertial>'
     '<collision><geometry><mesh filename="package://x/m.stl"/></geometry></collision></link></robot>'),
     "robot/link/collision/geometry/mesh", "boxes, cylinders or spheres"),
    (('<robot name="r"><link name="a"><collision><geometry><box size="1 1 1"/></geometry></collision></link>'
     "</robot>"), "robot/link/inertial", "no mass"),
    ('<robot name="r"><link name="a"/><gazebo><plugin name="p" filename="libp.so"/></gazebo></robot>',
     "robot/gazebo/plugin", "plugins"),
    (('<robot name="r"><link name="a"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1"/></inertial>'
     '<collision><geometry><box size="1 1 1"/></geometry></collision></link><gazebo reference="b"><mu1>1</mu1>'
     "</gazebo></robot>"), "robot/gazebo@reference", "does not have"),
])
def test_what_cannot_be_represented_is_refused_naming_the_element(text, field, fragment) -> None:
    with pytest.raises(UnsupportedModel) as err:
        parse_model_xml(text, name="thing", position=(0, 0, 3))
    assert err.value.field == field
    assert fragment in str(err.value)


@pytest.mark.parametrize("name", ["", "two words", "a/b", None, "-x"])
def test_model_names_must_be_usable(name) -> None:
    with pytest.raises(UnsupportedModel) as err:
        parse_model_xml(BOOK_WEIGHT.read_text(), name=name)
    assert err.value.field == "model_name"


def test_a_model_starting_below_the_ground_is_refused_unless_there_is_no_floor() -> None:
    with pytest.raises(UnsupportedModel) as err:
        parse_model_xml(BOOK_WEIGHT.read_text(), name="w", position=(0, 0, 0.05))
    assert err.value.field == "initial_pose.position"
    assert parse_model_xml(BOOK_WEIGHT.read_text(), name="w", position=(0, 0, 0.05), floor=False).spec.xyz[2] == 0.05


@pytest.mark.parametrize("orientation", [(1, 0, 0, math.nan), ("a", 0, 0, 0)])
def test_bad_orientations_are_refused(orientation) -> None:
    with pytest.raises(UnsupportedModel) as err:
        parse_model_xml(BOOK_WEIGHT.read_text(), name="w", position=(0, 0, 4), orientation=orientation)
    assert err.value.field == "initial_pose.orientation"


# -- frames and poses ------------------------------------------------------------------------------

def _matrix(quat_wxyz) -> np.ndarray:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat_wxyz, dtype=float) / np.linalg.norm(quat_wxyz))
    return R.reshape(3, 3)


def test_poses_compose_initial_then_model_then_link_then_collision() -> None:
    collision = ('<collision name="c"><pose>0 0 0.1 0 0 0</pose><geometry><box><size>0.2 0.2 0.2</size></box>'
                 "</geometry></collision>")
    text = sdf(f"<pose>0.5 0 0 0 0 0</pose>{collision}", model_extra="<pose>0 0 1 0 0 1.5707963267948966</pose>")
    yaw = math.pi / 2
    q = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))  # initial pose: quarter turn about z
    model = parse_model_xml(text, name="b", position=(10, 0, 0), orientation=q)
    # initial (10,0,0) yawed 90°, then model pose (0,0,1) yawed 90° more, then link x 0.5, collision z 0.1:
    # the link's x axis points along -x in the world.
    assert model.spec.xyz == pytest.approx((10 - 0.5, 0.0, 1.1))
    assert rpy_to_matrix(model.spec.rpy) == pytest.approx(rpy_to_matrix((0, 0, math.pi)), abs=1e-12)
    # The model frame (Gazebo's model pose: initial then the model's own pose) from the body pose.
    body_R = rpy_to_matrix(model.spec.rpy)
    frame_world = np.asarray(model.spec.xyz) + body_R @ np.asarray(model.frame_xyz)
    assert frame_world == pytest.approx((10.0, 0.0, 1.0))
    assert body_R @ _matrix(model.frame_quat) == pytest.approx(rpy_to_matrix((0, 0, math.pi)), abs=1e-12)


def test_a_default_pose_message_means_no_rotation_and_others_are_normalised() -> None:
    text = BOOK_WEIGHT.read_text()
    zero = parse_model_xml(text, name="w", position=(0, 0, 4), orientation=(0, 0, 0, 0))
    scaled = parse_model_xml(text, name="w", position=(0, 0, 4), orientation=(2, 0, 0, 0))
    assert zero.spec.rpy == pytest.approx((0, 0, 0)) and scaled.spec.rpy == pytest.approx((0, 0, 0))


def test_inertia_and_centre_of_mass_are_those_of_a_solid_and_differences_are_said() -> None:
    i = solid_inertia("box", (0.2, 0.4, 0.6), 3.0)
    inertial = (f"<inertial><pose>0.01 0 0 0 0 0</pose><mass>3</mass><inertia><ixx>{i[0]}</ixx><ixy>0.01</ixy>"
                f"<iyy>{i[1]}</iyy><izz>{i[2]}</izz></inertia></inertial>")
    inertial = inertial.replace("<ixy>0.01</ixy>", "<ixy>0.005</ixy>")
    model = parse_model_xml(sdf(inertial + BOX_COLLISION), name="crate", position=(0, 0, 1))
    notes = " | ".join(model.notes)
    assert "inertia" not in notes  # a product of 0.005 is within the tolerance of this box (5 % of 0.13)
    assert "centre of mass (0.01, 0, 0) m off the shape's centre" in notes
    inertial = inertial.replace("<ixy>0.005</ixy>", "<ixy>0.05</ixy>")
    notes = " | ".join(parse_model_xml(sdf(inertial + BOX_COLLISION), name="crate", position=(0, 0, 1)).notes)
    assert "(full tensor)" in notes


def test_urdf_models_read_mass_geometry_and_gazebo_friction() -> None:
    text = ('<robot name="crate"><link name="crate_link"><inertial><origin xyz="0 0 0.1"/><mass value="2"/>'
            '<inertia ixx="0.0133333" ixy="0" ixz="0" iyy="0.0133333" iyz="0" izz="0.0133333"/></inertial>'
            '<visual><geometry><mesh filename="package://crate/crate.dae"/></geometry></visual>'
            '<collision><origin xyz="0 0 0.1" rpy="0 0 0"/><geometry><box size="0.2 0.2 0.2"/></geometry>'
            '</collision></link><gazebo reference="crate_link"><mu1>0.6</mu1><mu2>0.6</mu2><kp>1e6</kp>'
            "<material>Gazebo/Wood</material></gazebo></robot>")
    model = parse_model_xml(text, name="crate", position=(1, 0, 0))
    assert (model.spec.shape, model.spec.size_m, model.spec.mass_kg) == ("box", (0.2, 0.2, 0.2), 2.0)
    assert model.spec.xyz == pytest.approx((1.0, 0.0, 0.1)) and model.spec.friction == 0.6
    assert model.frame_xyz == pytest.approx((0.0, 0.0, -0.1))  # the link frame below the box's centre
    assert model.format == "URDF" and model.notes == ("gazebo kp not used (MuJoCo's soft contacts)",)


# -- in the world ---------------------------------------------------------------------------------

def _session(gravity: float, command: float) -> Session:
    scenario = dataclasses.replace(scenario_for_robot("one_dof", "position"), gravity_m_s2=(0.0, 0.0, gravity))
    session = Session(scenario)
    session.manager.controller("joint1_position_controller").set_reference(command)
    session.loop.run(1.0)
    return session


def test_a_spawned_body_has_its_centre_of_mass_at_its_origin() -> None:
    session = _session(-9.81, -0.5)
    session.world.spawn(parse_model_xml(BOOK_WEIGHT.read_text(), name="w", position=(0, 0, 4)).spec)
    model = session.world.model
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "w")
    assert model.body_ipos[body] == pytest.approx([0.0, 0.0, 0.0])
    assert model.body_inertia[body] == pytest.approx([10 * (3 * 0.25 + 0.04) / 12] * 2 + [1.25])


def test_removing_one_object_keeps_the_others_and_the_robot_where_they_are() -> None:
    session = _session(-9.81, -0.5)
    world = session.world
    world.spawn(parse_model_xml(sdf(BOX_COLLISION), name="a", position=(1, 0, 0.3)).spec)
    world.spawn(parse_model_xml(sdf(BOX_COLLISION), name="b", position=(-1, 0, 0.3)).spec)
    session.loop.run(1.0)
    a_before, q_before = world.body_pose("a")[0], session.hardware.position[0]
    assert world.remove("b").name == "b"
    assert [o.name for o in world.spawned] == ["a"] and not world.has_body("b")
    assert world.body_pose("a")[0] == pytest.approx(a_before, abs=1e-12)
    session.loop.run(0.1)
    assert session.hardware.position[0] == pytest.approx(q_before, abs=1e-4)
    with pytest.raises(ConfigError):
        world.remove("b")


@pytest.mark.slow
def test_the_books_weight_dropped_on_the_piston_rests_at_the_theoretical_load() -> None:
    """Figure 11.5's drop (piston at -0.2 m, gravity -5) then gravity -9.8: the sensor carries the
    weight and its plate, the actuator also the piston, and the joint sits at -0.2 - effort/Kp."""
    session = _session(-5.0, -0.2)
    world, hw = session.world, session.hardware
    world.spawn(parse_model_xml(BOOK_WEIGHT.read_text(), name="cyl_weight", position=(0, 0, 4)).spec)
    samples: list[tuple[float, float, float]] = []
    session.loop.add_observer(lambda t: samples.append((hw.wrenches["ft_sensor"][2], hw.effort[0], hw.position[0])))
    for g in (5.0, 9.8):
        world.set_gravity((0.0, 0.0, -g))
        session.manager.context.set_gravity((0.0, 0.0, -g))
        session.loop.run(14.0)
        samples.clear()
        session.loop.run(1.0)
        force, effort, joint = np.mean(samples, axis=0)
        assert force == pytest.approx(-(10 + 0.01) * g, rel=2e-3)
        assert effort == pytest.approx((10 + 1.01) * g, rel=2e-3)
        assert joint == pytest.approx(-0.2 - (10 + 1.01) * g / 400, abs=5e-4)
        position, quat = world.body_pose("cyl_weight")
        # On the disk (MuJoCo's soft contact lets it sink a few millimetres into it).
        assert position == pytest.approx([0.0, 0.0, 2.0 + joint + 0.005 + 0.1], abs=5e-3)
        assert 2 * math.degrees(math.acos(min(1.0, abs(quat[0])))) < 1.0  # flat on the disk

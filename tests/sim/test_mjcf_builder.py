"""Tests of the RobotModel -> MuJoCo MjSpec builder and its repairs of the URDF import."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jointctl.errors import ModelError
from jointctl.model import load_robot_model
from jointctl.model.loader import expand_xacro
from jointctl.model.mjcf import COLLISION_GROUP, VISUAL_GROUP, rpy_to_matrix, rpy_to_quat
from jointctl.model.package_paths import PackageResolver
from jointctl.model.urdf_parser import parse_urdf
from jointctl.paths import robots_dir
from jointctl.sim import MujocoWorld, WorldSettings, build_spec

ONE_DOF_XACRO = robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro"
DISK_KG = 0.01


def one_dof_urdf_text() -> str:
    return expand_xacro(ONE_DOF_XACRO, PackageResolver(), {})


def compile_robot(robot, settings: WorldSettings = WorldSettings()) -> mujoco.MjModel:
    return build_spec(robot, settings).compile()


def body_id(m: mujoco.MjModel, name: str) -> int:
    bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
    assert bid >= 0, f"no body {name!r}"
    return bid


@pytest.fixture(scope="module")
def one_dof():
    return load_robot_model(ONE_DOF_XACRO)


@pytest.fixture(scope="module")
def locked_variant(tmp_path_factory: pytest.TempPathFactory):
    """The 1-DOF robot with the chapter's Gazebo sensor joint: prismatic, lower == upper == 0."""
    root = ET.fromstring(one_dof_urdf_text())
    (joint,) = [j for j in root.findall("joint") if j.get("name") == "ft_sensor_jnt"]
    assert joint.get("type") == "fixed"
    joint.set("type", "prismatic")
    ET.SubElement(joint, "axis", xyz="0 0 1")
    ET.SubElement(joint, "limit", lower="0", upper="0", effort="1000", velocity="100")
    path = tmp_path_factory.mktemp("locked") / "one_dof_locked.urdf"
    path.write_text(ET.tostring(root, encoding="unicode"))
    robot = load_robot_model(path)
    assert robot.joint("ft_sensor_jnt").type == "prismatic"
    assert robot.joint("ft_sensor_jnt").is_locked
    return robot


# -- the locked sensor joint and the masses ------------------------------------


@pytest.mark.parametrize("variant", ["one_dof", "locked_variant"])
def test_sensor_joint_becomes_a_weld_and_the_sensor_link_a_body(variant: str, request) -> None:
    m = compile_robot(request.getfixturevalue(variant))
    assert m.njnt == 1
    assert m.nq == 1 and m.nv == 1
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "joint1") == 0
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "ft_sensor_jnt") == -1
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_SLIDE
    disk = body_id(m, "ft_sensor_link")
    link2 = body_id(m, "link2")
    assert disk != link2
    assert m.body_parentid[disk] == link2
    assert m.body_jntnum[disk] == 0
    assert m.body_mass[disk] == pytest.approx(DISK_KG, abs=1e-12)
    assert m.body_pos[disk] == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)


@pytest.mark.parametrize("variant", ["one_dof", "locked_variant"])
def test_masses_survive(variant: str, request) -> None:
    m = compile_robot(request.getfixturevalue(variant))
    link1, link2 = body_id(m, "link1"), body_id(m, "link2")
    assert m.body_parentid[link1] == 0  # the world link is MuJoCo's world body
    assert m.body_mass[link1] == pytest.approx(1.0, abs=1e-12)
    assert m.body_mass[link2] == pytest.approx(1.0, abs=1e-12)
    assert m.body_subtreemass[link2] == pytest.approx(1.0 + DISK_KG, abs=1e-12)
    assert m.body_subtreemass[0] == pytest.approx(2.0 + DISK_KG, abs=1e-12)


def test_joint_range_damping_and_axis(one_dof) -> None:
    m = compile_robot(one_dof)
    assert m.jnt_limited[0] == 1
    assert m.jnt_range[0] == pytest.approx([-1.0, 0.0], abs=0)
    assert m.dof_damping[0] == 10.0
    assert m.dof_frictionloss[0] == 0.0
    assert m.jnt_axis[0] == pytest.approx([0.0, 0.0, 1.0], abs=0)
    assert m.body_pos[body_id(m, "link2")] == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)


# -- contacts ------------------------------------------------------------------


def link_pairs(m: mujoco.MjModel, d: mujoco.MjData) -> set[frozenset[str]]:
    pairs = set()
    for c in d.contact[: d.ncon]:
        names = (m.body(m.geom_bodyid[c.geom[0]]).name, m.body(m.geom_bodyid[c.geom[1]]).name)
        pairs.add(frozenset(names))
    return pairs


@pytest.mark.parametrize("variant", ["one_dof", "locked_variant"])
def test_no_contact_between_parent_and_child_at_the_lowest_position(variant: str, request) -> None:
    world = MujocoWorld(request.getfixturevalue(variant), initial_positions={"joint1": -1.0})
    m, d = world.model, world.data
    # link2 (r 0.1, z 0..1 at q = -1) overlaps link1's collision box (0.2 x 0.2 x 0.7)
    assert frozenset({"link1", "link2"}) not in link_pairs(m, d)
    for _ in range(50):
        mujoco.mj_step(m, d)
        pairs = link_pairs(m, d)
        assert frozenset({"link1", "link2"}) not in pairs
        assert frozenset({"link2", "ft_sensor_link"}) not in pairs
    # nothing holds the piston up at the bottom but the joint limit (and the floor): no push from link1
    assert d.qpos[0] == pytest.approx(-1.0, abs=5e-3)


def test_without_the_excludes_link1_and_link2_would_collide(one_dof) -> None:
    """The control experiment: the geometry really overlaps, so the previous test can fail."""
    spec = build_spec(one_dof, WorldSettings())
    assert len(spec.excludes) >= 1
    for exclude in list(spec.excludes):
        spec.delete(exclude)
    m = spec.compile()
    d = mujoco.MjData(m)
    d.qpos[0] = -1.0
    mujoco.mj_forward(m, d)
    assert frozenset({"link1", "link2"}) in link_pairs(m, d)


def test_excludes_are_the_parent_child_pairs(one_dof) -> None:
    m = compile_robot(one_dof)
    link1, link2, disk = (body_id(m, n) for n in ("link1", "link2", "ft_sensor_link"))
    signatures = set(int(s) for s in m.exclude_signature)
    expected = {(min(a, b) << 16) + max(a, b) for a, b in ((link1, link2), (link2, disk))}
    assert signatures == expected


# -- actuators and sensors -----------------------------------------------------


def test_one_motor_per_transmission_with_the_effort_limit(one_dof) -> None:
    m = compile_robot(one_dof)
    assert m.nu == len(one_dof.transmissions) == 1
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "joint1") == 0
    assert m.actuator_trntype[0] == mujoco.mjtTrn.mjTRN_JOINT
    assert m.actuator_trnid[0, 0] == mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "joint1")
    assert m.actuator_forcelimited[0] == 1
    assert m.actuator_forcerange[0] == pytest.approx([-1000.0, 1000.0], abs=0)
    assert m.actuator_gear[0, 0] == 1.0
    assert m.actuator_gainprm[0, 0] == 1.0  # a motor: force = ctrl
    assert m.actuator_biastype[0] == mujoco.mjtBias.mjBIAS_NONE


def test_force_and_torque_sensors_at_the_sensor_link_origin(one_dof) -> None:
    m = compile_robot(one_dof)
    force = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, "ft_sensor_force")
    torque = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, "ft_sensor_torque")
    assert force >= 0 and torque >= 0
    assert m.sensor_type[force] == mujoco.mjtSensor.mjSENS_FORCE
    assert m.sensor_type[torque] == mujoco.mjtSensor.mjSENS_TORQUE
    assert m.sensor_dim[force] == 3 and m.sensor_dim[torque] == 3
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "ft_sensor_site")
    assert site >= 0
    for sid in (force, torque):
        assert m.sensor_objtype[sid] == mujoco.mjtObj.mjOBJ_SITE
        assert m.sensor_objid[sid] == site
    assert m.site_bodyid[site] == body_id(m, "ft_sensor_link")
    assert m.site_pos[site] == pytest.approx([0.0, 0.0, 0.0], abs=0)


def test_velocity_only_transmission_is_refused(tmp_path: Path) -> None:
    text = one_dof_urdf_text().replace("EffortJointInterface", "VelocityJointInterface")
    path = tmp_path / "velocity.urdf"
    path.write_text(text)
    robot = load_robot_model(path)
    assert robot.transmissions[0].hardware_interfaces == ("VelocityJointInterface",)
    with pytest.raises(ModelError) as info:
        build_spec(robot, WorldSettings())
    error = info.value
    assert error.source == str(path)
    assert error.field == "transmission[tran1].hardwareInterface"
    assert "VelocityJointInterface" in str(error)
    assert "transmission[tran1]" in str(error)


def test_effort_and_velocity_interfaces_together_are_accepted(tmp_path: Path) -> None:
    text = one_dof_urdf_text()
    text = text.replace(
        "<hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>",
        "<hardwareInterface>hardware_interface/VelocityJointInterface</hardwareInterface>"
        "<hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>",
        1,
    )
    robot = parse_urdf(text)
    assert set(robot.transmissions[0].hardware_interfaces) == {"VelocityJointInterface", "EffortJointInterface"}
    assert compile_robot(robot).nu == 1


# -- world settings ------------------------------------------------------------


def test_gravity_and_timestep_come_from_settings(one_dof) -> None:
    m = compile_robot(one_dof, WorldSettings(timestep_s=0.0025, gravity_m_s2=(0.5, -1.0, -5.0)))
    assert m.opt.timestep == 0.0025
    assert m.opt.gravity == pytest.approx([0.5, -1.0, -5.0], abs=0)
    default = compile_robot(one_dof)
    assert default.opt.timestep == 0.001
    assert default.opt.gravity == pytest.approx([0.0, 0.0, -9.81], abs=0)
    assert default.names.split(b"\0")[0] == b"one_DOF_robot"


def test_floor(one_dof) -> None:
    with_floor = compile_robot(one_dof, WorldSettings(floor=True))
    fid = mujoco.mj_name2id(with_floor, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    assert fid >= 0
    assert with_floor.geom_type[fid] == mujoco.mjtGeom.mjGEOM_PLANE
    assert with_floor.geom_bodyid[fid] == 0
    without = compile_robot(one_dof, WorldSettings(floor=False))
    assert mujoco.mj_name2id(without, mujoco.mjtObj.mjOBJ_GEOM, "floor") == -1
    assert mujoco.mjtGeom.mjGEOM_PLANE not in set(without.geom_type)
    assert without.ngeom == with_floor.ngeom - 1


# -- geometry, frames, inertia -------------------------------------------------


def test_geoms_sizes_and_groups(one_dof) -> None:
    m = compile_robot(one_dof)

    def geom(name: str) -> int:
        gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
        assert gid >= 0, name
        return gid

    box = geom("link1_collision_0")
    assert m.geom_type[box] == mujoco.mjtGeom.mjGEOM_BOX
    assert m.geom_size[box] == pytest.approx([0.1, 0.1, 0.35], abs=1e-12)  # half lengths
    assert m.geom_pos[box] == pytest.approx([0.0, 0.0, 0.35], abs=1e-12)
    assert m.geom_group[box] == COLLISION_GROUP
    assert (m.geom_contype[box], m.geom_conaffinity[box]) == (1, 1)
    cyl = geom("link2_collision_0")
    assert m.geom_type[cyl] == mujoco.mjtGeom.mjGEOM_CYLINDER
    assert m.geom_size[cyl][:2] == pytest.approx([0.1, 0.5], abs=1e-12)  # radius, half length
    vis = geom("link1_visual_0")
    assert m.geom_size[vis] == pytest.approx([0.1, 0.1, 0.5], abs=1e-12)
    assert m.geom_group[vis] == VISUAL_GROUP
    assert (m.geom_contype[vis], m.geom_conaffinity[vis]) == (0, 0)


TWO_LINK = """<robot name="two">
  <link name="base">
    <inertial><mass value="3"/><inertia ixx="1" iyy="1" izz="1"/></inertial>
    <collision><geometry><sphere radius="0.2"/></geometry></collision>
  </link>
  <link name="arm">
    <inertial>
      <origin xyz="0.1 0 0" rpy="0 0 1.5707963267948966"/>
      <mass value="2"/>
      <inertia ixx="0.1" iyy="0.2" izz="0.3"/>
    </inertial>
  </link>
  <joint name="hinge" type="revolute">
    <parent link="base"/><child link="arm"/>
    <origin xyz="0.5 0 1" rpy="0 0 1.5707963267948966"/>
    <axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="7" velocity="1"/>
    <dynamics damping="0.2" friction="0.3"/>
  </joint>
  <transmission name="t"><joint name="hinge"><hardwareInterface>EffortJointInterface</hardwareInterface></joint></transmission>
</robot>"""


def test_root_without_world_link_is_bolted_to_the_world() -> None:
    m = compile_robot(parse_urdf(TWO_LINK))
    base = body_id(m, "base")
    assert m.body_parentid[base] == 0
    assert m.body_jntnum[base] == 0
    assert m.body_mass[base] == pytest.approx(3.0, abs=1e-12)
    arm = body_id(m, "arm")
    assert m.body_parentid[arm] == base
    assert m.body_mass[arm] == pytest.approx(2.0, abs=1e-12)
    assert m.nexclude == 1
    assert int(m.exclude_signature[0]) == (min(base, arm) << 16) + max(base, arm)
    assert m.actuator_forcerange[0] == pytest.approx([-7.0, 7.0], abs=0)
    assert m.dof_damping[0] == 0.2
    assert m.dof_frictionloss[0] == 0.3


def test_joint_origin_and_axis_in_the_child_frame() -> None:
    m = compile_robot(parse_urdf(TWO_LINK))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    arm = body_id(m, "arm")
    assert d.xpos[arm] == pytest.approx([0.5, 0.0, 1.0], abs=1e-12)
    # axis x of the child frame, which is yawed by 90 degrees: y in the world
    assert d.xaxis[0] == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_HINGE
    # turning the hinge turns the arm's centre of mass about world y
    d.qpos[0] = 0.3
    mujoco.mj_forward(m, d)
    com_offset = Rotation.from_euler("xyz", [0, 0, math.pi / 2]).apply([0.1, 0.0, 0.0])  # in the world at q = 0
    expected = np.array([0.5, 0.0, 1.0]) + Rotation.from_rotvec([0.0, 0.3, 0.0]).apply(com_offset)
    assert d.xipos[arm] == pytest.approx(expected, abs=1e-12)


def test_inertia_of_a_rotated_inertial_frame() -> None:
    m = compile_robot(parse_urdf(TWO_LINK))
    arm = body_id(m, "arm")
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, m.body_iquat[arm])
    rot = rot.reshape(3, 3)
    tensor = rot @ np.diag(m.body_inertia[arm]) @ rot.T
    # a 90 degree yaw swaps ixx and iyy in the link frame
    assert tensor == pytest.approx(np.diag([0.2, 0.1, 0.3]), abs=1e-12)
    assert m.body_ipos[arm] == pytest.approx([0.1, 0.0, 0.0], abs=1e-12)


def test_continuous_joint_is_an_unlimited_hinge_without_force_limit() -> None:
    text = TWO_LINK.replace('type="revolute"', 'type="continuous"').replace(
        '<limit lower="-1" upper="1" effort="7" velocity="1"/>', "")
    m = compile_robot(parse_urdf(text))
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_HINGE
    assert m.jnt_limited[0] == 0
    assert m.nu == 1
    assert m.actuator_forcelimited[0] == 0


def test_transmission_on_a_joint_that_cannot_move_is_refused() -> None:
    text = TWO_LINK.replace('lower="-1" upper="1"', 'lower="0.2" upper="0.2"')
    robot = parse_urdf(text, source="locked.urdf")
    with pytest.raises(ModelError) as info:
        build_spec(robot, WorldSettings())
    assert info.value.field == "transmission[t].joint"
    assert "'hinge'" in str(info.value)


@pytest.mark.parametrize("jtype", ["floating", "planar"])
def test_unsupported_joint_types_are_refused(jtype: str) -> None:
    text = TWO_LINK.replace('type="revolute"', f'type="{jtype}"').replace(
        '<limit lower="-1" upper="1" effort="7" velocity="1"/>', "")
    text = text[: text.index("<transmission")] + "</robot>"
    with pytest.raises(ModelError) as info:
        build_spec(parse_urdf(text), WorldSettings())
    assert info.value.field == "joint[hinge].type"
    assert repr(jtype) in str(info.value)


def test_locked_joint_at_a_nonzero_value_keeps_its_offset() -> None:
    text = """<robot name="r"><link name="world"/>
      <link name="a"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1"/></inertial></link>
      <joint name="j" type="prismatic"><parent link="world"/><child link="a"/>
        <origin xyz="0 0 1"/><axis xyz="0 0 1"/>
        <limit lower="0.3" upper="0.3" effort="1" velocity="1"/></joint></robot>"""
    m = compile_robot(parse_urdf(text))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert m.njnt == 0
    assert d.xpos[body_id(m, "a")] == pytest.approx([0.0, 0.0, 1.3], abs=1e-12)


def test_meshes_are_loaded_once_per_file_and_scale(tmp_path: Path) -> None:
    obj = tmp_path / "tet.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    mesh = f'<geometry><mesh filename="{obj}" scale="0.1 0.1 0.1"/></geometry>'
    text = f"""<robot name="m"><link name="a">
      <inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1"/></inertial>
      <visual>{mesh}</visual><collision>{mesh}</collision>
      <collision><geometry><mesh filename="{obj}"/></geometry></collision></link></robot>"""
    m = compile_robot(parse_urdf(text), WorldSettings(floor=False))
    assert m.nmesh == 2  # (path, scale 0.1) shared by two geoms, (path, scale 1) the third
    assert m.ngeom == 3
    assert set(int(t) for t in m.geom_type) == {int(mujoco.mjtGeom.mjGEOM_MESH)}
    mesh_of = {m.geom(g).name: int(m.geom_dataid[g]) for g in range(m.ngeom)}
    assert mesh_of["a_visual_0"] == mesh_of["a_collision_0"] != mesh_of["a_collision_1"]

    def diameter(mesh_id: int) -> float:
        adr, num = m.mesh_vertadr[mesh_id], m.mesh_vertnum[mesh_id]
        verts = m.mesh_vert[adr : adr + num]
        return max(float(np.linalg.norm(a - b)) for a in verts for b in verts)

    # the tetrahedron's longest edge is sqrt(2) (unscaled) and 0.1 sqrt(2) scaled
    assert diameter(mesh_of["a_collision_1"]) == pytest.approx(math.sqrt(2), rel=1e-6)
    assert diameter(mesh_of["a_collision_0"]) == pytest.approx(0.1 * math.sqrt(2), rel=1e-6)


# -- rpy conversions -----------------------------------------------------------

EDGE_RPY = [
    (0.0, 0.0, 0.0),
    (math.pi, 0.0, 0.0),
    (0.0, math.pi / 2, 0.0),
    (0.3, -math.pi / 2, -1.2),
    (0.0, 0.0, -math.pi),
    (math.pi, math.pi, math.pi),
]


def random_rpy(n: int = 300) -> list[tuple[float, float, float]]:
    rng = np.random.default_rng(20240611)
    return [tuple(float(a) for a in row) for row in rng.uniform(-math.pi, math.pi, size=(n, 3))] + EDGE_RPY


def test_rpy_to_matrix_is_fixed_axis_xyz() -> None:
    for rpy in random_rpy():
        expected = Rotation.from_euler("xyz", rpy).as_matrix()
        assert rpy_to_matrix(rpy) == pytest.approx(expected, abs=1e-12), rpy


def test_rpy_to_quat_is_fixed_axis_xyz() -> None:
    for rpy in random_rpy():
        x, y, z, w = Rotation.from_euler("xyz", rpy).as_quat()
        quat = np.array(rpy_to_quat(rpy))
        assert np.linalg.norm(quat) == pytest.approx(1.0, abs=1e-12)
        expected = np.array([w, x, y, z])
        sign = 1.0 if float(np.dot(quat, expected)) >= 0 else -1.0  # q and -q are one rotation
        assert quat == pytest.approx(sign * expected, abs=1e-9), rpy


def test_rpy_is_not_the_moving_axis_convention() -> None:
    """Guard: the intrinsic 'XYZ' sequence differs for a generic rpy, so the tests above can tell."""
    rpy = (0.4, -0.7, 1.1)
    assert not np.allclose(rpy_to_matrix(rpy), Rotation.from_euler("XYZ", rpy).as_matrix(), atol=1e-3)

"""Tests of loading URDF / xacro files, with ``$(find pkg)`` and ``package://`` resolved without ROS."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from jointctl.errors import ModelError
from jointctl.model import load_robot_model
from jointctl.model.loader import expand_xacro
from jointctl.model.package_paths import PackageResolver
from jointctl.paths import robots_dir

ONE_DOF_XACRO = robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro"
XACRO_NS = 'xmlns:xacro="http://www.ros.org/wiki/xacro"'


@pytest.fixture(autouse=True)
def clean_package_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("JOINTCTL_PACKAGE_PATH", raising=False)
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)


def make_package(parent: Path, folder: str, name: str | None) -> Path:
    """A package folder under ``parent``; ``name`` in its package.xml (no package.xml when None)."""
    pkg = parent / folder
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "meshes").mkdir()
    (pkg / "meshes" / "part.stl").write_text("solid part\nendsolid part\n")
    if name is not None:
        (pkg / "package.xml").write_text(
            f'<?xml version="1.0"?>\n<package format="2">\n  <name>{name}</name>\n'
            "  <version>0.0.1</version>\n</package>\n"
        )
    return pkg


MACROS = f"""<?xml version="1.0"?>
<robot {XACRO_NS}>
  <xacro:macro name="part" params="name">
    <link name="${{name}}">
      <visual><geometry><mesh filename="package://my_pkg/meshes/part.stl"/></geometry></visual>
    </link>
  </xacro:macro>
</robot>
"""

TOP = f"""<?xml version="1.0"?>
<robot name="pkg_robot" {XACRO_NS}>
  <xacro:include filename="$(find my_pkg)/urdf/macros.xacro"/>
  <xacro:part name="base"/>
</robot>
"""


@pytest.fixture
def workspace(tmp_path: Path) -> Path:
    """tmp/ws/src_dir is package ``my_pkg`` (the folder name differs from the package name)."""
    ws = tmp_path / "ws"
    pkg = make_package(ws, "src_dir", "my_pkg")
    (pkg / "urdf" / "macros.xacro").write_text(MACROS)
    return ws


@pytest.fixture
def top_xacro(tmp_path: Path) -> Path:
    path = tmp_path / "elsewhere" / "top.urdf.xacro"
    path.parent.mkdir()
    path.write_text(TOP)
    # ``.urdf.xacro`` ends in ``.xacro``: the suffix is what counts
    return path


# -- the chapter's 1-DOF robot -----------------------------------------------


def test_one_dof_robot_from_xacro() -> None:
    robot = load_robot_model(ONE_DOF_XACRO)
    assert robot.name == "one_DOF_robot"
    assert robot.namespace == "one_DOF_robot"
    assert robot.source == str(ONE_DOF_XACRO)
    assert tuple(j.name for j in robot.movable_joints) == ("joint1",)
    assert robot.root_link == "world"

    joint1 = robot.joint("joint1")
    assert joint1.type == "prismatic"
    assert (joint1.parent, joint1.child) == ("link1", "link2")
    assert joint1.axis == (0.0, 0.0, 1.0)
    assert joint1.origin.xyz == (0.0, 0.0, 1.0)
    assert (joint1.limits.lower, joint1.limits.upper) == (-1.0, 0.0)
    assert joint1.limits.effort == 1000.0
    assert joint1.limits.velocity == 100.0
    assert joint1.damping == 10.0

    (tr,) = robot.transmissions
    assert tr.joint == "joint1"
    assert tr.hardware_interfaces == ("EffortJointInterface",)
    assert tr.mechanical_reduction == 1.0
    assert robot.transmission_for("joint1") is tr

    (sensor,) = robot.sensors
    assert sensor.kind == "force_torque"
    assert sensor.joint == "ft_sensor_jnt"
    assert sensor.link == "ft_sensor_link"
    assert sensor.topic == "ft_sensor_topic"
    assert sensor.update_rate_hz == 1000.0


def test_one_dof_masses_from_the_xacro_macro() -> None:
    robot = load_robot_model(ONE_DOF_XACRO)
    assert robot.link("link1").inertial.mass_kg == 1.0
    assert robot.link("link2").inertial.mass_kg == 1.0
    disk = robot.link("ft_sensor_link").inertial
    assert disk.mass_kg == pytest.approx(0.01, abs=1e-15)
    # solid cylinder r = 0.05, h = 0.005: ixx = m (3 r^2 + h^2) / 12, izz = m r^2 / 2
    ixx = 0.01 * (3 * 0.05**2 + 0.005**2) / 12
    assert disk.inertia[0] == pytest.approx(ixx, rel=1e-12)
    assert disk.inertia[1] == pytest.approx(ixx, rel=1e-12)
    assert disk.inertia[2] == pytest.approx(0.01 * 0.05**2 / 2, rel=1e-12)
    # the disk sits on the piston: its centre half a thickness above the sensor frame
    assert disk.origin.xyz == pytest.approx((0.0, 0.0, 0.0025), abs=1e-15)


def test_expand_xacro_gives_urdf_text() -> None:
    text = expand_xacro(ONE_DOF_XACRO, PackageResolver(), {})
    assert "<robot" in text and 'name="one_DOF_robot"' in text
    assert "xacro:" not in text.replace(XACRO_NS, "")
    assert "${" not in text


# -- plain URDF files, missing files, xacro errors ----------------------------


def test_plain_urdf_file(tmp_path: Path) -> None:
    path = tmp_path / "r.urdf"
    path.write_text('<robot name="plain"><link name="only"/></robot>')
    robot = load_robot_model(path)
    assert robot.name == "plain"
    assert robot.source == str(path)


def test_urdf_file_is_not_run_through_xacro(tmp_path: Path) -> None:
    path = tmp_path / "r.urdf"
    path.write_text(f'<robot name="${{n}}" {XACRO_NS}><link name="only"/></robot>')
    assert load_robot_model(path).name == "${n}"


def test_missing_file_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "absent.urdf"
    with pytest.raises(ModelError) as info:
        load_robot_model(path)
    assert info.value.source == str(path)
    assert str(path) in str(info.value)
    assert "not found" in str(info.value)


def test_directory_is_not_a_description(tmp_path: Path) -> None:
    with pytest.raises(ModelError) as info:
        load_robot_model(tmp_path)
    assert str(tmp_path) in str(info.value)


def test_parser_errors_name_the_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.urdf"
    path.write_text('<robot name="r"><link name="a"/><link name="a"/></robot>')
    with pytest.raises(ModelError) as info:
        load_robot_model(path)
    assert info.value.source == str(path)
    assert str(info.value).startswith(str(path))
    assert "'a'" in str(info.value)


def test_xacro_undefined_property_names_file_and_property(tmp_path: Path) -> None:
    path = tmp_path / "undefined.xacro"
    path.write_text(f'<robot name="r" {XACRO_NS}><link name="${{no_such_property}}"/></robot>')
    with pytest.raises(ModelError) as info:
        load_robot_model(path)
    assert info.value.source == str(path)
    assert str(info.value).startswith(str(path))
    assert "no_such_property" in str(info.value)


def test_xacro_malformed_xml_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "broken.xacro"
    path.write_text(f'<robot name="r" {XACRO_NS}><link name="a"></robot>')
    with pytest.raises(ModelError) as info:
        load_robot_model(path)
    assert info.value.source == str(path)
    assert "xacro" in str(info.value)


def test_xacro_output_is_validated_with_the_file_as_source(tmp_path: Path) -> None:
    path = tmp_path / "neg.xacro"
    path.write_text(
        f'<robot name="r" {XACRO_NS}><xacro:property name="m" value="-1"/>'
        '<link name="a"><inertial><mass value="${m}"/><inertia ixx="1" iyy="1" izz="1"/></inertial></link>'
        "</robot>"
    )
    with pytest.raises(ModelError) as info:
        load_robot_model(path)
    assert info.value.source == str(path)
    assert "link[a].inertial.mass" in str(info.value)


def test_xacro_args(tmp_path: Path) -> None:
    path = tmp_path / "args.xacro"
    path.write_text(
        f'<robot name="r" {XACRO_NS}><xacro:arg name="mass" default="1.5"/>'
        '<link name="a"><inertial><mass value="$(arg mass)"/><inertia ixx="1" iyy="1" izz="1"/></inertial>'
        "</link></robot>"
    )
    assert load_robot_model(path).link("a").inertial.mass_kg == 1.5
    assert load_robot_model(path, xacro_args={"mass": "2.5"}).link("a").inertial.mass_kg == 2.5


def test_a_failed_xacro_run_does_not_break_the_next(tmp_path: Path) -> None:
    bad = tmp_path / "bad.xacro"
    bad.write_text(f'<robot name="r" {XACRO_NS}><link name="$(find no_such_pkg_x)"/></robot>')
    with pytest.raises(ModelError):
        load_robot_model(bad)
    assert load_robot_model(ONE_DOF_XACRO).name == "one_DOF_robot"


# -- $(find pkg) and package:// ------------------------------------------------


def test_find_and_package_uri_through_search_path(workspace: Path, top_xacro: Path) -> None:
    robot = load_robot_model(top_xacro, search_path=[workspace])
    mesh = robot.link("base").visuals[0].geometry
    expected = workspace / "src_dir" / "meshes" / "part.stl"
    assert Path(mesh.mesh_path) == expected
    assert Path(mesh.mesh_path).is_absolute()


def test_find_and_package_uri_through_environment(
    workspace: Path, top_xacro: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("JOINTCTL_PACKAGE_PATH", os.pathsep.join([str(tmp_path / "nothing_here"), str(workspace)]))
    robot = load_robot_model(top_xacro)
    assert Path(robot.link("base").visuals[0].geometry.mesh_path) == workspace / "src_dir" / "meshes" / "part.stl"


def test_find_through_ros_package_path(workspace: Path, top_xacro: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(workspace))
    robot = load_robot_model(top_xacro)
    assert Path(robot.link("base").visuals[0].geometry.mesh_path).parent == workspace / "src_dir" / "meshes"


def test_missing_package_in_find_is_named(top_xacro: Path) -> None:
    with pytest.raises(ModelError) as info:
        load_robot_model(top_xacro)  # my_pkg is on no search path
    assert info.value.source == str(top_xacro)
    assert "my_pkg" in str(info.value)
    assert "not found" in str(info.value)


def test_missing_package_in_find_keeps_the_resolver_error(top_xacro: Path) -> None:
    with pytest.raises(ModelError) as info:
        load_robot_model(top_xacro)
    assert info.value.field == "$(find)"
    assert info.value.value == "my_pkg"
    assert str(info.value).count("not found") == 1


def test_missing_package_in_mesh_uri_is_named(tmp_path: Path) -> None:
    path = tmp_path / "r.urdf"
    path.write_text(
        '<robot name="r"><link name="a"><visual><geometry>'
        '<mesh filename="package://absent_pkg/meshes/a.stl"/></geometry></visual></link></robot>'
    )
    with pytest.raises(ModelError) as info:
        load_robot_model(path)
    assert "absent_pkg" in str(info.value)
    assert info.value.value == "absent_pkg"


def test_missing_mesh_file_in_existing_package(workspace: Path, tmp_path: Path) -> None:
    path = tmp_path / "r.urdf"
    path.write_text(
        '<robot name="r"><link name="a"><collision><geometry>'
        '<mesh filename="package://my_pkg/meshes/absent.stl"/></geometry></collision></link></robot>'
    )
    with pytest.raises(ModelError) as info:
        load_robot_model(path, search_path=[workspace])
    error = info.value
    assert error.source == str(path)
    assert error.field == "link[a].collision"
    assert error.value == "package://my_pkg/meshes/absent.stl"
    assert "mesh file not found" in str(error)


def test_relative_and_file_mesh_paths(tmp_path: Path) -> None:
    (tmp_path / "meshes").mkdir()
    rel = tmp_path / "meshes" / "rel.stl"
    rel.write_text("solid x\nendsolid x\n")
    absolute = tmp_path / "abs.stl"
    absolute.write_text("solid y\nendsolid y\n")
    path = tmp_path / "r.urdf"
    path.write_text(
        '<robot name="r"><link name="a">'
        '<visual><geometry><mesh filename="meshes/rel.stl"/></geometry></visual>'
        f'<collision><geometry><mesh filename="file://{absolute}"/></geometry></collision>'
        "</link></robot>"
    )
    link = load_robot_model(path).link("a")
    assert Path(link.visuals[0].geometry.mesh_path) == rel
    assert Path(link.collisions[0].geometry.mesh_path) == absolute


# -- PackageResolver -----------------------------------------------------------


def test_resolver_finds_by_manifest_name_not_folder_name(workspace: Path) -> None:
    resolver = PackageResolver([workspace])
    assert resolver.find("my_pkg") == workspace / "src_dir"
    with pytest.raises(ModelError):
        resolver.find("src_dir_that_is_not_there")


def test_resolver_root_may_be_the_package_itself(workspace: Path) -> None:
    assert PackageResolver([workspace / "src_dir"]).find("my_pkg") == workspace / "src_dir"


def test_resolver_falls_back_to_folder_name(tmp_path: Path) -> None:
    make_package(tmp_path, "bare_pkg", None)
    assert PackageResolver([tmp_path]).find("bare_pkg") == tmp_path / "bare_pkg"


def test_resolver_reads_a_manifest_that_is_not_well_formed(tmp_path: Path) -> None:
    pkg = make_package(tmp_path, "folder", None)
    (pkg / "package.xml").write_text("<package><name> sloppy_pkg </name><broken></package>")
    assert PackageResolver([tmp_path]).find("sloppy_pkg") == pkg


def test_resolver_order_explicit_then_env_then_builtin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    first = make_package(tmp_path / "first", "a", "one_dof")
    second = make_package(tmp_path / "second", "b", "one_dof")
    monkeypatch.setenv("JOINTCTL_PACKAGE_PATH", str(tmp_path / "second"))
    assert PackageResolver([tmp_path / "first"]).find("one_dof") == first
    assert PackageResolver().find("one_dof") == second
    monkeypatch.delenv("JOINTCTL_PACKAGE_PATH")
    assert PackageResolver().find("one_dof") == robots_dir() / "one_dof"
    roots = PackageResolver([tmp_path / "first"]).roots
    assert roots[0] == tmp_path / "first"
    assert roots[-1] == robots_dir()


def test_resolver_missing_package_error(tmp_path: Path) -> None:
    resolver = PackageResolver([tmp_path])
    with pytest.raises(ModelError) as info:
        resolver.find("ghost_pkg")
    error = info.value
    assert error.field == "$(find)"
    assert error.value == "ghost_pkg"
    assert "ghost_pkg" in str(error)
    assert str(tmp_path) in str(error)  # the searched folders are listed
    assert "JOINTCTL_PACKAGE_PATH" in str(error)


def test_resolve_uri(workspace: Path, tmp_path: Path) -> None:
    resolver = PackageResolver([workspace])
    assert resolver.resolve_uri("package://my_pkg/meshes/part.stl") == workspace / "src_dir" / "meshes" / "part.stl"
    assert resolver.resolve_uri("file:///abs/x.stl") == Path("/abs/x.stl")
    assert resolver.resolve_uri("rel/x.stl", tmp_path) == tmp_path / "rel" / "x.stl"
    assert resolver.resolve_uri("rel/x.stl") == Path("rel/x.stl")
    assert resolver.resolve_uri("/abs/y.stl", tmp_path) == Path("/abs/y.stl")
    with pytest.raises(ModelError) as info:
        resolver.resolve_uri("package://nope_pkg/x.stl")
    assert info.value.value == "nope_pkg"


def test_find_in_xacro_of_the_builtin_package(tmp_path: Path) -> None:
    path = tmp_path / "wrap.xacro"
    path.write_text(
        f'<robot name="wrapped" {XACRO_NS}>'
        '<link name="$(find one_dof)"/></robot>'
    )
    robot = load_robot_model(path)
    assert Path(robot.links[0].name) == robots_dir() / "one_dof"

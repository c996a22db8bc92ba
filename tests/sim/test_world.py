"""Tests of MujocoWorld: compiling, initial positions, reset and name lookups."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from jointctl.errors import ConfigError, ModelError
from jointctl.model import load_robot_model
from jointctl.model.urdf_parser import parse_urdf
from jointctl.paths import robots_dir
from jointctl.sim import MujocoWorld, WorldSettings

ONE_DOF_XACRO = robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro"


@pytest.fixture(scope="module")
def one_dof():
    return load_robot_model(ONE_DOF_XACRO)


def sensor_site_z(world: MujocoWorld) -> float:
    return float(world.data.site_xpos[world.site_id("ft_sensor")][2])


def test_initial_position_sets_qpos_and_the_sensor_height(one_dof) -> None:
    world = MujocoWorld(one_dof, initial_positions={"joint1": -0.5})
    assert world.joint_names == ("joint1",)
    assert world.data.qpos[world.qpos_adr[0]] == -0.5
    assert world.initial_positions == {"joint1": -0.5}
    # base 1 m + joint1 (-0.5) + piston 1 m: the top of the disk at 1.5 m
    assert sensor_site_z(world) == pytest.approx(1.5, abs=1e-9)
    assert world.data.site_xpos[world.site_id("ft_sensor")][:2] == pytest.approx([0.0, 0.0], abs=1e-12)


def test_default_initial_position_is_zero(one_dof) -> None:
    world = MujocoWorld(one_dof)
    assert world.data.qpos[0] == 0.0
    assert sensor_site_z(world) == pytest.approx(2.0, abs=1e-9)
    assert world.time_s == 0.0


@pytest.mark.parametrize("value", [-1, 0, -0.25])
def test_integers_and_limits_themselves_are_accepted(one_dof, value) -> None:
    world = MujocoWorld(one_dof, initial_positions={"joint1": value})
    assert world.initial_positions["joint1"] == float(value)
    assert isinstance(world.initial_positions["joint1"], float)
    assert sensor_site_z(world) == pytest.approx(2.0 + value, abs=1e-9)


@pytest.mark.parametrize(
    ("positions", "field", "fragment"),
    [
        ({"joint9": -0.5}, "initial_positions.joint9", "'joint9'"),
        ({"ft_sensor_jnt": 0.0}, "initial_positions.ft_sensor_jnt", "'ft_sensor_jnt'"),
        ({"joint1": math.nan}, "initial_positions.joint1", "nan"),
        ({"joint1": math.inf}, "initial_positions.joint1", "inf"),
        ({"joint1": -math.inf}, "initial_positions.joint1", "-inf"),
        ({"joint1": "-0.5"}, "initial_positions.joint1", "'-0.5'"),
        ({"joint1": None}, "initial_positions.joint1", "None"),
        ({"joint1": True}, "initial_positions.joint1", "True"),
        ({"joint1": 0.5}, "initial_positions.joint1", "0.5"),
        ({"joint1": -1.0001}, "initial_positions.joint1", "-1.0001"),
    ],
)
def test_bad_initial_positions(one_dof, positions, field: str, fragment: str) -> None:
    with pytest.raises(ConfigError) as info:
        MujocoWorld(one_dof, initial_positions=positions, source="scenario.yaml")
    error = info.value
    assert error.code == "config"
    assert error.field == field
    assert error.source == "scenario.yaml"
    assert field in str(error)
    assert fragment in str(error)
    assert str(error).startswith("scenario.yaml")


def test_out_of_limits_message_gives_the_limits(one_dof) -> None:
    with pytest.raises(ConfigError) as info:
        MujocoWorld(one_dof, initial_positions={"joint1": 0.5})
    assert "[-1.0, 0.0]" in str(info.value)


def test_reset_restores_time_and_initial_state(one_dof) -> None:
    world = MujocoWorld(one_dof, initial_positions={"joint1": -0.5})
    d = world.data
    before_qpos = d.qpos.copy()
    before_site = d.site_xpos.copy()
    before_sensor = d.sensordata.copy()
    d.ctrl[0] = 200.0
    for _ in range(100):
        world.step()
    assert world.time_s == pytest.approx(0.1, abs=1e-12)
    assert abs(d.qpos[0] - before_qpos[0]) > 1e-3
    assert abs(d.qvel[0]) > 1e-3
    world.reset()
    assert world.time_s == 0.0
    assert np.array_equal(d.qpos, before_qpos)
    assert np.all(d.qvel == 0.0)
    assert np.all(d.ctrl == 0.0)
    assert np.allclose(d.site_xpos, before_site, atol=1e-12)  # forward kinematics were recomputed
    assert np.allclose(d.sensordata, before_sensor, atol=1e-9)


def test_settings_are_used(one_dof) -> None:
    world = MujocoWorld(one_dof, WorldSettings(timestep_s=0.002, gravity_m_s2=(0.0, 0.0, -5.0), floor=False))
    assert world.timestep_s == 0.002
    assert isinstance(world.timestep_s, float)
    assert world.model.opt.gravity == pytest.approx([0.0, 0.0, -5.0], abs=0)
    world.step()
    assert world.time_s == pytest.approx(0.002, abs=1e-15)


def test_free_fall_from_theory(one_dof) -> None:
    """No command: m x'' = -m g - c x' with m = 1.01 kg (piston and disk), c = 10 N s/m."""
    world = MujocoWorld(one_dof, WorldSettings(floor=False), initial_positions={"joint1": -0.2})
    mass, c, g, t = 1.01, 10.0, 9.81, 0.2
    for _ in range(200):
        world.step()
    tau = mass / c
    v_expected = -(mass * g / c) * (1.0 - math.exp(-t / tau))
    x_expected = -0.2 - (mass * g / c) * (t - tau * (1.0 - math.exp(-t / tau)))
    # first-order integrator at 1 ms: relative error of order dt / tau ~ 1 %
    assert world.data.qvel[0] == pytest.approx(v_expected, rel=2e-2)
    assert world.data.qpos[0] == pytest.approx(x_expected, abs=2e-3)


def test_addresses_and_sensor_lookup(one_dof) -> None:
    world = MujocoWorld(one_dof)
    assert list(world.qpos_adr) == [0]
    assert list(world.dof_adr) == [0]
    assert list(world.actuator_ids) == [0]
    force, torque = world.sensor_adr("ft_sensor")
    assert (force, torque) == (0, 3)
    assert world.site_id("ft_sensor") >= 0
    assert world.site_id("nope") == -1
    with pytest.raises(ConfigError) as info:
        world.sensor_adr("nope")
    assert info.value.field == "sensor"
    assert "'nope'" in str(info.value)


def test_contiguous(one_dof) -> None:
    world = MujocoWorld(one_dof)
    assert world.contiguous(np.array([2, 3, 4])) == slice(2, 5)
    assert world.contiguous(np.array([1, 0])) is None
    assert world.contiguous(np.array([0, 2])) is None
    assert world.contiguous(np.array([], dtype=int)) is None


TWO_JOINTS = """<robot name="two">
  <link name="world"/>
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"/></inertial></link>
  <link name="b"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"/></inertial></link>
  <!-- document order: the deeper joint first, so it differs from MuJoCo's tree order -->
  <joint name="jb" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="5" velocity="1"/></joint>
  <joint name="ja" type="prismatic"><parent link="world"/><child link="a"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="50" velocity="1"/></joint>
  <transmission name="t"><joint name="jb"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
  </transmission>
</robot>"""


def test_joint_order_is_document_order_with_mapped_addresses() -> None:
    world = MujocoWorld(parse_urdf(TWO_JOINTS), initial_positions={"jb": 0.7, "ja": -0.3})
    assert world.joint_names == ("jb", "ja")
    m = world.model
    for k, name in enumerate(world.joint_names):
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        assert world.qpos_adr[k] == m.jnt_qposadr[jid]
        assert world.dof_adr[k] == m.jnt_dofadr[jid]
    assert world.data.qpos[world.qpos_adr[0]] == 0.7
    assert world.data.qpos[world.qpos_adr[1]] == -0.3
    assert list(world.actuator_ids) == [0, -1]  # ja has no transmission
    assert world.contiguous(world.qpos_adr) is None


def test_model_mujoco_refuses_becomes_model_error() -> None:
    massless = """<robot name="r"><link name="world"/><link name="a"/>
      <joint name="j" type="prismatic"><parent link="world"/><child link="a"/><axis xyz="0 0 1"/>
      <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"""
    with pytest.raises(ModelError) as info:
        MujocoWorld(parse_urdf(massless, source="massless.urdf"))
    assert info.value.source == "massless.urdf"
    assert "MuJoCo" in str(info.value)


def test_gravity_can_change_and_survives_a_spawn_and_spawned_objects_can_be_removed():
    from jointctl.sim.objects import ObjectSpec

    robot = load_robot_model(ONE_DOF_XACRO)
    world = MujocoWorld(robot, initial_positions={"joint1": -0.5})
    world.set_gravity((0.0, 0.0, -5.0))
    assert world.gravity_m_s2 == (0.0, 0.0, -5.0)
    weight = ObjectSpec("weight", "sphere", (0.05,), 1.0, (0.0, 0.0, 2.0))
    world.spawn(weight)
    assert world.gravity_m_s2 == (0.0, 0.0, -5.0)  # the recompiled model keeps it
    for _ in range(100):
        world.step()
    position, _ = world.body_pose("weight")
    assert position[2] == pytest.approx(2.0 - 0.5 * 5.0 * 0.1 ** 2, abs=2e-3)  # falls at 5 m/s²
    rebuilt = []
    world.on_rebuild(lambda: rebuilt.append(True))
    world.remove_spawned()
    assert not world.has_body("weight") and world.spawned == [] and rebuilt == [True]
    world.reset()
    assert world.data.qpos[world.qpos_adr[0]] == pytest.approx(-0.5)
    world.spawn(weight)  # the same name may come again
    with pytest.raises(ConfigError, match="three finite numbers"):
        world.set_gravity((0.0, 0.0, float("nan")))


def _state(world: MujocoWorld) -> dict:
    """Every field of the world's MjData that a step reads or writes (MuJoCo's state, derived quantities and
    warning counters)."""
    d = world.data
    fields = ("qpos", "qvel", "act", "ctrl", "qacc", "qacc_warmstart", "qfrc_applied", "xfrc_applied", "xpos",
              "site_xpos", "sensordata", "actuator_force", "qfrc_bias")
    return {"time": d.time, **{name: getattr(d, name).copy() for name in fields},
            "warnings": [d.warning[k].number for k in range(len(d.warning))]}


def test_a_restarted_world_is_in_the_state_a_new_world_starts_in(one_dof) -> None:
    # A run left the world moving, its controls set and a warning counted; a restart at another pose is the new
    # world built at that pose, to the last bit (mj_resetData zeroes MjData whole, then the pose is set).
    world = MujocoWorld(one_dof, initial_positions={"joint1": -0.5})
    world.data.ctrl[0] = 300.0
    for _ in range(200):
        world.step()
    world.data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number = 3
    world.on_rebuild(lambda: None)
    world.restart({"joint1": -0.2})
    fresh = MujocoWorld(one_dof, initial_positions={"joint1": -0.2})
    before, expected = _state(world), _state(fresh)
    assert before["time"] == 0.0 and before["warnings"] == expected["warnings"]
    for name, value in expected.items():
        assert np.array_equal(before[name], value), name
    assert world.initial_positions == {"joint1": -0.2} and world._rebuild_listeners == []
    for w in (world, fresh):  # and it runs the same
        w.data.ctrl[0] = 150.0
        for _ in range(300):
            w.step()
    after, expected = _state(world), _state(fresh)
    for name, value in expected.items():
        assert np.array_equal(after[name], value), name


def test_a_restart_checks_the_pose_and_refuses_a_changed_model(one_dof) -> None:
    from jointctl.sim.objects import ObjectSpec

    world = MujocoWorld(one_dof)
    with pytest.raises(ConfigError, match="outside the joint's limits"):
        world.restart({"joint1": 5.0})
    world.set_gravity((0.0, 0.0, -1.0))
    assert not world.is_as_built()
    with pytest.raises(RuntimeError, match="changed since it was built"):
        world.restart()
    world.set_gravity((0.0, 0.0, -9.81))
    assert world.is_as_built()
    world.spawn(ObjectSpec("weight", "box", (0.05, 0.05, 0.05), 1.0, (0.0, 0.0, 2.0)))
    world.remove_spawned()  # recompiled: the model is no longer the one built
    assert not world.is_as_built()

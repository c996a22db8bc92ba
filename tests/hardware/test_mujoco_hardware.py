"""Tests of MujocoHardware: the hardware contract on the 1-DOF robot, with physics checked against theory."""

from __future__ import annotations

import math

import pytest

from jointctl.errors import ConfigError
from jointctl.hardware import EFFORT, HardwareInterface, MujocoHardware
from jointctl.model import load_robot_model
from jointctl.model.urdf_parser import parse_urdf
from jointctl.paths import robots_dir
from jointctl.sim import MujocoWorld, WorldSettings

ONE_DOF_XACRO = robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro"
G = 9.81
MOVING_KG = 1.01  # piston 1 kg + sensor disk 0.01 kg
DISK_KG = 0.01
KP = 400.0
TARGET = -0.5


@pytest.fixture(scope="module")
def one_dof():
    return load_robot_model(ONE_DOF_XACRO)


@pytest.fixture
def hw(one_dof) -> MujocoHardware:
    world = MujocoWorld(one_dof, WorldSettings(timestep_s=0.001, gravity_m_s2=(0.0, 0.0, -G)),
                        initial_positions={"joint1": TARGET})
    return MujocoHardware(world)


def run_p_law(hw: MujocoHardware, seconds: float, period: float = 0.001) -> None:
    i = hw.joint_index("joint1")
    cmd = hw.command_buffer(EFFORT)
    for _ in range(round(seconds / period)):
        hw.read()
        cmd[i] = KP * (TARGET - hw.position[i])
        hw.write()
        hw.advance(period)
    hw.read()


def test_is_a_hardware_interface(hw: MujocoHardware) -> None:
    assert isinstance(hw, HardwareInterface)
    assert hw.joint_names == ("joint1",)
    assert hw.sensor_names == ("ft_sensor",)


def test_read_gives_python_float_lists(hw: MujocoHardware) -> None:
    hw.read()
    for values in (hw.position, hw.velocity, hw.effort, hw.wrenches["ft_sensor"]):
        assert type(values) is list
        assert all(type(v) is float for v in values)
    assert len(hw.position) == len(hw.velocity) == len(hw.effort) == 1
    assert len(hw.wrenches["ft_sensor"]) == 6
    assert hw.position == [TARGET]
    assert hw.velocity == [0.0]


def test_p_law_settles_at_the_static_deflection(hw: MujocoHardware) -> None:
    """Kp (x* - x) = m g  =>  x = x* - m g / Kp; the effort holds the weight of piston and disk."""
    run_p_law(hw, 3.0)
    assert hw.world.time_s == pytest.approx(3.0, abs=1e-9)
    assert hw.position[0] == pytest.approx(TARGET - MOVING_KG * G / KP, abs=1e-4)
    assert hw.effort[0] == pytest.approx(MOVING_KG * G, abs=1e-3)
    assert hw.velocity[0] == pytest.approx(0.0, abs=1e-4)


def test_force_sensor_reads_the_resting_disk_negative(hw: MujocoHardware) -> None:
    """The disk's weight rests on the sensor: force z = -(0.01 kg * g) (chapter sign), the rest ~0."""
    run_p_law(hw, 3.0)
    fx, fy, fz, tx, ty, tz = hw.wrenches["ft_sensor"]
    assert fz == pytest.approx(-DISK_KG * G, abs=1e-4)
    assert (fx, fy) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert (tx, ty, tz) == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


def test_wrench_list_is_updated_in_place(hw: MujocoHardware) -> None:
    wrench = hw.wrenches["ft_sensor"]
    run_p_law(hw, 0.5)
    assert hw.wrenches["ft_sensor"] is wrench
    assert wrench[2] < 0.0


def test_weight_compensation_holds_still(hw: MujocoHardware) -> None:
    """An effort equal to the weight leaves the piston at rest (no spring, damping only)."""
    hw.command_buffer(EFFORT)[0] = MOVING_KG * G
    hw.write()
    for _ in range(1000):
        hw.advance(0.001)
    hw.read()
    assert hw.position[0] == pytest.approx(TARGET, abs=1e-9)
    assert hw.effort[0] == pytest.approx(MOVING_KG * G, abs=1e-12)


def test_effort_is_applied_as_a_force(hw: MujocoHardware) -> None:
    """A constant net force F - m g on m with damping c: v(t) = (F - m g)/c (1 - exp(-c t / m))."""
    force, c, t = 30.0, 10.0, 0.1
    hw.command_buffer(EFFORT)[0] = force
    hw.write()
    for _ in range(100):
        hw.advance(0.001)
    hw.read()
    expected = (force - MOVING_KG * G) / c * (1 - math.exp(-c * t / MOVING_KG))
    assert hw.velocity[0] == pytest.approx(expected, rel=2e-2)  # first-order integrator, dt / tau ~ 1 %
    assert hw.effort[0] == force


def test_advance_takes_whole_physics_steps(hw: MujocoHardware) -> None:
    hw.advance(0.002)
    assert hw.world.time_s == pytest.approx(0.002, abs=1e-12)
    hw.advance(0.002)
    assert hw.world.time_s == pytest.approx(0.004, abs=1e-12)
    hw.advance(0.001)
    assert hw.world.time_s == pytest.approx(0.005, abs=1e-12)
    hw.advance(0.005)
    assert hw.world.time_s == pytest.approx(0.010, abs=1e-12)


@pytest.mark.parametrize("period", [0.0015, 0.0005, 0.0, -0.001])
def test_period_that_is_not_a_whole_number_of_steps_is_refused(hw: MujocoHardware, period: float) -> None:
    with pytest.raises(ConfigError) as info:
        hw.advance(period)
    assert info.value.field == "period_s"
    assert info.value.value == period
    assert "period_s" in str(info.value)
    assert hw.world.time_s == 0.0
    hw.advance(0.001)  # still usable afterwards, with the old period
    assert hw.world.time_s == pytest.approx(0.001, abs=1e-12)


def test_command_interfaces(hw: MujocoHardware) -> None:
    assert hw.command_interfaces("joint1") == {"effort"}
    assert hw.command_interfaces("ft_sensor_jnt") == frozenset()


def test_joint_index(hw: MujocoHardware) -> None:
    assert hw.joint_index("joint1") == 0
    with pytest.raises(ConfigError) as info:
        hw.joint_index("joint7", source="ctl.yaml", field="one_DOF_robot.ctl.joint")
    error = info.value
    assert error.value == "joint7"
    assert error.field == "one_DOF_robot.ctl.joint"
    assert error.source == "ctl.yaml"
    assert "'joint7'" in str(error)
    assert "joint1" in str(error)  # the known joints are listed
    with pytest.raises(ConfigError) as info:
        hw.joint_index("nope")
    assert info.value.field == "joint"


@pytest.mark.parametrize(("command", "expected"), [(5000.0, 1000.0), (-5000.0, -1000.0), (999.0, 999.0)])
def test_effort_saturates_at_the_force_range(hw: MujocoHardware, command: float, expected: float) -> None:
    hw.command_buffer(EFFORT)[0] = command
    hw.write()
    hw.advance(0.001)
    hw.read()
    assert hw.effort[0] == expected


def test_command_buffer_is_one_list_per_interface(hw: MujocoHardware) -> None:
    buf = hw.command_buffer(EFFORT)
    assert buf is hw.command_buffer(EFFORT)
    assert buf == [0.0]
    assert hw.command_buffer("velocity") is not buf


def test_write_sends_the_buffer_only_on_write(hw: MujocoHardware) -> None:
    hw.command_buffer(EFFORT)[0] = 12.5
    assert hw.world.data.ctrl[0] == 0.0
    hw.write()
    assert hw.world.data.ctrl[0] == 12.5


def test_reset_restores_state_and_zeroes_commands(hw: MujocoHardware) -> None:
    buf = hw.command_buffer(EFFORT)
    buf[0] = 300.0
    hw.write()
    for _ in range(50):
        hw.advance(0.001)
    hw.read()
    assert hw.position[0] > TARGET + 1e-3
    hw.reset()
    assert hw.world.time_s == 0.0
    assert hw.position == [TARGET]
    assert hw.velocity == [0.0]
    assert buf == [0.0]
    assert hw.command_buffer(EFFORT) is buf
    hw.write()
    assert hw.world.data.ctrl[0] == 0.0


TWO_JOINTS = """<robot name="two">
  <link name="world"/>
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"/></inertial></link>
  <link name="b"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"/></inertial></link>
  <link name="c"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"/></inertial></link>
  <joint name="jc" type="prismatic"><parent link="b"/><child link="c"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="100" velocity="1"/></joint>
  <joint name="ja" type="prismatic"><parent link="world"/><child link="a"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="100" velocity="1"/></joint>
  <joint name="jb" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="100" velocity="1"/></joint>
  <transmission name="tb"><joint name="jb"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
  </transmission>
  <transmission name="tc"><joint name="jc"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
  </transmission>
</robot>"""


def test_mixed_actuation_and_non_contiguous_addresses() -> None:
    """Joints in document order (jc, ja, jb) differ from MuJoCo's tree order (ja, jb, jc); ja has no motor."""
    world = MujocoWorld(parse_urdf(TWO_JOINTS), WorldSettings(gravity_m_s2=(0.0, 0.0, 0.0), floor=False),
                        initial_positions={"jc": 0.3, "ja": -0.2, "jb": 0.1})
    hw = MujocoHardware(world)
    assert hw.joint_names == ("jc", "ja", "jb")
    hw.read()
    assert hw.position == [0.3, -0.2, 0.1]
    assert hw.command_interfaces("ja") == frozenset()
    assert hw.command_interfaces("jb") == {"effort"}
    assert hw.command_interfaces("jc") == {"effort"}
    cmd = hw.command_buffer(EFFORT)
    cmd[:] = [7.0, 99.0, -3.0]  # the 99 on the unactuated ja must go nowhere
    hw.write()
    hw.advance(0.001)
    hw.read()
    assert hw.effort == [7.0, 0.0, -3.0]
    assert all(type(v) is float for v in hw.effort + hw.position + hw.velocity)
    # orthogonal slides: the mass matrix is diag(3, 2, 1) kg for (ja, jb, jc); no gravity, no damping,
    # so one 1 ms step gives v = F / m * dt to each joint
    assert hw.velocity[0] == pytest.approx(7.0 / 1.0 * 0.001, rel=1e-9)
    assert hw.velocity[1] == pytest.approx(0.0, abs=1e-15)
    assert hw.velocity[2] == pytest.approx(-3.0 / 2.0 * 0.001, rel=1e-9)


def test_the_simulation_door_spawns_and_reports_a_falling_body_against_free_fall(hw):
    from jointctl.sim.objects import object_from_config

    door = hw.simulation
    assert door is not None and door.gravity_m_s2 == (0.0, 0.0, -G) and door.floor
    weight = object_from_config({"name": "ball", "shape": "sphere", "radius_m": 0.05, "mass_kg": 1.0,
                                 "xyz": [1.0, 1.0, 3.0]}, field="objects[0]", source=None, floor=True)
    door.spawn(weight)
    assert [o.name for o in door.spawned] == ["ball"] and door.has_body("ball")
    steps = 300
    for _ in range(steps):
        hw.advance(0.001)
    t = steps * 0.001
    position, quaternion, angular, linear = door.body_state("ball")
    # Free fall from rest, to within one 1 ms step of it (where in the step the spawn lands).
    assert linear == pytest.approx([0.0, 0.0, -G * t], abs=G * 0.001 + 1e-9)
    assert position[2] == pytest.approx(3.0 - 0.5 * G * t * t, abs=G * t * 0.001)
    assert quaternion == pytest.approx([1.0, 0.0, 0.0, 0.0]) and angular == pytest.approx([0.0, 0.0, 0.0])
    door.set_gravity((0.0, 0.0, 0.0))
    assert door.gravity_m_s2 == (0.0, 0.0, 0.0)
    assert door.remove("ball").name == "ball" and not door.has_body("ball")


def test_hardware_without_a_simulation_has_no_door():
    from tests.control.conftest import FakeHardware

    assert FakeHardware().simulation is None

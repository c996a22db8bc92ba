"""AdmittanceController: one cycle's arithmetic, sampling, refusals, chaining, and the statics.

Theory (chapter 11.4): each cycle ``f = K (x_att - x) - B v + F``, ``v_ref += f / M dt``
clamped to ±max_velocity, handed to the velocity controller. At rest f = 0, so
``x = x_att + F / K``; with the sensor's sign convention (a load on the disk reads negative
force z) the disk's own 0.01 kg under 9.8 m/s² moves it 0.098 mm below the attractor with
K = 1000 N/m and a resting 10 kg weight 98.1 mm. Holding signals between samples (the chapter's
node reads 50 Hz joint states and 1 kHz force) changes none of that: at rest the held samples equal
the state, so f = 0 gives the same point.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import pytest
import yaml

from jointctl.control import (
    AdmittanceController,
    ControllerManager,
    JointPositionController,
    JointVelocityController,
)
from jointctl.control.registry import controller_types
from jointctl.control.controller import Controller
from jointctl.errors import ConfigError, ControllerError, InvalidCommand
from jointctl.hardware.interface import EFFORT
from jointctl.model import load_robot_model
from jointctl.paths import robots_dir
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario

from .conftest import NAMESPACE, POSITION_YAML, FakeHardware

NAC_YAML = robots_dir() / "one_dof" / "config" / "one_dof_nac_params.yaml"
JSC = "joint_state_controller"
POS = "joint1_position_controller"
VEL = "joint1_velocity_controller"
NAC = "joint1_admittance_controller"
NAC_FIELD = f"{NAMESPACE}.{NAC}"
DT = 0.001
KV = 200.0  # the velocity controller's p gain in the chapter's file


class SensorHardware(FakeHardware):
    """The fake hardware of the control tests with a force-torque sensor whose wrench is settable."""

    def __init__(self, joint_names=("joint1",), sensor_names=("ft_sensor",)) -> None:
        super().__init__(joint_names)
        self.sensor_names = tuple(sensor_names)
        self.wrenches = {s: [0.0] * 6 for s in self.sensor_names}

    def set_wrench(self, sensor: str, values) -> None:
        self.wrenches[sensor][:] = [float(v) for v in values]  # in place: controllers hold the list


def definitions(**nac_changes) -> dict:
    """The chapter's NAC file plus the position controller; ``None`` removes an NAC key."""
    tree = yaml.safe_load(NAC_YAML.read_text())
    controllers = copy.deepcopy(tree[NAMESPACE])
    controllers[POS] = yaml.safe_load(POSITION_YAML.read_text())[NAMESPACE][POS]
    for key, value in nac_changes.items():
        if value is None:
            controllers[NAC].pop(key, None)
        else:
            controllers[NAC][key] = value
    return {NAMESPACE: controllers}


@pytest.fixture
def sensor_hw(robot) -> SensorHardware:
    hw = SensorHardware(tuple(j.name for j in robot.movable_joints))
    hw.set_state("joint1", -0.2)
    return hw


@pytest.fixture
def make_manager(sensor_hw, robot, write_yaml):
    """A manager over ``sensor_hw`` holding the NAC file's definitions, with NAC keys changed."""

    def make(**nac_changes) -> ControllerManager:
        manager = ControllerManager(sensor_hw, robot)
        manager.load_file(write_yaml(definitions(**nac_changes)))
        return manager

    return make


def started(make_manager, **nac_changes) -> tuple[ControllerManager, AdmittanceController,
                                                  JointVelocityController]:
    manager = make_manager(**nac_changes)
    manager.start([VEL, NAC])
    return manager, manager.controller(NAC), manager.controller(VEL)


# -- loading the chapter's file -------------------------------------------------------------
def test_the_chapter_file_loads_with_its_parameters(make_manager) -> None:
    manager = make_manager()
    nac = manager.load(NAC)
    assert isinstance(nac, AdmittanceController)
    assert (nac.mass, nac.stiffness, nac.damping, nac.attractor, nac.max_velocity) == (
        1.0, 1000.0, 50.0, -0.2, 1.0)
    assert nac.force_index == 2
    assert (nac.joint_state_rate_hz, nac.force_rate_hz) == (None, None)
    assert nac.joints == ()
    assert nac.downstream == (VEL,)
    assert nac.claimed_interfaces() == ((VEL, "reference"),)
    assert nac.field == NAC_FIELD


# -- one cycle's arithmetic -----------------------------------------------------------------
def test_one_update_computes_the_virtual_force_and_integrates_it(make_manager, sensor_hw) -> None:
    manager, nac, vel = started(make_manager, mass=2.0, stiffness=1000.0, damping=50.0, attractor=-0.2,
                                max_velocity=1.0)
    sensor_hw.set_state("joint1", -0.25, 0.1)
    sensor_hw.set_wrench("ft_sensor", [0.5, -0.7, -3.0, 0.1, 0.2, 0.3])
    nac.update(0.0, DT)
    # f = 1000 (-0.2 + 0.25) - 50 (0.1) + (-3) = 50 - 5 - 3 = 42 N; v_ref = 42 / 2 * 0.001
    assert (nac.position, nac.velocity, nac.force) == (-0.25, 0.1, -3.0)
    assert nac.velocity_reference == pytest.approx(0.021, rel=1e-12)
    assert vel.reference_input == nac.velocity_reference
    nac.update(DT, DT)  # same state: the same f again, integrated
    assert nac.velocity_reference == pytest.approx(0.042, rel=1e-12)
    assert vel.reference_input == pytest.approx(0.042, rel=1e-12)


def test_the_velocity_reference_is_clamped_both_ways(make_manager, sensor_hw) -> None:
    manager, nac, vel = started(make_manager, mass=1.0, stiffness=0.0, damping=0.0, max_velocity=0.05)
    sensor_hw.set_wrench("ft_sensor", [0, 0, 30.0, 0, 0, 0])  # +0.03 m/s per cycle
    nac.update(0.0, DT)
    assert vel.reference_input == pytest.approx(0.03, rel=1e-12)
    nac.update(DT, DT)
    assert vel.reference_input == 0.05  # 0.06 clamped to +max_velocity
    sensor_hw.set_wrench("ft_sensor", [0, 0, -80.0, 0, 0, 0])  # -0.08 m/s per cycle
    nac.update(2 * DT, DT)
    assert vel.reference_input == pytest.approx(-0.03, rel=1e-12)  # from the clamped value, not from 0.06
    nac.update(3 * DT, DT)
    assert vel.reference_input == -0.05
    assert nac.velocity_reference == -0.05


def test_the_velocity_reference_integrates_over_the_given_period(make_manager, sensor_hw) -> None:
    manager, nac, vel = started(make_manager, mass=4.0, stiffness=0.0, damping=0.0)
    sensor_hw.set_wrench("ft_sensor", [0, 0, 2.0, 0, 0, 0])
    nac.update(0.0, 0.002)
    assert vel.reference_input == pytest.approx(2.0 / 4.0 * 0.002, rel=1e-12)


def test_the_chain_reaches_the_effort_command(make_manager, sensor_hw) -> None:
    manager, nac, vel = started(make_manager)  # M 1, K 1000, B 50, attractor -0.2
    sensor_hw.set_state("joint1", -0.21, -0.02)
    manager.update(0.0, DT)
    v_ref = (1000.0 * 0.01 - 50.0 * -0.02 + 0.0) / 1.0 * DT
    assert vel.reference_input == pytest.approx(v_ref, rel=1e-12)
    # the velocity controller ran after it in the same cycle, with the new reference
    assert manager.references[0] == pytest.approx(v_ref, rel=1e-12)
    assert sensor_hw.command_buffer(EFFORT)[0] == pytest.approx(KV * (v_ref - -0.02), rel=1e-12)


def test_starting_again_resets_the_velocity_reference(make_manager, sensor_hw) -> None:
    manager, nac, vel = started(make_manager, stiffness=0.0, damping=0.0)
    sensor_hw.set_wrench("ft_sensor", [0, 0, 10.0, 0, 0, 0])
    for k in range(5):
        nac.update(k * DT, DT)
    assert nac.velocity_reference == pytest.approx(0.05, rel=1e-12)
    manager.stop([NAC, VEL])
    manager.start([VEL, NAC])
    assert nac.velocity_reference == 0.0
    nac.update(0.0, DT)
    assert nac.velocity_reference == pytest.approx(0.01, rel=1e-12)


@pytest.mark.parametrize(("axis", "expected"), [("x", 1.5), ("y", -2.5), ("z", 4.0)])
def test_force_axis_picks_the_component(make_manager, sensor_hw, axis, expected) -> None:
    manager, nac, vel = started(make_manager, force_axis=axis, stiffness=0.0, damping=0.0, mass=0.5)
    assert nac.force_index == "xyz".index(axis)
    sensor_hw.set_wrench("ft_sensor", [1.5, -2.5, 4.0, 100.0, 200.0, 300.0])
    nac.update(0.0, DT)
    assert nac.force == expected
    assert vel.reference_input == pytest.approx(expected / 0.5 * DT, rel=1e-12)


def test_force_axis_defaults_to_z(make_manager) -> None:
    assert make_manager(force_axis=None).load(NAC).force_index == 2


def _drive(manager, nac, sensor_hw, cycles: int, start_s: float = 0.0) -> list[tuple[float, float, float]]:
    """Cycle k sets position -0.2 - 1 mm·k, velocity 0.01·k, force -k; what the controller used."""
    seen = []
    for k in range(cycles):
        sensor_hw.set_state("joint1", -0.2 - 0.001 * k, 0.01 * k)
        sensor_hw.set_wrench("ft_sensor", [0, 0, -float(k), 0, 0, 0])
        manager.update(start_s + k * DT, DT)
        seen.append((nac.position, nac.velocity, nac.force))
    return seen


def _held(k: int, every: int) -> int:
    """The cycle whose sample is in use at cycle k when sampling every ``every`` cycles from 0."""
    return every * (k // every)


def test_joint_state_rate_holds_position_and_velocity_and_not_the_force(make_manager, sensor_hw) -> None:
    # The chapter's node: joint states (position and velocity in one message) at 50 Hz, force every cycle.
    manager, nac, vel = started(make_manager, joint_state_rate_hz=50)
    seen = _drive(manager, nac, sensor_hw, 61)
    # cycle 0's state equals the start sample (-0.2, 0, 0)
    assert seen == [(-0.2 - 0.001 * _held(k, 20), 0.01 * _held(k, 20), -float(k)) for k in range(61)]


def test_force_rate_holds_the_force_and_not_the_joint_state(make_manager, sensor_hw) -> None:
    manager, nac, vel = started(make_manager, force_rate_hz=100)
    seen = _drive(manager, nac, sensor_hw, 31)
    assert seen == [(-0.2 - 0.001 * k, 0.01 * k, -float(_held(k, 10))) for k in range(31)]


@pytest.mark.parametrize(("force_rate_hz", "force_every"), [(200, 5), (50, 20)])
def test_the_two_rates_keep_their_own_schedules(make_manager, sensor_hw, force_rate_hz, force_every) -> None:
    # Joint states at 50 Hz with the force at 200 Hz; both at 50 Hz is the fully stale case.
    manager, nac, vel = started(make_manager, joint_state_rate_hz=50, force_rate_hz=force_rate_hz)
    seen = _drive(manager, nac, sensor_hw, 45)
    assert seen == [(-0.2 - 0.001 * _held(k, 20), 0.01 * _held(k, 20), -float(_held(k, force_every)))
                    for k in range(45)]


def test_held_signals_still_integrate_every_cycle(make_manager, sensor_hw) -> None:
    # As in the node, v_ref is integrated and commanded every cycle, from the held samples.
    sensor_hw.set_state("joint1", -0.21, 0.0)
    manager, nac, vel = started(make_manager, mass=1.0, stiffness=1000.0, damping=50.0, attractor=-0.2,
                                joint_state_rate_hz=50, force_rate_hz=50)  # sampled at the start:
    nac.update(0.0, DT)  # f = 1000 · 0.01 = 10 N
    sensor_hw.set_state("joint1", -0.5, 3.0)  # not seen until the next sample
    for k in range(1, 20):
        nac.update(k * DT, DT)
        assert vel.reference_input == pytest.approx(10.0 * DT * (k + 1), rel=1e-12)


def test_sampling_starts_at_the_start_time(make_manager, sensor_hw) -> None:
    # 100 Hz from a start at 1 s: the start sample is held until 1.01 s, then 1.02 s...
    manager = make_manager(joint_state_rate_hz=100, force_rate_hz=100)
    manager.start([VEL, NAC], time_s=1.0)  # the hardware holds -0.2 and no force at the start
    nac = manager.controller(NAC)
    for k in range(25):
        sensor_hw.set_state("joint1", -0.3 - 0.001 * k)
        sensor_hw.set_wrench("ft_sensor", [0, 0, -float(k + 1), 0, 0, 0])
        manager.update(1.0 + k * DT, DT)
        assert nac.position == (-0.2 if k < 10 else -0.3 - 0.001 * _held(k, 10))
        assert nac.force == (0.0 if k < 10 else -float(_held(k, 10) + 1))


def test_without_rates_every_cycle_sees_the_new_state(make_manager, sensor_hw) -> None:
    manager, nac, vel = started(make_manager)
    assert _drive(manager, nac, sensor_hw, 5) == [(-0.2 - 0.001 * k, 0.01 * k, -float(k)) for k in range(5)]


# -- refusals ---------------------------------------------------------------------------------
@pytest.mark.parametrize(("changes", "key", "value"), [
    ({"mass": 0.0}, "mass", 0.0),
    ({"mass": -1.0}, "mass", -1.0),
    ({"mass": ".nan"}, "mass", ".nan"),
    ({"mass": True}, "mass", True),
    ({"stiffness": -1.0}, "stiffness", -1.0),
    ({"damping": -0.5}, "damping", -0.5),
    ({"max_velocity": 0.0}, "max_velocity", 0.0),
    ({"max_velocity": -1.0}, "max_velocity", -1.0),
    ({"joint_state_rate_hz": 0}, "joint_state_rate_hz", 0.0),
    ({"joint_state_rate_hz": -50}, "joint_state_rate_hz", -50.0),
    ({"joint_state_rate_hz": "50 Hz"}, "joint_state_rate_hz", "50 Hz"),
    ({"force_rate_hz": 0}, "force_rate_hz", 0.0),
    ({"force_rate_hz": ".inf"}, "force_rate_hz", ".inf"),
    ({"state_rate_hz": 50}, "state_rate_hz", 50),  # the former all-signals option is gone: say which
    ({"force_axis": "w"}, "force_axis", "w"),
    ({"force_axis": "Z"}, "force_axis", "Z"),
    ({"stifness": 5.0}, "stifness", 5.0),
    ({"sensor": ""}, "sensor", ""),
    ({"velocity_controller": 3}, "velocity_controller", 3),
    ({"attractor": "low"}, "attractor", "low"),
])
def test_bad_parameters_are_refused_naming_the_field(make_manager, changes, key, value) -> None:
    manager = make_manager(**changes)
    with pytest.raises(ConfigError) as info:
        manager.load(NAC)
    error = info.value
    assert error.field == f"{NAC_FIELD}.{key}"
    assert error.value == value
    assert f"{NAC_FIELD}.{key}" in str(error)


@pytest.mark.parametrize("key", ["joint", "sensor", "velocity_controller", "mass", "stiffness", "damping",
                                 "attractor", "max_velocity"])
def test_required_parameters(make_manager, key) -> None:
    with pytest.raises(ConfigError, match="is required") as info:
        make_manager(**{key: None}).load(NAC)
    assert info.value.field == f"{NAC_FIELD}.{key}"


def test_zero_stiffness_and_damping_are_accepted(make_manager) -> None:
    nac = make_manager(stiffness=0, damping=0).load(NAC)
    assert (nac.stiffness, nac.damping) == (0.0, 0.0)


def test_an_unknown_sensor_is_refused(make_manager) -> None:
    with pytest.raises(ConfigError, match=r"no force-torque sensor.*\(sensors: ft_sensor\)") as info:
        make_manager(sensor="wrist_sensor").load(NAC)
    assert info.value.field == f"{NAC_FIELD}.sensor"
    assert info.value.value == "wrist_sensor"


def test_an_unknown_joint_is_refused(make_manager) -> None:
    with pytest.raises(ConfigError, match="no such joint") as info:
        make_manager(joint="joint9").load(NAC)
    assert info.value.field == f"{NAC_FIELD}.joint"


@pytest.mark.parametrize("attractor", [0.01, -1.01, 5.0])
def test_an_attractor_outside_the_joint_range_is_refused(make_manager, attractor) -> None:
    with pytest.raises(ConfigError, match=r"outside the joint's range \[-1.0, 0.0\]") as info:
        make_manager(attractor=attractor).load(NAC)
    assert info.value.field == f"{NAC_FIELD}.attractor"
    assert info.value.value == attractor


@pytest.mark.parametrize("attractor", [-1.0, 0.0, -0.5])
def test_an_attractor_on_or_inside_the_range_is_accepted(make_manager, attractor) -> None:
    assert make_manager(attractor=attractor).load(NAC).attractor == attractor


def test_a_controller_that_is_not_a_velocity_controller_is_refused(make_manager) -> None:
    manager = make_manager(velocity_controller=JSC)
    with pytest.raises(ConfigError, match="must name a velocity controller of the same joint") as info:
        manager.start([JSC, NAC])
    assert info.value.field == f"{NAC_FIELD}.velocity_controller"
    assert info.value.value == JSC
    assert manager.active == ()


TWO_JOINTS_URDF = """<?xml version="1.0"?>
<robot name="two_joints">
  <link name="base"/>
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <link name="b"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="joint1" type="prismatic"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="0" effort="1000" velocity="100"/></joint>
  <joint name="joint2" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1000" velocity="100"/></joint>
</robot>
"""


def test_a_velocity_controller_of_another_joint_is_refused(tmp_path: Path, write_yaml) -> None:
    urdf = tmp_path / "two.urdf"
    urdf.write_text(TWO_JOINTS_URDF)
    robot = load_robot_model(urdf)
    hw = SensorHardware(("joint1", "joint2"))
    tree = definitions()
    tree[NAMESPACE]["joint2_velocity_controller"] = {**tree[NAMESPACE][VEL], "joint": "joint2"}
    tree[NAMESPACE][NAC]["velocity_controller"] = "joint2_velocity_controller"
    manager = ControllerManager(hw, robot)
    manager.load_file(write_yaml(tree))
    with pytest.raises(ConfigError, match="same joint") as info:
        manager.start(["joint2_velocity_controller", NAC])
    assert info.value.field == f"{NAC_FIELD}.velocity_controller"
    assert info.value.value == "joint2_velocity_controller"
    assert manager.active == ()
    # the right one on that robot is accepted
    tree[NAMESPACE][NAC]["velocity_controller"] = VEL
    manager = ControllerManager(hw, robot)
    manager.load_file(write_yaml(tree, "right.yaml"))
    manager.start([VEL, NAC])
    assert manager.command_owner(VEL) is manager.controller(NAC)


def test_a_position_controller_is_not_a_velocity_controller(make_manager) -> None:
    manager = make_manager(velocity_controller=POS)
    assert isinstance(manager.load(POS), JointPositionController)
    with pytest.raises(ConfigError, match="velocity controller") as info:
        manager.start([POS, NAC])
    assert info.value.field == f"{NAC_FIELD}.velocity_controller"


# -- set_gains --------------------------------------------------------------------------------
def test_set_gains_applies_at_the_next_update(make_manager, sensor_hw) -> None:
    manager, nac, vel = started(make_manager, damping=0.0)
    sensor_hw.set_state("joint1", -0.25)
    nac.set_gains(stiffness=500.0)
    assert (nac.mass, nac.stiffness, nac.damping) == (1.0, 500.0, 0.0)
    nac.update(0.0, DT)
    assert vel.reference_input == pytest.approx(500.0 * 0.05 * DT, rel=1e-12)
    nac.set_gains(mass=5, damping=2)  # ints are accepted as floats
    assert (nac.mass, nac.stiffness, nac.damping) == (5.0, 500.0, 2.0)
    assert isinstance(nac.mass, float)
    nac.set_gains(stiffness=0.0, damping=0.0)
    assert (nac.stiffness, nac.damping) == (0.0, 0.0)
    nac.set_gains()  # nothing given: nothing changes
    assert (nac.mass, nac.stiffness, nac.damping) == (5.0, 0.0, 0.0)


@pytest.mark.parametrize(("gains", "name"), [
    ({"mass": 0.0}, "mass"),
    ({"mass": -1.0}, "mass"),
    ({"mass": math.inf}, "mass"),
    ({"stiffness": -1.0}, "stiffness"),
    ({"stiffness": math.nan}, "stiffness"),
    ({"damping": -0.1}, "damping"),
    ({"damping": True}, "damping"),
    ({"mass": "2"}, "mass"),
])
def test_set_gains_refuses_bad_values_and_keeps_the_gains(make_manager, gains, name) -> None:
    nac = make_manager().load(NAC)
    with pytest.raises(ConfigError) as info:
        nac.set_gains(**gains)
    assert info.value.field == name
    assert info.value.source == NAC
    assert (nac.mass, nac.stiffness, nac.damping) == (1.0, 1000.0, 50.0)


def test_a_refused_set_gains_changes_nothing(make_manager) -> None:
    nac = make_manager().load(NAC)
    with pytest.raises(ConfigError):
        nac.set_gains(mass=2.0, stiffness=-1.0)
    assert nac.mass == 1.0


# -- chaining in the manager ----------------------------------------------------------------------
def test_it_runs_before_its_velocity_controller_even_when_started_after(make_manager) -> None:
    manager = make_manager()
    manager.start([JSC, VEL])
    manager.start([NAC])
    nac, vel, jsc = manager.controller(NAC), manager.controller(VEL), manager.controller(JSC)
    assert [c.name for c in manager.active] == [JSC, NAC, VEL]
    assert manager.update_calls == (jsc.update, nac.update, vel.update)
    assert manager.update_calls.index(nac.update) < manager.update_calls.index(vel.update)


def test_listing_it_first_or_last_gives_the_same_order(make_manager) -> None:
    for names in ([NAC, VEL], [VEL, NAC]):
        manager = make_manager()
        manager.start(names)
        assert [c.name for c in manager.active] == [NAC, VEL]


def test_the_update_order_is_observable_in_one_cycle(make_manager, sensor_hw) -> None:
    # In one cycle the velocity controller already uses the reference computed in that cycle.
    manager = make_manager(stiffness=0.0, damping=0.0)
    manager.start([VEL])
    manager.start([NAC])
    sensor_hw.set_wrench("ft_sensor", [0, 0, 10.0, 0, 0, 0])
    manager.update(0.0, DT)
    assert sensor_hw.command_buffer(EFFORT)[0] == pytest.approx(KV * 10.0 * DT, rel=1e-12)


def test_while_chained_the_velocity_controller_refuses_edge_references(make_manager, sensor_hw) -> None:
    # Chained mode: the admittance controller writes the reference interface; an edge (a command
    # topic, a command source) is refused naming it, and the admittance's value is what is used.
    manager = make_manager(stiffness=0.0, damping=0.0)
    manager.start([VEL])
    vel = manager.controller(VEL)
    vel.set_reference(0.3)  # not chained yet: accepted
    assert (vel.upstream, vel.reference_input) == (None, 0.3)
    manager.start([NAC])
    assert vel.upstream == NAC
    with pytest.raises(InvalidCommand, match=f"comes from controller '{NAC}'") as info:
        vel.set_reference(0.5)
    assert (info.value.source, info.value.field, info.value.value) == (VEL, "reference", 0.5)
    sensor_hw.set_wrench("ft_sensor", [0, 0, 10.0, 0, 0, 0])
    manager.update(0.0, DT)
    assert vel.reference_input == pytest.approx(10.0 * DT, rel=1e-12)  # the admittance's, not 0.5
    manager.stop([NAC, VEL])
    assert vel.upstream is None
    manager.start([VEL])
    vel.set_reference(0.5)  # no longer chained: the edge works again
    assert vel.reference_input == 0.5


def test_the_velocity_watchdog_is_off_while_chained(make_manager, sensor_hw, write_yaml, robot) -> None:
    # The admittance controller writes every cycle of the same loop, never through the edge door:
    # a 5 ms command timeout must not zero its reference.
    tree = definitions(stiffness=0.0, damping=0.0)
    tree[NAMESPACE][VEL]["command_timeout_s"] = 0.005
    manager = ControllerManager(sensor_hw, robot)
    manager.load_file(write_yaml(tree))
    manager.start([VEL, NAC])
    vel = manager.controller(VEL)
    sensor_hw.set_wrench("ft_sensor", [0, 0, 10.0, 0, 0, 0])
    for k in range(50):
        manager.update(k * DT, DT)
    assert not vel.timed_out
    assert manager.references[0] == pytest.approx(50 * 10.0 * DT, rel=1e-9)  # integrated, in use
    assert sensor_hw.command_buffer(EFFORT)[0] == pytest.approx(KV * 50 * 10.0 * DT, rel=1e-9)
    manager.stop([NAC, VEL])
    manager.start([VEL])  # alone, from an edge: the watchdog is back
    vel.set_reference(0.1)
    for k in range(50, 60):
        manager.update(k * DT, DT)
    assert vel.timed_out and manager.references[0] == 0.0


def test_starting_it_without_its_velocity_controller_is_refused(make_manager) -> None:
    manager = make_manager()
    manager.start([JSC])
    with pytest.raises(ControllerError, match=f"needs {VEL} running") as info:
        manager.start([NAC])
    assert info.value.value == NAC
    assert [c.name for c in manager.active] == [JSC]
    assert len(manager.update_calls) == 1


def test_stopping_the_velocity_controller_alone_is_refused(make_manager) -> None:
    manager, nac, vel = started(make_manager)
    with pytest.raises(ControllerError, match=f"controller '{NAC}' feeds it: stop both together") as info:
        manager.stop([VEL])
    assert info.value.value == VEL
    assert [c.name for c in manager.active] == [NAC, VEL]
    assert manager.update_calls == (nac.update, vel.update)


def test_stopping_both_works_and_so_does_stopping_the_admittance_controller_alone(make_manager) -> None:
    manager, nac, vel = started(make_manager)
    manager.stop([VEL, NAC])
    assert manager.active == () and manager.update_calls == ()
    assert manager.command_owner(VEL) is None
    assert math.isnan(manager.references[0])
    manager.start([VEL, NAC])
    manager.stop([NAC])
    assert [c.name for c in manager.active] == [VEL]
    assert manager.command_owner(VEL) is None
    manager.stop([VEL])
    assert manager.active == ()


def test_command_owner_is_the_admittance_controller(make_manager) -> None:
    manager = make_manager()
    manager.start([JSC, VEL])
    assert manager.command_owner(VEL) is None
    manager.start([NAC])
    assert manager.command_owner(VEL) is manager.controller(NAC)
    assert manager.command_owner(NAC) is None
    assert manager.command_owner(JSC) is None
    assert manager.commanding("joint1") is manager.controller(VEL)


def test_two_admittance_controllers_cannot_command_one_velocity_controller(robot, sensor_hw,
                                                                          write_yaml) -> None:
    tree = definitions()
    tree[NAMESPACE]["second_admittance_controller"] = dict(tree[NAMESPACE][NAC])
    manager = ControllerManager(sensor_hw, robot)
    manager.load_file(write_yaml(tree))
    manager.start([VEL, NAC])
    with pytest.raises(ControllerError, match=f"controller '{VEL}' reference interface is already claimed by "
                                              f"controller '{NAC}'") as info:
        manager.start(["second_admittance_controller"])
    assert info.value.value == "second_admittance_controller"
    assert [c.name for c in manager.active] == [NAC, VEL]


class _Relay(Controller):
    """A test controller that commands the controller named by its ``next`` parameter."""

    def __init__(self, name, params) -> None:
        super().__init__(name, params)
        self.downstream = (params.string("next"),)
        params.reject_unknown({"type"})
        self.started = 0

    def claimed_interfaces(self):
        return ((self.downstream[0], "reference"),)

    def configure(self, hardware, robot) -> None:
        pass

    def start(self, time_s: float) -> None:
        self.started += 1

    def update(self, time_s: float, period_s: float) -> None:
        pass


@pytest.fixture
def relay_manager(monkeypatch, sensor_hw, robot, write_yaml):
    """A manager with relays a -> b -> a and c -> c (loops), d -> a, next to the NAC file."""
    tree = definitions()
    for name, nxt in (("a", "b"), ("b", "a"), ("c", "c")):
        tree[NAMESPACE][name] = {"type": "test/Relay", "next": nxt}
    manager = ControllerManager(sensor_hw, robot, types={**controller_types(), "test/Relay": _Relay})
    manager.load_file(write_yaml(tree))
    return manager


@pytest.mark.parametrize(("names", "trail"), [(["a", "b"], "a -> b -> a"), (["c"], "c -> c")])
def test_a_chain_loop_is_refused(relay_manager, names, trail) -> None:
    with pytest.raises(ControllerError, match="feed each other in a loop") as info:
        relay_manager.start(names)
    assert info.value.value == trail


def test_a_refused_chain_loop_starts_nothing(relay_manager) -> None:
    relay_manager.start([JSC])
    with pytest.raises(ControllerError, match="loop"):
        relay_manager.start(["a", "b"])
    assert [c.name for c in relay_manager.active] == [JSC]
    assert relay_manager.controller("a").started == 0
    relay_manager.start([VEL])  # the manager is still usable
    assert [c.name for c in relay_manager.active] == [JSC, VEL]


# -- closed loop on the MuJoCo stack: the statics ------------------------------------------------
def nac_scenario(**changes) -> dict:
    scenario = {
        "name": "nac_statics",
        "robot": "one_dof",
        "controller_file": "nac",
        "start_controllers": [JSC, VEL, NAC],
        "gravity": 0.0,
        "initial_positions": {"joint1": -0.2},
        "duration_s": 3.0,
    }
    scenario.update(changes)
    return scenario


def run_session(write_scenario, seconds: float, **changes) -> Session:
    session = Session(load_scenario(write_scenario(nac_scenario(**changes))))
    session.run(seconds)
    return session


def test_without_gravity_or_load_it_rests_at_the_attractor(write_scenario) -> None:
    session = run_session(write_scenario, 3.0, initial_positions={"joint1": -0.3})
    assert session.hardware.position[0] == pytest.approx(-0.2, abs=1e-4)
    assert session.hardware.velocity[0] == pytest.approx(0.0, abs=1e-4)
    assert session.hardware.wrenches["ft_sensor"][2] == pytest.approx(0.0, abs=1e-9)


def test_without_gravity_it_moves_to_a_changed_attractor(write_scenario) -> None:
    session = run_session(write_scenario, 3.0, controllers={NAC: {"attractor": -0.6}})
    assert session.hardware.position[0] == pytest.approx(-0.6, abs=1e-4)


@pytest.mark.parametrize("stiffness", [1000.0, 250.0])
def test_the_disk_own_weight_shifts_the_rest_point_by_f_over_k(write_scenario, stiffness) -> None:
    g, plate = 9.8, 0.01
    session = run_session(write_scenario, 4.0, gravity=-g, controllers={NAC: {"stiffness": stiffness}})
    force_z = session.hardware.wrenches["ft_sensor"][2]
    assert force_z == pytest.approx(-plate * g, rel=0.005)
    expected = -0.2 - plate * g / stiffness  # 0.098 mm (K 1000) or 0.392 mm (K 250) below
    assert session.hardware.position[0] == pytest.approx(expected, abs=1e-5)


def test_a_resting_weight_shifts_the_rest_point_by_f_over_k(write_scenario) -> None:
    g, weight, plate, k = 9.8, 10.0, 0.01, 1000.0
    top = 2.0 - 0.2 + 0.005  # base 1 m + joint1 + piston 1 m + the disk's 5 mm
    obj = {"name": "weight", "shape": "cylinder", "radius_m": 0.05, "length_m": 0.2, "mass_kg": weight,
           "xyz": [0.0, 0.0, top + 0.1 + 0.001]}
    session = run_session(write_scenario, 5.0, gravity=-g, objects=[obj])
    force_z = session.hardware.wrenches["ft_sensor"][2]
    assert force_z == pytest.approx(-(weight + plate) * g, rel=0.005)
    x = session.hardware.position[0]
    assert x == pytest.approx(-0.2 + force_z / k, abs=1e-5)  # x_att + F/K with the sensed F
    assert x == pytest.approx(-0.2 - (weight + plate) * g / k, abs=5e-4)  # -0.2981 m from theory


def test_slow_rates_do_not_start_from_an_unread_state(write_scenario) -> None:
    session = Session(load_scenario(write_scenario(nac_scenario(
        controllers={NAC: {"joint_state_rate_hz": 50, "force_rate_hz": 50}}))))
    session.loop.run(cycles=25)
    assert session.hardware.position[0] == pytest.approx(-0.2, abs=1e-4)


@pytest.mark.parametrize("rates", [{"joint_state_rate_hz": 50},
                                   {"joint_state_rate_hz": 50, "force_rate_hz": 1000}],
                         ids=["joint_states_50hz", "the_book_node"])
def test_fed_as_the_book_node_a_resting_weight_still_rests_at_f_over_k(write_scenario, rates) -> None:
    # The weight placed 1 mm above the disk (no drop): a small disturbance, well inside the linear
    # range, that the node-like loop damps (see tests/scenario for its decay rate against theory).
    # Statics do not depend on the sampling, so the tolerance is the in-loop one.
    g, weight, plate, k = 9.8, 10.0, 0.01, 1000.0
    top = 2.0 - 0.2 + 0.005
    obj = {"name": "weight", "shape": "cylinder", "radius_m": 0.05, "length_m": 0.2, "mass_kg": weight,
           "xyz": [0.0, 0.0, top + 0.1 + 0.001]}
    session = run_session(write_scenario, 8.0, gravity=-g, objects=[obj], controllers={NAC: rates})
    force_z = session.hardware.wrenches["ft_sensor"][2]
    assert force_z == pytest.approx(-(weight + plate) * g, rel=0.005)
    assert session.hardware.position[0] == pytest.approx(-0.2 + force_z / k, abs=1e-5)

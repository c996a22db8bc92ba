"""Objects in scenarios: validation, spawn timing, a load on the force sensor, chained command sources.

Geometry of the 1-DOF robot: base 1 m + joint1 q + piston 1 m puts the sensor frame (the disk's
bottom face) at z = 2 + q and the disk's top at 2 + q + 0.005. Theory at rest for a 10 kg load
held by the position controller (Kp 400) under 5 m/s²: the sensor carries the load and its own
0.01 kg plate, force z = -(10 + 0.01)·5 N (negative: chapter convention); the actuator carries
everything that moves, effort = (1 + 0.01 + 10)·5 N; position -0.2 - effort / Kp.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.errors import ConfigError
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from tests.conftest import step_scenario

JSC = "joint_state_controller"
POS = "joint1_position_controller"
VEL = "joint1_velocity_controller"
NAC = "joint1_admittance_controller"
PISTON, PLATE, WEIGHT = 1.0, 0.01, 10.0
KP = 400.0


def cylinder(name: str = "weight", z: float = 4.0, **changes) -> dict:
    obj = {"name": name, "shape": "cylinder", "radius_m": 0.05, "length_m": 0.2, "mass_kg": WEIGHT,
           "xyz": [0.0, 0.0, z]}
    obj.update(changes)
    return obj


def disk_top(q: float) -> float:
    return 2.0 + q + 0.005


def hold_scenario(**changes) -> dict:
    """The position controller holding joint1 at -0.2 under gravity -5 (fig. 11.5's set-up)."""
    scenario = step_scenario(
        gravity=-5.0, duration_s=10.0,
        commands={POS: {"type": "constant", "value": -0.2}},
    )
    scenario.update(changes)
    return scenario


def nac_scenario(**changes) -> dict:
    scenario = {
        "name": "nac",
        "robot": "one_dof",
        "controller_file": "nac",
        "start_controllers": [JSC, VEL, NAC],
        "gravity": -9.8,
        "initial_positions": {"joint1": -0.2},
        "duration_s": 1.0,
    }
    scenario.update(changes)
    return scenario


# -- validation -------------------------------------------------------------------------------
def test_objects_are_read_into_the_scenario(write_scenario) -> None:
    scenario = load_scenario(write_scenario(step_scenario(objects=[
        cylinder(spawn_at_s=1.0), {"name": "ball", "shape": "sphere", "radius_m": 0.1, "mass_kg": 1,
                                   "xyz": [1, 0, 1]}])))
    assert [o.name for o in scenario.objects] == ["weight", "ball"]
    assert scenario.objects[0].spawn_at_s == 1.0
    assert scenario.objects[0].size_m == (0.05, 0.2)
    assert scenario.objects[1].shape == "sphere"
    assert load_scenario(write_scenario(step_scenario(), "none.yaml")).objects == ()


def test_the_builtin_drop_scenarios_carry_their_weight() -> None:
    for name, at in (("one_dof_drop_weight", 0.5), ("one_dof_nac_drop", 1.0)):
        (weight,) = load_scenario(name).objects
        assert (weight.name, weight.shape, weight.mass_kg, weight.xyz, weight.spawn_at_s) == (
            "weight", "cylinder", 10.0, (0.0, 0.0, 4.0), at)


def test_two_objects_with_the_same_name_are_refused(write_scenario) -> None:
    path = write_scenario(step_scenario(objects=[cylinder(), cylinder(z=5.0), cylinder(z=6.0)]))
    with pytest.raises(ConfigError, match="two objects have the same name") as info:
        load_scenario(path)
    assert info.value.field == "objects[1].name"
    assert info.value.value == "weight"
    assert info.value.source == str(path)


@pytest.mark.parametrize("value", [{"weight": cylinder()}, "weight", 3])
def test_objects_must_be_a_list(write_scenario, value) -> None:
    with pytest.raises(ConfigError, match="must be a list of objects") as info:
        load_scenario(write_scenario(step_scenario(objects=value)))
    assert info.value.field == "objects"
    assert info.value.value == value


@pytest.mark.parametrize(("objects", "field", "value"), [
    ([cylinder(mass_kg=-10)], "objects[0].mass_kg", -10),
    ([cylinder(), cylinder("second", shape="cone")], "objects[1].shape", "cone"),
    ([cylinder(spawn_at_s=-1)], "objects[0].spawn_at_s", -1),
    ([cylinder(z=0.05)], "objects[0].xyz", [0.0, 0.0, 0.05]),
    ([cylinder(speed=3)], "objects[0].speed", 3),
])
def test_an_object_refusal_names_the_scenario_and_the_entry(write_scenario, objects, field, value) -> None:
    path = write_scenario(step_scenario(objects=objects))
    with pytest.raises(ConfigError) as info:
        load_scenario(path)
    assert info.value.field == field
    assert info.value.value == value
    assert str(info.value).startswith(f"{path}: {field}: ")


def test_the_floor_setting_decides_whether_an_object_may_start_below_ground(write_scenario) -> None:
    with pytest.raises(ConfigError, match="below the ground"):
        load_scenario(write_scenario(step_scenario(objects=[cylinder(z=0.05)])))
    scenario = load_scenario(write_scenario(step_scenario(floor=False, objects=[cylinder(z=0.05)]), "f.yaml"))
    assert scenario.objects[0].xyz == (0.0, 0.0, 0.05)


def test_an_object_named_like_a_link_is_refused_before_the_run(write_scenario) -> None:
    path = write_scenario(step_scenario(objects=[cylinder("link2", z=4.0, spawn_at_s=0.5)]))
    with pytest.raises(ConfigError) as info:
        Session(load_scenario(path)).run(1.0)
    assert info.value.field == "objects[0].name"


# -- spawn timing -------------------------------------------------------------------------------
def test_an_object_appears_at_the_first_cycle_at_or_after_its_spawn_time(write_scenario) -> None:
    session = Session(load_scenario(write_scenario(step_scenario(objects=[
        cylinder(spawn_at_s=0.25, xyz=[1.0, 0.0, 4.0])]))))
    world = session.world
    nbody = world.model.nbody
    assert world.spawned == []
    assert session.loop.run(cycles=250) == 250  # loop times 0 ... 0.249 s
    assert world.spawned == []
    assert world.model.nbody == nbody
    session.loop.run(cycles=1)  # loop time 0.25 s
    assert [o.name for o in world.spawned] == ["weight"]
    assert world.model.nbody == nbody + 1
    session.loop.run(cycles=100)
    assert len(world.spawned) == 1  # once only
    # the robot went on under control across the spawn (the step to -0.5 at 0.1 s is under way)
    session.hardware.read()  # the hardware reads the recompiled data
    assert session.hardware.position == [float(world.data.qpos[0])]
    assert session.hardware.position[0] < -0.3


def test_objects_spawn_in_time_order_whatever_their_order_in_the_file(write_scenario) -> None:
    session = Session(load_scenario(write_scenario(step_scenario(objects=[
        cylinder("late", spawn_at_s=0.05, xyz=[1.0, 0.0, 4.0]),
        cylinder("early", spawn_at_s=0.02, xyz=[-1.0, 0.0, 4.0]),
        cylinder("first", xyz=[0.0, 1.0, 4.0]),
    ]))))
    names = lambda: [o.name for o in session.world.spawned]  # noqa: E731
    assert names() == []
    session.loop.run(cycles=1)
    assert names() == ["first"]
    session.loop.run(cycles=20)  # up to t = 0.020 s
    assert names() == ["first", "early"]
    session.loop.run(cycles=29)  # up to t = 0.049 s
    assert names() == ["first", "early"]
    session.loop.run(cycles=1)
    assert names() == ["first", "early", "late"]


def test_a_spawned_object_falls_under_the_scenario_gravity(write_scenario) -> None:
    session = Session(load_scenario(write_scenario(step_scenario(
        gravity=-4.0, objects=[cylinder(xyz=[1.0, 0.0, 3.0], spawn_at_s=0.1)]))))
    session.loop.run(cycles=101)  # spawned at 0.1 s, then one step
    session.loop.run(cycles=199)  # 0.2 s of fall in all
    jid = session.world.model.njnt - 1
    z = float(session.world.data.qpos[session.world.model.jnt_qposadr[jid] + 2])
    assert z == pytest.approx(3.0 - 4.0 * 0.2 ** 2 / 2, abs=4.0 * 0.2 * 0.001 / 2 + 1e-6)


# -- a load on the force sensor -----------------------------------------------------------------
def test_the_geometry_used_to_rest_an_object_on_the_disk(write_scenario) -> None:
    session = Session(load_scenario(write_scenario(hold_scenario())))
    world = session.world
    site_z = float(world.data.site_xpos[world.site_id("ft_sensor")][2])
    assert site_z == pytest.approx(disk_top(-0.2) - 0.005, abs=1e-12)  # 1.8 m: the disk's bottom face


def test_a_resting_load_reads_its_weight_and_the_plate_on_the_sensor(write_scenario) -> None:
    g = 5.0
    obj = cylinder(z=disk_top(-0.2) + 0.1 + 0.001, spawn_at_s=0.0)
    session = Session(load_scenario(write_scenario(hold_scenario(objects=[obj]))))
    force_z, effort, position = [], [], []
    hw = session.hardware

    def observe(t: float) -> None:
        force_z.append(hw.wrenches["ft_sensor"][2])
        effort.append(hw.effort[0])
        position.append(hw.position[0])

    session.loop.add_observer(observe)
    session.run(10.0)
    assert len(force_z) == 10000
    # The joint is lightly damped (10 N·s/m on 11 kg): average the last second, about one period.
    last = slice(-1000, None)
    f, e, x = np.mean(force_z[last]), np.mean(effort[last]), np.mean(position[last])
    assert f < 0.0
    assert f == pytest.approx(-(WEIGHT + PLATE) * g, rel=0.005)  # -50.05 N
    assert e == pytest.approx((PISTON + PLATE + WEIGHT) * g, rel=0.005)  # 55.05 N
    assert e + f == pytest.approx(PISTON * g, rel=0.05)  # the actuator also carries the piston
    assert x == pytest.approx(-0.2 - (PISTON + PLATE + WEIGHT) * g / KP, abs=1e-3)  # -0.3376 m
    # the weight rests on the disk, centred on it
    pos, _ = session.world.body_pose("weight")
    assert pos[2] == pytest.approx(disk_top(hw.position[0]) + 0.1, abs=2e-3)
    assert pos[:2] == pytest.approx([0.0, 0.0], abs=1e-3)


def test_without_a_load_the_sensor_reads_only_the_plate(write_scenario) -> None:
    session = Session(load_scenario(write_scenario(hold_scenario(duration_s=2.0))))
    session.run()
    assert session.hardware.wrenches["ft_sensor"][2] == pytest.approx(-PLATE * 5.0, rel=0.005)
    assert session.hardware.effort[0] == pytest.approx((PISTON + PLATE) * 5.0, rel=0.005)


# -- command sources and chaining -----------------------------------------------------------------
def test_a_command_source_for_a_chained_velocity_controller_is_refused(write_scenario) -> None:
    path = write_scenario(nac_scenario(commands={VEL: {"type": "constant", "value": 0.1}}))
    with pytest.raises(ConfigError, match=f"controller '{NAC}' already commands it") as info:
        Session(load_scenario(path))
    assert info.value.field == f"commands.{VEL}"
    assert info.value.value == VEL
    assert str(info.value).startswith(f"{path}: commands.{VEL}: ")


def test_the_velocity_controller_takes_a_source_when_nothing_commands_it(write_scenario) -> None:
    session = Session(load_scenario(write_scenario(nac_scenario(
        start_controllers=[JSC, VEL], commands={VEL: {"type": "constant", "value": -0.1}}))))
    session.run(0.5)
    assert session.manager.command_owner(VEL) is None
    assert session.manager.controller(VEL).reference_input == -0.1
    assert session.hardware.velocity[0] < -0.05


def test_the_admittance_controller_drives_the_chain_in_a_session(write_scenario) -> None:
    session = Session(load_scenario(write_scenario(nac_scenario())))
    nac, vel = session.manager.controller(NAC), session.manager.controller(VEL)
    assert [c.name for c in session.manager.active] == [JSC, NAC, VEL]
    session.run(0.5)
    assert vel.reference_input == nac.velocity_reference
    assert session.manager.references[0] == vel.reference_input

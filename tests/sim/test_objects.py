"""Spawned objects: solid inertia, reading ``objects`` entries, and MujocoWorld.spawn.

Theory used here: principal moments of homogeneous solids about the centre of mass
(cylinder of radius r and length h along z: m(3r² + h²)/12, m(3r² + h²)/12, mr²/2;
box a×b×c: m(b² + c²)/12, m(a² + c²)/12, m(a² + b²)/12; sphere: 2mr²/5) and free fall
z(t) = z0 - g t²/2, which MuJoCo's semi-implicit Euler integrator follows as
z_n = z0 - g dt² n(n + 1)/2 (an excess drop of g t dt / 2).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from jointctl.errors import ConfigError
from jointctl.hardware.interface import EFFORT
from jointctl.hardware.mujoco_hardware import MujocoHardware
from jointctl.model import load_robot_model
from jointctl.paths import robots_dir
from jointctl.sim import MujocoWorld, WorldSettings
from jointctl.sim.objects import ObjectSpec, object_from_config, solid_inertia

ONE_DOF_XACRO = robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro"
SOURCE = "scenario.yaml"
FIELD = "objects[0]"


@pytest.fixture(scope="module")
def one_dof():
    return load_robot_model(ONE_DOF_XACRO)


def weight(**changes) -> ObjectSpec:
    """The 10 kg cylinder of the drop scenarios (r 0.05 m, length 0.2 m) at (0, 0, 4)."""
    values = dict(name="weight", shape="cylinder", size_m=(0.05, 0.2), mass_kg=10.0, xyz=(0.0, 0.0, 4.0))
    values.update(changes)
    return ObjectSpec(**values)


def body_id(world: MujocoWorld, name: str) -> int:
    return mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_BODY, name)


def free_qpos_adr(world: MujocoWorld, name: str) -> int:
    jid = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_free")
    assert jid >= 0
    return int(world.model.jnt_qposadr[jid])


# -- solid inertia -------------------------------------------------------------------------
def test_cylinder_inertia_is_the_textbook_solid_cylinder() -> None:
    m, r, h = 10.0, 0.05, 0.2
    ixx, iyy, izz = solid_inertia("cylinder", (r, h), m)
    # m(3r² + h²)/12 = 10 (0.0075 + 0.04) / 12
    assert ixx == pytest.approx(0.475 / 12, rel=1e-12)
    assert iyy == pytest.approx(0.475 / 12, rel=1e-12)
    assert izz == pytest.approx(10 * 0.0025 / 2, rel=1e-12)  # mr²/2 = 0.0125


def test_thin_rod_and_flat_disk_limits_of_the_cylinder() -> None:
    # A long thin rod: mL²/12 about a transverse axis; a flat disk: mr²/4 about a diameter.
    rod = solid_inertia("cylinder", (1e-6, 2.0), 3.0)
    assert rod[0] == pytest.approx(3.0 * 4.0 / 12, rel=1e-9)
    assert rod[2] == pytest.approx(0.0, abs=1e-11)
    disk = solid_inertia("cylinder", (0.5, 1e-9), 2.0)
    assert disk[0] == pytest.approx(2.0 * 0.25 / 4, rel=1e-9)
    assert disk[2] == pytest.approx(2.0 * 0.25 / 2, rel=1e-12)


def test_box_inertia_is_the_textbook_solid_cuboid() -> None:
    m, a, b, c = 6.0, 0.1, 0.2, 0.3
    ixx, iyy, izz = solid_inertia("box", (a, b, c), m)
    assert ixx == pytest.approx(m * (b * b + c * c) / 12, rel=1e-12)  # 0.065
    assert iyy == pytest.approx(m * (a * a + c * c) / 12, rel=1e-12)  # 0.05
    assert izz == pytest.approx(m * (a * a + b * b) / 12, rel=1e-12)  # 0.025
    assert (ixx, iyy, izz) == pytest.approx((0.065, 0.05, 0.025), rel=1e-12)
    # a cube: ms²/6 about every axis
    assert solid_inertia("box", (0.4, 0.4, 0.4), 3.0) == pytest.approx((0.08, 0.08, 0.08), rel=1e-12)


def test_sphere_inertia_is_two_fifths_m_r_squared() -> None:
    assert solid_inertia("sphere", (0.1,), 5.0) == pytest.approx((0.02, 0.02, 0.02), rel=1e-12)


def test_principal_inertia_defaults_to_the_solid_and_honours_an_explicit_one() -> None:
    assert weight().principal_inertia == pytest.approx((0.475 / 12, 0.475 / 12, 0.0125), rel=1e-12)
    assert weight(inertia=(0.3, 0.4, 0.5)).principal_inertia == (0.3, 0.4, 0.5)


@pytest.mark.parametrize(("shape", "size", "half_height", "mujoco_size"), [
    ("cylinder", (0.05, 0.2), 0.1, [0.05, 0.1, 0.0]),
    ("box", (0.1, 0.2, 0.3), 0.15, [0.05, 0.1, 0.15]),
    ("sphere", (0.07,), 0.07, [0.07, 0.0, 0.0]),
])
def test_half_height_and_mujoco_half_sizes(shape, size, half_height, mujoco_size) -> None:
    spec = ObjectSpec("o", shape, size, 1.0, (0.0, 0.0, 1.0))
    assert spec.half_height_m == pytest.approx(half_height, rel=1e-12)
    assert spec.mujoco_size == pytest.approx(mujoco_size, rel=1e-12)


# -- reading an objects entry --------------------------------------------------------------
def config(**changes) -> dict:
    """A valid cylinder entry; a value of None removes the key."""
    cfg = {"name": "weight", "shape": "cylinder", "radius_m": 0.05, "length_m": 0.2, "mass_kg": 10.0,
           "xyz": [0, 0, 4.0]}
    for key, value in changes.items():
        if value is None:
            cfg.pop(key, None)
        else:
            cfg[key] = value
    return cfg


def read(cfg, floor: bool = True) -> ObjectSpec:
    return object_from_config(cfg, field=FIELD, source=SOURCE, floor=floor)


def test_a_full_entry_is_read_with_si_floats_and_defaults() -> None:
    spec = read(config(xyz=[1, 2, 3]))
    assert spec == ObjectSpec("weight", "cylinder", (0.05, 0.2), 10.0, (1.0, 2.0, 3.0))
    assert spec.rpy == (0.0, 0.0, 0.0)
    assert spec.inertia is None
    assert spec.spawn_at_s == 0.0
    assert spec.friction == 1.0
    assert all(isinstance(v, float) for v in (*spec.xyz, spec.mass_kg, *spec.size_m))
    full = read(config(rpy=[0.1, 0, 0], inertia=[0.04, 0.04, 0.0125], spawn_at_s=1.5, friction=0.5,
                       xyz=[0, 0, 4]))
    assert (full.rpy, full.inertia, full.spawn_at_s, full.friction) == (
        (0.1, 0.0, 0.0), (0.04, 0.04, 0.0125), 1.5, 0.5)


def test_box_and_sphere_entries() -> None:
    box = read({"name": "crate", "shape": "box", "size_m": [0.1, 0.2, 0.3], "mass_kg": 2, "xyz": [0, 0, 1]})
    assert box.size_m == (0.1, 0.2, 0.3)
    assert box.mass_kg == 2.0
    ball = read({"name": "ball", "shape": "sphere", "radius_m": 0.1, "mass_kg": 1, "xyz": [0, 0, 1]})
    assert ball.size_m == (0.1,)


BOX = {"name": "crate", "shape": "box", "size_m": [0.1, 0.2, 0.3], "mass_kg": 2.0, "xyz": [0, 0, 1]}
SPHERE = {"name": "ball", "shape": "sphere", "radius_m": 0.1, "mass_kg": 1.0, "xyz": [0, 0, 1]}


@pytest.mark.parametrize(("cfg", "key", "value"), [
    # mass
    (config(mass_kg=0), "mass_kg", 0),
    (config(mass_kg=-1.5), "mass_kg", -1.5),
    (config(mass_kg=math.nan), "mass_kg", math.nan),
    (config(mass_kg=math.inf), "mass_kg", math.inf),
    (config(mass_kg="10"), "mass_kg", "10"),
    (config(mass_kg=True), "mass_kg", True),
    # cylinder and sphere sizes
    (config(radius_m=0), "radius_m", 0),
    (config(radius_m=-0.05), "radius_m", -0.05),
    (config(radius_m=math.inf), "radius_m", math.inf),
    (config(length_m=0.0), "length_m", 0.0),
    (config(length_m=-0.2), "length_m", -0.2),
    (config(length_m=math.nan), "length_m", math.nan),
    (config(length_m=True), "length_m", True),
    ({**SPHERE, "radius_m": -0.1}, "radius_m", -0.1),
    ({**SPHERE, "radius_m": math.nan}, "radius_m", math.nan),
    # box sizes, entry by entry
    ({**BOX, "size_m": [0.1, 0, 0.3]}, "size_m[1]", 0),
    ({**BOX, "size_m": [-0.1, 0.2, 0.3]}, "size_m[0]", -0.1),
    ({**BOX, "size_m": [0.1, 0.2, math.inf]}, "size_m[2]", math.inf),
    ({**BOX, "size_m": [0.1, 0.2, True]}, "size_m[2]", True),
    ({**BOX, "size_m": [0.1, 0.2]}, "size_m", [0.1, 0.2]),
    ({**BOX, "size_m": 0.1}, "size_m", 0.1),
    # shape, unknown keys, name
    (config(shape="cone"), "shape", "cone"),
    (config(shape=None), "shape", None),
    (config(colour="red"), "colour", "red"),
    (config(size_m=[0.1, 0.1, 0.1]), "size_m", [0.1, 0.1, 0.1]),  # a box key on a cylinder
    ({**SPHERE, "length_m": 0.2}, "length_m", 0.2),
    ({**BOX, "radius_m": 0.2}, "radius_m", 0.2),
    (config(name="my weight"), "name", "my weight"),
    (config(name="2nd"), "name", "2nd"),
    (config(name=""), "name", ""),
    (config(name=7), "name", 7),
    (config(name=None), "name", None),
    # pose
    (config(xyz=[0, 0]), "xyz", [0, 0]),
    (config(xyz=[0, 0, math.nan]), "xyz[2]", math.nan),
    (config(xyz=[0, "a", 4]), "xyz[1]", "a"),
    (config(xyz=[0, True, 4]), "xyz[1]", True),
    (config(rpy=[0, 0, math.inf]), "rpy[2]", math.inf),
    # inertia
    (config(inertia=[0.01, 0.01, 0.03]), "inertia", [0.01, 0.01, 0.03]),
    (config(inertia=[0.5, 0.1, 0.1]), "inertia", [0.5, 0.1, 0.1]),
    (config(inertia=[0, 0.1, 0.1]), "inertia[0]", 0),
    (config(inertia=[0.1, 0.1, -0.1]), "inertia[2]", -0.1),
    # timing and friction
    (config(spawn_at_s=-0.1), "spawn_at_s", -0.1),
    (config(spawn_at_s=math.inf), "spawn_at_s", math.inf),
    (config(spawn_at_s=True), "spawn_at_s", True),
    (config(friction=0), "friction", 0),
    (config(friction=False), "friction", False),
    # below the ground: centre 0.09 m, half length 0.1 m
    (config(xyz=[0, 0, 0.09]), "xyz", [0.0, 0.0, 0.09]),
    ({**BOX, "xyz": [0, 0, 0.1]}, "xyz", [0.0, 0.0, 0.1]),
    ({**SPHERE, "xyz": [0, 0, -1]}, "xyz", [0.0, 0.0, -1.0]),
])
def test_refusals_name_the_key_and_the_value(cfg, key, value) -> None:
    with pytest.raises(ConfigError) as info:
        read(cfg)
    error = info.value
    assert error.field == f"{FIELD}.{key}"
    assert error.source == SOURCE
    assert error.has_value
    if isinstance(value, float) and math.isnan(value):
        assert math.isnan(error.value)
    else:
        assert error.value == value
        assert type(error.value) is type(value)
    text = str(error)
    assert text.startswith(f"{SOURCE}: {FIELD}.{key}: ")
    assert f"(got {value!r})" in text


@pytest.mark.parametrize(("cfg", "key"), [
    (config(mass_kg=None), "mass_kg"),
    (config(radius_m=None), "radius_m"),
    (config(length_m=None), "length_m"),
    ({k: v for k, v in BOX.items() if k != "size_m"}, "size_m"),
    ({k: v for k, v in SPHERE.items() if k != "radius_m"}, "radius_m"),
    (config(xyz=None), "xyz"),
])
def test_missing_fields_are_required(cfg, key) -> None:
    with pytest.raises(ConfigError, match="is required") as info:
        read(cfg)
    assert info.value.field == f"{FIELD}.{key}"
    assert not info.value.has_value


@pytest.mark.parametrize("cfg", [None, [1, 2], "weight", 3.0])
def test_an_entry_must_be_a_mapping(cfg) -> None:
    with pytest.raises(ConfigError, match="must be a mapping") as info:
        read(cfg)
    assert info.value.field == FIELD


def test_inertia_on_the_triangle_inequality_boundary_is_accepted() -> None:
    assert read(config(inertia=[0.1, 0.2, 0.3])).inertia == (0.1, 0.2, 0.3)


def test_the_ground_check_is_on_the_lowest_point_and_only_with_a_floor() -> None:
    # Upright cylinder: centre z - L/2 >= 0 is allowed, down to exactly touching the ground.
    assert read(config(xyz=[0, 0, 0.1])).xyz == (0.0, 0.0, 0.1)
    assert read({**BOX, "xyz": [0, 0, 0.15]}).xyz == (0.0, 0.0, 0.15)
    assert read({**SPHERE, "xyz": [0, 0, 0.1]}).xyz == (0.0, 0.0, 0.1)
    # Without a floor anything goes, even below z = 0.
    assert read(config(xyz=[0, 0, 0.09]), floor=False).xyz == (0.0, 0.0, 0.09)
    assert read({**SPHERE, "xyz": [0, 0, -1]}, floor=False).xyz == (0.0, 0.0, -1.0)


def test_a_tilted_object_is_checked_with_its_bounding_sphere() -> None:
    # Tilted by 90° the cylinder lies down (lowest point 0.05 m below its centre), but the check
    # is conservative: sqrt(0.05² + 0.1²) = 0.1118 m.
    reach = math.hypot(0.05, 0.1)
    assert read(config(rpy=[math.pi / 2, 0, 0], xyz=[0, 0, reach + 1e-9])).rpy[0] == math.pi / 2
    with pytest.raises(ConfigError) as info:
        read(config(rpy=[math.pi / 2, 0, 0], xyz=[0, 0, reach - 1e-6]))
    assert info.value.field == f"{FIELD}.xyz"


# -- spawning into the world ---------------------------------------------------------------
def test_spawn_keeps_the_robot_state_and_adds_one_body(one_dof) -> None:
    world = MujocoWorld(one_dof, initial_positions={"joint1": -0.2})
    world.data.ctrl[world.actuator_ids[0]] = 30.0  # let the joint move, so the state is not trivial
    for _ in range(100):
        world.step()
    adr, dof = world.qpos_adr[0], world.dof_adr[0]
    q, v, t = float(world.data.qpos[adr]), float(world.data.qvel[dof]), world.time_s
    assert v != 0.0 and q != -0.2
    nbody = world.model.nbody
    old_data = world.data

    world.spawn(weight())

    assert world.data is not old_data  # MuJoCo recompiled: new model and data
    assert world.model.nbody == nbody + 1
    # exactly the same joint state and time: the spawn itself moves nothing
    assert world.qpos_adr[0] == adr and world.dof_adr[0] == dof
    assert float(world.data.qpos[adr]) == q
    assert float(world.data.qvel[dof]) == v
    assert world.time_s == t
    bid = body_id(world, "weight")
    assert bid >= 0
    assert world.model.body_mass[bid] == 10.0
    assert world.model.body_inertia[bid] == pytest.approx(solid_inertia("cylinder", (0.05, 0.2), 10.0),
                                                          rel=1e-9)
    # the free joint starts at the object's pose, upright and at rest
    a = free_qpos_adr(world, "weight")
    assert world.data.qpos[a:a + 7] == pytest.approx([0, 0, 4, 1, 0, 0, 0], abs=1e-12)
    assert np.all(world.data.qvel[world.model.jnt_dofadr[world.model.njnt - 1]:] == 0.0)
    assert world.spawned == [weight()]
    # the object's mass is the only mass added to the world
    assert world.model.body_mass.sum() == pytest.approx(1.0 + 1.0 + 0.01 + 10.0, rel=1e-12)


def test_spawned_box_and_sphere_get_their_shape_and_inertia(one_dof) -> None:
    world = MujocoWorld(one_dof)
    world.spawn(ObjectSpec("crate", "box", (0.1, 0.2, 0.3), 6.0, (1.0, 0.0, 1.0)))
    world.spawn(ObjectSpec("ball", "sphere", (0.1,), 5.0, (-1.0, 0.0, 1.0)))
    assert [o.name for o in world.spawned] == ["crate", "ball"]
    m = world.model
    for name, size, inertia, geom_type in (
        ("crate", [0.05, 0.1, 0.15], (0.065, 0.05, 0.025), mujoco.mjtGeom.mjGEOM_BOX),
        ("ball", [0.1, 0.0, 0.0], (0.02, 0.02, 0.02), mujoco.mjtGeom.mjGEOM_SPHERE),
    ):
        bid = body_id(world, name)
        gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{name}_geom")
        assert m.geom_bodyid[gid] == bid
        assert m.geom_type[gid] == geom_type
        assert m.geom_size[gid][:3] == pytest.approx(size, abs=1e-12)
        assert m.body_inertia[bid] == pytest.approx(inertia, rel=1e-9)


@pytest.mark.parametrize("name", ["weight", "link2", "ft_sensor_link"])
def test_a_duplicate_name_is_refused_and_changes_nothing(one_dof, name) -> None:
    world = MujocoWorld(one_dof)
    world.spawn(weight())
    nbody, data = world.model.nbody, world.data
    calls = []
    world.on_rebuild(lambda: calls.append(1))
    with pytest.raises(ConfigError, match="already exists") as info:
        world.spawn(weight(name=name, xyz=(1.0, 0.0, 1.0)))
    assert info.value.value == name
    assert world.model.nbody == nbody
    assert world.data is data
    assert [o.name for o in world.spawned] == ["weight"]
    assert calls == []


def test_rebuild_listeners_are_called_once_per_spawn_after_the_swap(one_dof) -> None:
    world = MujocoWorld(one_dof)
    seen = []
    world.on_rebuild(lambda: seen.append(("a", world.model.nbody, len(world.spawned))))
    world.on_rebuild(lambda: seen.append(("b", world.model.nbody, len(world.spawned))))
    nbody = world.model.nbody
    world.spawn(weight())
    world.spawn(weight(name="second", xyz=(1.0, 0.0, 1.0)))
    assert seen == [("a", nbody + 1, 1), ("b", nbody + 1, 1), ("a", nbody + 2, 2), ("b", nbody + 2, 2)]


def test_the_hardware_follows_the_new_model_and_data(one_dof) -> None:
    world = MujocoWorld(one_dof, initial_positions={"joint1": -0.2})
    hw = MujocoHardware(world)
    hw.command_buffer(EFFORT)[0] = 30.0
    hw.write()
    world.spawn(weight())
    # the command in the buffer is carried into the new MjData
    assert world.data.ctrl[world.actuator_ids[0]] == 30.0
    for _ in range(5):
        hw.advance(0.001)
        hw.read()
        assert hw.position == [float(world.data.qpos[0])]
        assert hw.velocity == [float(world.data.qvel[0])]
    # advance stepped the new data (and with it the clock), and the joint moved under the command
    assert world.time_s == pytest.approx(0.005, abs=1e-12)
    assert hw.position[0] != -0.2
    assert hw.effort == [30.0]
    # the sensor is read from the new data as well
    f_adr, _ = world.sensor_adr("ft_sensor")
    assert hw.wrenches["ft_sensor"][2] == -float(world.data.sensordata[f_adr + 2])
    assert hw.wrenches["ft_sensor"][2] != 0.0


def test_a_spawned_sphere_falls_freely(one_dof) -> None:
    settings = WorldSettings()
    world = MujocoWorld(one_dof, settings)
    world.spawn(ObjectSpec("ball", "sphere", (0.05,), 1.0, (1.0, 0.5, 3.0)))  # clear of the robot
    a = free_qpos_adr(world, "ball")
    g = -settings.gravity_m_s2[2]
    dt = world.timestep_s
    n = 300
    for _ in range(n):
        world.step()
    t = world.time_s
    assert t == pytest.approx(0.3, abs=1e-12)
    z = float(world.data.qpos[a + 2])
    assert world.data.qpos[a:a + 2] == pytest.approx([1.0, 0.5], abs=1e-12)
    # semi-implicit Euler, exactly
    assert z == pytest.approx(3.0 - g * dt * dt * n * (n + 1) / 2, abs=1e-9)
    # and the continuous law, within the integrator's g t dt / 2 (1.47 mm at 9.81 m/s², 0.3 s, 1 ms)
    assert z == pytest.approx(3.0 - g * t * t / 2, abs=g * t * dt / 2 + 1e-6)
    assert float(world.data.qvel[world.model.jnt_dofadr[world.model.njnt - 1] + 2]) == pytest.approx(
        -g * t, rel=1e-9)


def test_free_fall_matches_the_continuous_law_within_a_millimetre_at_lower_gravity(one_dof) -> None:
    settings = WorldSettings(gravity_m_s2=(0.0, 0.0, -5.0))
    world = MujocoWorld(one_dof, settings)
    world.spawn(ObjectSpec("ball", "sphere", (0.05,), 1.0, (1.0, 0.0, 3.0)))
    for _ in range(300):
        world.step()
    mujoco.mj_forward(world.model, world.data)
    position, _ = world.body_pose("ball")
    assert position[2] == pytest.approx(3.0 - 5.0 * 0.3 ** 2 / 2, abs=1e-3)


def test_body_pose_right_after_spawn_is_the_spawn_pose(one_dof) -> None:
    world = MujocoWorld(one_dof)
    world.spawn(weight(xyz=(0.3, 0.0, 4.0)))
    position, quat = world.body_pose("weight")
    assert position == pytest.approx([0.3, 0.0, 4.0], abs=1e-9)
    assert quat == pytest.approx([1.0, 0.0, 0.0, 0.0], abs=1e-9)


def test_the_hardware_reading_does_not_glitch_at_the_spawn(one_dof) -> None:
    world = MujocoWorld(one_dof, initial_positions={"joint1": -0.2})
    hw = MujocoHardware(world)
    hw.command_buffer(EFFORT)[0] = 20.0
    for _ in range(50):
        hw.write()
        hw.advance(0.001)
    hw.read()
    effort, force_z = hw.effort[0], hw.wrenches["ft_sensor"][2]
    assert effort == 20.0 and force_z < 0.0
    world.spawn(weight(xyz=(1.0, 0.0, 4.0)))  # far from the robot: nothing changes for it
    hw.read()
    assert hw.effort[0] == 20.0
    assert hw.wrenches["ft_sensor"][2] == pytest.approx(force_z, rel=0.05)


def test_body_pose_of_an_unknown_body_is_refused(one_dof) -> None:
    world = MujocoWorld(one_dof)
    with pytest.raises(ConfigError, match="no body of that name") as info:
        world.body_pose("weight")
    assert info.value.value == "weight"

"""Part 2's minimal robot: the description against the book's numbers, and its physics against theory.

The numbers here are the book's (minimal_robot_w_sensor.urdf, chapter11-facts.md section 11), typed
in by hand, so the tests check the xacro and jointctl's model and MuJoCo builder against them:

- link2: 1 kg, centre of mass 0.5 m above joint1, iyy 0.1 kg·m²;
- kinect_link: 0.1 kg at (0.2, 0, 0.95) m in link2, isotropic 0.001 kg·m²;
- so about joint1 (axis y): I = 0.1 + 1·0.5² + 0.001 + 0.1·(0.2² + 0.95²) = 0.44525 kg·m², and the
  gravity torque is τ_g(q) = g·(0.02·cos q + 0.595·sin q) N·m (first moments m·x = 0.1·0.2,
  m·z = 1·0.5 + 0.1·0.95), i.e. m·g·l·sin(q + φ) with m·l = √(0.02² + 0.595²) kg·m, φ = atan2(0.02, 0.595).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from jointctl.model import load_robot_model
from jointctl.paths import robots_dir
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario, read_robot_manifest
from jointctl.sim.mjcf_builder import WorldSettings
from jointctl.sim.world import MujocoWorld

XACRO = robots_dir() / "minimal_robot" / "urdf" / "minimal_robot.xacro"
G = 9.81
I_AXIS = 0.1 + 1.0 * 0.5**2 + 0.001 + 0.1 * (0.2**2 + 0.95**2)
MX, MZ = 0.1 * 0.2, 1.0 * 0.5 + 0.1 * 0.95
ML = math.hypot(MX, MZ)
LEAN = math.atan2(MX, MZ)
KP, KV = 10.0, 3.0


def gravity_torque(q: float) -> float:
    """Torque gravity applies about joint1 [N·m] (positive: towards positive q)."""
    return G * (MX * math.cos(q) + MZ * math.sin(q))


@pytest.fixture(scope="module")
def robot():
    return load_robot_model(XACRO)


@pytest.fixture(scope="module")
def world(robot):
    return MujocoWorld(robot, WorldSettings(gravity_m_s2=(0.0, 0.0, -G)))


# -- the description ------------------------------------------------------------------------------

def test_the_books_robot_name_links_and_joints(robot):
    assert robot.name == "one_DOF_robot"
    assert robot.root_link == "world"
    assert [lk.name for lk in robot.links] == ["world", "link1", "link2", "kinect_link"]
    assert {(j.name, j.type, j.parent, j.child) for j in robot.joints} == {
        ("glue_robot_to_world", "fixed", "world", "link1"),
        ("joint1", "continuous", "link1", "link2"),
        ("kinect_joint", "fixed", "link2", "kinect_link"),
    }
    assert [j.name for j in robot.movable_joints] == ["joint1"]


def test_joint1_is_continuous_about_y_one_metre_up_without_limits_or_damping(robot):
    joint = robot.joint("joint1")
    assert joint.axis == (0.0, 1.0, 0.0)
    assert joint.origin.xyz == (0.0, 0.0, 1.0) and joint.origin.rpy == (0.0, 0.0, 0.0)
    assert joint.limits is None  # no position, velocity or effort limit in the book's URDF
    assert (joint.damping, joint.friction, joint.armature) == (0.0, 0.0, 0.0)
    assert joint.is_movable and not joint.is_locked
    transmission = robot.transmission_for("joint1")
    assert transmission is not None and "EffortJointInterface" in transmission.hardware_interfaces


def test_masses_and_inertias_are_the_books(robot):
    link1, link2, kinect = (robot.link(n).inertial for n in ("link1", "link2", "kinect_link"))
    assert (link1.mass_kg, link1.origin.xyz, link1.inertia) == (1.0, (0.0, 0.0, 0.5), (1.0, 1.0, 1.0, 0.0, 0.0, 0.0))
    assert (link2.mass_kg, link2.origin.xyz, link2.inertia) == (1.0, (0.0, 0.0, 0.5), (0.1, 0.1, 0.005, 0.0, 0.0, 0.0))
    assert (kinect.mass_kg, kinect.origin.xyz, kinect.inertia) == (0.1, (0.0, 0.0, 0.0),
                                                                   (0.001, 0.001, 0.001, 0.0, 0.0, 0.0))
    kinect_joint = robot.joint("kinect_joint")
    assert kinect_joint.origin.xyz == (0.2, 0.0, 0.95) and kinect_joint.origin.rpy == (0.0, 1.2, 0.0)


def test_shapes_are_the_books(robot):
    link1, link2, kinect = (robot.link(n) for n in ("link1", "link2", "kinect_link"))
    assert link1.visuals[0].geometry.size_m == (0.2, 0.2, 1.0) and link1.visuals[0].origin.xyz == (0, 0, 0.5)
    assert link1.collisions[0].geometry.size_m == (0.2, 0.2, 0.7) and link1.collisions[0].origin.xyz == (0, 0, 0.5)
    for shape in (*link2.visuals, *link2.collisions):
        g = shape.geometry
        assert (g.kind, g.radius_m, g.length_m, shape.origin.xyz) == ("cylinder", 0.1, 1.0, (0, 0, 0.5))
    for shape in (*kinect.visuals, *kinect.collisions):
        assert shape.geometry.size_m == (0.05, 0.2, 0.05)


def test_the_manifest_declares_the_books_ros_names():
    files = read_robot_manifest(robots_dir() / "minimal_robot" / "robot.yaml")
    assert set(files.controller_files) == {"position", "trajectory"}
    ros = files.extras["ros"]
    assert ros["actions"] == {"example_traj_action_server": {"type": "traj",
                                                             "controller": "joint1_trajectory_controller"}}
    assert ros["command_topics"] == {"/pos_cmd": "joint1_position_controller"}


# -- the MuJoCo model ------------------------------------------------------------------------------

def test_the_fixed_camera_link_keeps_its_own_body_and_mass(world):
    m = world.model
    kinect = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "kinect_link")
    link2 = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "link2")
    assert kinect >= 0 and m.body_parentid[kinect] == link2
    assert m.body_mass[kinect] == pytest.approx(0.1)
    assert m.body_mass[link2] == pytest.approx(1.0)  # not fused: the camera's mass is not added here
    assert m.body_subtreemass[link2] == pytest.approx(1.1)
    assert m.body_jntnum[kinect] == 0  # welded to link2
    np.testing.assert_allclose(m.body_inertia[kinect], [0.001] * 3)


def test_joint1_is_an_unlimited_hinge_with_an_unlimited_motor(world):
    m = world.model
    jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "joint1")
    assert m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_HINGE
    assert not m.jnt_limited[jid]
    np.testing.assert_allclose(m.jnt_axis[jid], [0, 1, 0])
    assert m.dof_damping[m.jnt_dofadr[jid]] == 0.0
    act = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "joint1")
    assert act >= 0 and not m.actuator_forcelimited[act]


@pytest.mark.parametrize("q", [0.0, 0.5, 1.0, -1.0, 2.5, math.pi, 7.0])
def test_inertia_and_gravity_torque_about_joint1(world, q):
    m, d = world.model, mujoco.MjData(world.model)
    d.qpos[world.qpos_adr[0]] = q
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    dof = world.dof_adr[0]
    assert full[dof, dof] == pytest.approx(I_AXIS, rel=1e-12)
    assert -d.qfrc_bias[dof] == pytest.approx(gravity_torque(q), abs=1e-12)
    assert gravity_torque(q) == pytest.approx(G * ML * math.sin(q + LEAN), abs=1e-12)


def test_without_torque_the_upright_pendulum_falls(world):
    """Released at rest at q = 0 (its centre of mass 0.034 rad off upright, towards +x) with no
    torque, the angle off the balance point grows as φ·cosh(λt), λ = √(m·g·l / I) = 3.62 /s, while
    it is small, then the pendulum falls through a quarter turn."""
    world.reset()
    m, d = world.model, world.data
    d.ctrl[:] = 0.0
    lam = math.sqrt(G * ML / I_AXIS)
    q_adr = world.qpos_adr[0]
    t, worst, small = 0.0, 0.0, 0.0
    while t < 0.4:  # off-balance angle below 0.15 rad: sin(x) = x within 0.4 %
        mujoco.mj_step(m, d)
        t = d.time
        predicted = -LEAN + LEAN * math.cosh(lam * t)
        small = max(small, abs(predicted + LEAN))
        worst = max(worst, abs(d.qpos[q_adr] - predicted))
    # Tolerances: the sine's curvature (x³/6 at most, relative x²/6) and Euler's one-step lag at 1 ms.
    assert worst <= small * (small**2 / 6 + lam * m.opt.timestep)
    while d.time < 2.0 and d.qpos[q_adr] < math.pi / 2:
        mujoco.mj_step(m, d)
    assert d.qpos[q_adr] >= math.pi / 2, "the inverted pendulum did not fall"


def test_the_books_loop_holds_a_commanded_angle_with_the_predicted_sag(write_scenario):
    """Kp 10, Kv 3, no gravity compensation: at rest Kp·(command - q) = -τ_g(q); the pendulum sags
    past its command. The root is unique because Kp = 10 exceeds m·g·l = 5.84 N·m."""
    from scipy.optimize import brentq

    command = 0.3
    scenario = write_scenario({
        "name": "minimal_hold", "robot": "minimal_robot", "controller_file": "position",
        "start_controllers": ["joint_state_controller", "joint1_position_controller"],
        "gravity": -G, "initial_positions": {"joint1": 0.0}, "duration_s": 8.0,
        "commands": {"joint1_position_controller": {"type": "step", "from": 0.0, "to": command, "at": 0.5}},
    })
    with Session(load_scenario(scenario)) as session:
        session.run()
        q = session.hardware.position[0]
        qdot = session.hardware.velocity[0]
        effort = session.hardware.effort[0]
    rest = brentq(lambda x: KP * (command - x) + gravity_torque(x), command - 1.0, command + 1.0, xtol=1e-14)
    # The slowest mode decays at least as fast as e^(-1.9 t) (its upright value, the slowest pose);
    # 7.5 s after the step that leaves < 1e-6 of the 0.6 rad move.
    assert q == pytest.approx(rest, abs=1e-6)
    assert rest - command == pytest.approx(0.384, abs=1e-3)  # it sags 0.38 rad past its command
    assert abs(qdot) < 1e-5
    assert effort == pytest.approx(-gravity_torque(rest), abs=1e-4)

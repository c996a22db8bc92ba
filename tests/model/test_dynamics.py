"""The robot's kinematics and dynamics library (jointctl.model.dynamics) against independent answers.

Theory: the Jacobians are the derivatives of the forward kinematics (checked by central differences,
the rotational one through the rotation vector of R(q + h)·R(q - h)ᵀ); ``g(q)`` is the effort that
holds a pose at rest, i.e. the simulated world's bias force at zero velocity; ``M(q)`` is the world's
joint-space inertia (the same robot, compiled by the simulator with a floor around it); ``M(q)·q̈``
is that matrix times q̈; a subset of joints answers with the rows and columns of those joints.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from jointctl.errors import ModelError
from jointctl.model import load_robot_model
from jointctl.model.dynamics import RobotDynamics
from jointctl.paths import robots_dir
from jointctl.sim import MujocoWorld, WorldSettings

ARM_XACRO = robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro"
ONE_DOF_XACRO = robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro"
GRAVITY = (0.0, 0.0, -0.5)
POSES = [np.array([0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0]) + np.random.default_rng(seed).uniform(-0.5, 0.5, 7)
         for seed in range(3)]


@pytest.fixture(scope="module")
def arm():
    return load_robot_model(ARM_XACRO)


@pytest.fixture(scope="module")
def dynamics(arm) -> RobotDynamics:
    return RobotDynamics(arm, GRAVITY)


@pytest.fixture(scope="module")
def world(arm) -> MujocoWorld:
    return MujocoWorld(arm, WorldSettings(gravity_m_s2=GRAVITY))


def world_at(world: MujocoWorld, q) -> tuple[np.ndarray, np.ndarray]:
    """The world's bias force (zero velocity) and full joint-space inertia at ``q``."""
    m, d = world.model, world.data
    d.qpos[world.qpos_adr] = q
    d.qvel[:] = 0.0
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    dofs = world.dof_adr
    return d.qfrc_bias[dofs].copy(), full[np.ix_(dofs, dofs)]


def rotation_vector(r: np.ndarray) -> np.ndarray:
    angle = math.acos(max(-1.0, min(1.0, (np.trace(r) - 1) / 2)))
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return axis / 2 if angle < 1e-9 else axis * angle / (2 * math.sin(angle))


def test_joints_default_to_the_movable_joints_in_document_order(arm, dynamics) -> None:
    assert dynamics.joint_names == tuple(j.name for j in arm.movable_joints)
    np.testing.assert_array_equal(dynamics.damping, [j.damping for j in arm.movable_joints])


@pytest.mark.parametrize("q", POSES)
def test_gravity_and_mass_matrix_are_the_worlds(dynamics, world, q) -> None:
    bias, mass = world_at(world, q)
    dynamics.set_pose(q)
    np.testing.assert_allclose(dynamics.gravity_at_pose(), bias, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dynamics.mass_matrix(), mass, rtol=1e-12, atol=1e-12)
    qdd = np.linspace(-1.0, 1.0, 7)
    np.testing.assert_allclose(dynamics.inertia_at_pose(qdd), mass @ qdd, rtol=1e-12, atol=1e-12)
    out = np.zeros((7, 7))
    assert dynamics.mass_matrix(out) is out


def test_set_gravity_scales_the_gravity_efforts(arm) -> None:
    dynamics = RobotDynamics(arm, GRAVITY)
    dynamics.set_pose(POSES[0])
    half = dynamics.gravity_at_pose().copy()
    dynamics.set_gravity((0.0, 0.0, -1.0))
    dynamics.set_pose(POSES[0])
    np.testing.assert_allclose(dynamics.gravity_at_pose(), 2 * half, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("q", POSES)
def test_jacobians_are_the_derivatives_of_forward_kinematics(dynamics, q) -> None:
    frame, h = dynamics.frame("link8"), 1e-6
    jv_fd, jr_fd = np.zeros((3, 7)), np.zeros((3, 7))
    for i in range(7):
        dq = np.zeros(7)
        dq[i] = h
        positions, rotations = dynamics.poses("link8", [q + dq, q - dq])
        jv_fd[:, i] = (positions[0] - positions[1]) / (2 * h)
        jr_fd[:, i] = rotation_vector(rotations[0] @ rotations[1].T) / (2 * h)
    dynamics.set_pose(q, inertia=False)
    jv, jr = frame.jacobians()
    np.testing.assert_allclose(jv, jv_fd, atol=1e-7)
    np.testing.assert_allclose(jr, jr_fd, atol=1e-7)


def test_a_frame_follows_every_pose_and_poses_match_it(dynamics) -> None:
    frame = dynamics.frame("link8")
    assert dynamics.frame("link8") is frame
    positions, rotations = dynamics.poses("link8", POSES)
    for q, p, r in zip(POSES, positions, rotations):
        dynamics.set_pose(q, inertia=False)
        np.testing.assert_array_equal(frame.position, p)
        np.testing.assert_array_equal(frame.rotation, r)
    dynamics.set_pose(np.zeros(7), inertia=False)
    np.testing.assert_allclose(frame.position, [0.0, 0.05, 2.55], atol=0.002)  # straight up (the chapter)


def test_a_subset_of_joints_answers_in_its_order_with_the_others_at_zero(arm, dynamics) -> None:
    subset = RobotDynamics(arm, GRAVITY, joints=["joint3", "joint1"])
    q = np.zeros(7)
    q[3], q[1] = -1.9, 1.1
    subset.set_pose([-1.9, 1.1])
    dynamics.set_pose(q)
    np.testing.assert_allclose(subset.gravity_at_pose(), dynamics.gravity_at_pose()[[3, 1]], rtol=1e-12)
    np.testing.assert_allclose(subset.mass_matrix(), dynamics.mass_matrix()[np.ix_([3, 1], [3, 1])], rtol=1e-12)
    jv, jr = subset.frame("link8").jacobians()
    full_jv, full_jr = dynamics.frame("link8").jacobians()
    np.testing.assert_allclose(jv, full_jv[:, [3, 1]], rtol=1e-12)
    np.testing.assert_allclose(jr, full_jr[:, [3, 1]], rtol=1e-12)


def test_joint_axis_of_the_prismatic_robot_is_vertical_and_its_mass_the_moving_mass() -> None:
    robot = load_robot_model(ONE_DOF_XACRO)
    dynamics = RobotDynamics(robot, (0.0, 0.0, -9.8))
    dynamics.set_pose([0.0])
    np.testing.assert_allclose(dynamics.joint_axis("joint1"), [0.0, 0.0, 1.0])
    moving = robot.link("link2").inertial.mass_kg + robot.link("ft_sensor_link").inertial.mass_kg  # 1.01 kg
    assert dynamics.mass_matrix()[0, 0] == pytest.approx(moving, rel=1e-12)
    assert dynamics.gravity_at_pose()[0] == pytest.approx(9.8 * moving, rel=1e-12)


def test_unknown_joints_and_links_are_refused_naming_them(arm, dynamics) -> None:
    with pytest.raises(ModelError) as info:
        RobotDynamics(arm, joints=["joint0", "elbow"])
    assert info.value.value == "elbow"
    with pytest.raises(ModelError) as info:
        dynamics.frame("link9")
    assert info.value.value == "link9"
    with pytest.raises(ModelError):
        dynamics.joint_axis("elbow")

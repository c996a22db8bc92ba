"""The 7-DOF arm's model: kinematics, inertia repair, limits in radians, collision shapes."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from jointctl.model import load_robot_model
from jointctl.paths import robots_dir
from jointctl.sim import MujocoWorld, WorldSettings

ARM = robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro"
PRE_POSE = [0, 1, 0, -2, 0, 1, 0]


@pytest.fixture(scope="module")
def world():
    return MujocoWorld(load_robot_model(ARM), WorldSettings())


def flange(world, q):
    world.data.qpos[:7] = q
    mujoco.mj_forward(world.model, world.data)
    sid = world.site_id("ft_sensor")
    return world.data.site_xpos[sid].copy(), world.data.site_xmat[sid].reshape(3, 3).copy()


@pytest.mark.parametrize(("q", "expected"), [([0] * 7, (0, 0.05, 2.55)), (PRE_POSE, (0, 0.05, 1.63))])
def test_forward_kinematics_within_2_mm_of_the_chapter(world, q, expected):
    position, rotation = flange(world, q)
    assert np.linalg.norm(position - np.array(expected)) < 0.002
    assert rotation[:, 2] == pytest.approx([0, 0, 1], abs=0.01)  # the plate faces up


def test_revolute_limits_are_radians(world):
    # MjSpec reads hinge ranges in degrees unless told otherwise: ±3 must stay ±3 rad.
    jid = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_JOINT, "joint1")
    assert world.model.jnt_range[jid] == pytest.approx([-3.0, 3.0])
    jid = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_JOINT, "joint6")
    assert world.model.jnt_range[jid] == pytest.approx([-4.5, 1.2])


def test_the_chapters_inertia_excess_is_carried_as_armature(world):
    # chapter izz minus a physical izz (<= ixx + iyy), per joint
    assert world.model.dof_armature[:7] == pytest.approx([9.6, 9.7, 7.9, 0.9, 0.0, 0.0, 0.94])
    for body in range(1, world.model.nbody):
        a, b, c = sorted(world.model.body_inertia[body])
        assert a + b >= c * (1 - 1e-9)


def test_limits_damping_and_masses_are_the_chapters():
    robot = load_robot_model(ARM)
    table = {"joint0": (-3, 3, 1300, 0.2, 10), "joint1": (-3, 3, 1300, 0.2, 10),
             "joint2": (-3.1, 2.8, 500, 0.3, 5), "joint3": (-3.1, 2.7, 500, 0.3, 1000),
             "joint4": (-4.0, 1.5, 100, 0.4, 30), "joint5": (-3, 3, 100, 0.5, 30),
             "joint6": (-4.5, 1.2, 70, 0.4, 15)}
    for name, (lower, upper, effort, velocity, damping) in table.items():
        joint = robot.joint(name)
        assert (joint.limits.lower, joint.limits.upper, joint.limits.effort, joint.limits.velocity,
                joint.damping) == (lower, upper, effort, velocity, damping)
    masses = [robot.link(f"link{k}").inertial.mass_kg for k in range(1, 9)]
    assert masses == [30, 20, 15, 15, 8, 6, 4, 4]


def test_only_the_base_and_the_sensor_plate_collide(world):
    m = world.model
    colliding = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.geom_bodyid[g])
                 for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]}
    assert colliding == {"world", "link1", "ft_sensor_link"}  # world: the floor

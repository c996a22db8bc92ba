"""The compiled pose queries (jointctl.model.dynamics_kernel) answer as RobotDynamics does, bit for bit: the same
MuJoCo functions on the same private data, so every answer is compared with ``==``, for all of the arm's joints
and for a subset in another order (gathered columns), at poses with and without M(q)."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.model import load_robot_model
from jointctl.model.dynamics import RobotDynamics
from jointctl.model.dynamics_kernel import (
    DynamicsArrays, dynamics_gravity, dynamics_inertia, dynamics_jacobians, dynamics_mass_matrix,
    dynamics_set_pose)
from jointctl.paths import robots_dir

ARM_XACRO = robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro"
POSES = [np.array([0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0]) + np.random.default_rng(seed).uniform(-0.5, 0.5, 7)
         for seed in range(3)]


@pytest.fixture(scope="module")
def arm():
    return load_robot_model(ARM_XACRO)


@pytest.mark.parametrize("joints", [None, ("joint5", "joint1", "joint3")])
def test_the_compiled_queries_answer_as_the_python_ones(arm, joints):
    python, compiled = RobotDynamics(arm, (0.0, 0.0, -0.5), joints), RobotDynamics(arm, (0.0, 0.0, -0.5), joints)
    arrays = DynamicsArrays(compiled)
    n = len(python.joint_names)
    body = arrays.body("link8")
    jv, jr, gravity, inertia = np.zeros((3, n)), np.zeros((3, n)), np.zeros(n), np.zeros(n)
    for pose in POSES:
        q = pose[:n] if joints is None else pose[[5, 1, 3]]
        qdd = np.linspace(-1.0, 2.0, n)
        python.set_pose(q)
        dynamics_set_pose(arrays.addresses, arrays.qpos, arrays.qpos_adr, q, True)
        assert np.array_equal(arrays.xpos[body], python.frame("link8").position)
        assert np.array_equal(arrays.xmat[body].reshape(3, 3), python.frame("link8").rotation)
        expected_jv, expected_jr = (a.copy() for a in python.frame("link8").jacobians())
        dynamics_jacobians(arrays.addresses, arrays.jacp, arrays.jacr, body, arrays.dof_adr, jv, jr)
        assert np.array_equal(jv, expected_jv) and np.array_equal(jr, expected_jr)
        assert np.abs(jv).max() > 0.1  # a real Jacobian, not two zero buffers
        dynamics_gravity(arrays.addresses, arrays.tau, arrays.dof_adr, gravity)
        assert np.array_equal(gravity, python.gravity_at_pose())
        assert np.abs(gravity).max() > 0.0
        dynamics_inertia(arrays.addresses, arrays.tau, arrays.qdd, arrays.dof_adr, qdd, inertia)
        assert np.array_equal(inertia, python.inertia_at_pose(qdd))
        assert np.allclose(inertia, python.mass_matrix() @ qdd, rtol=1e-12, atol=1e-12)
        nv = arrays.jacp.shape[1]
        table = np.full((3 + -(-nv * nv // 9) + n, 9), np.nan)  # rows of 9: M's nv x nv from row 3, then M(q)
        dynamics_mass_matrix(arrays.addresses, nv, arrays.dof_adr, table, 3, table, table.shape[0] - n)
        assert np.array_equal(table[-n:, :n], python.mass_matrix())


def test_a_pose_without_the_inertia_leaves_it_as_it_was(arm):
    dynamics = RobotDynamics(arm, (0.0, 0.0, -0.5))
    arrays = DynamicsArrays(dynamics)
    dynamics_set_pose(arrays.addresses, arrays.qpos, arrays.qpos_adr, POSES[0], True)
    before = dynamics.mass_matrix()
    dynamics_set_pose(arrays.addresses, arrays.qpos, arrays.qpos_adr, POSES[1], False)
    assert np.array_equal(dynamics.mass_matrix(), before)
    dynamics_set_pose(arrays.addresses, arrays.qpos, arrays.qpos_adr, POSES[1], True)
    assert not np.array_equal(dynamics.mass_matrix(), before)

"""A transmission's ``mechanicalReduction`` honoured as ros_control's ``transmission_interface/SimpleTransmission``
does (transmission_interface/simple_transmission.h): with reduction n, joint effort = n · actuator effort, joint
position = actuator position / n, joint velocity = actuator velocity / n (n may be negative: a direction flip).

The controllers command joint effort and read joint state, as through ros_control's joint-space interfaces; the
URDF's ``<limit effort>`` is the joint's (ros_control's joint_limits_interface saturates the joint effort command
with it before the transmission maps it to the actuator), so the actuator's limit is that over |n|. The
simulated actuator is MuJoCo's motor with gear n, commanded in actuator effort: joint effort / n. A
SimpleTransmission has no inertia, friction or play of its own, so the joint moves exactly as with n = 1.

The 1-DOF robot: the piston and its disk (1.01 kg) on joint1, effort limit 1000 N, damping 10 N·s/m.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from jointctl.errors import ModelError
from jointctl.hardware import EFFORT, MujocoHardware
from jointctl.model import load_robot_model
from jointctl.paths import robots_dir
from jointctl.sim import MujocoWorld, WorldSettings

G, MOVING_KG, KP, TARGET, LIMIT_N = 9.81, 1.01, 400.0, -0.5, 1000.0


@pytest.fixture(scope="module")
def one_dof():
    return load_robot_model(robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro")


def geared(robot, reduction: float, kind: str = "transmission_interface/SimpleTransmission"):
    return dataclasses.replace(robot, transmissions=tuple(
        dataclasses.replace(t, mechanical_reduction=reduction, type=kind) for t in robot.transmissions))


def hardware(robot) -> MujocoHardware:
    world = MujocoWorld(robot, WorldSettings(timestep_s=0.001, gravity_m_s2=(0.0, 0.0, -G)),
                        initial_positions={"joint1": TARGET + 0.1})
    return MujocoHardware(world)


def p_law(hw: MujocoHardware, cycles: int, kp: float = KP) -> np.ndarray:
    """Positions [m] of the P law's cycles, its efforts written in joint effort [N]."""
    cmd, positions = hw.command_buffer(EFFORT), []
    for _ in range(cycles):
        hw.read()
        positions.append(hw.position[0])
        cmd[0] = kp * (TARGET - hw.position[0])
        hw.write()
        hw.advance(0.001)
    hw.read()
    return np.array(positions)


@pytest.mark.parametrize("reduction", [50.0, -50.0, 0.2])
def test_the_joint_moves_as_without_a_reduction_and_the_actuator_works_in_its_own_units(one_dof, reduction):
    plain, hw = hardware(one_dof), hardware(geared(one_dof, reduction))
    np.testing.assert_allclose(p_law(hw, 3000), p_law(plain, 3000), rtol=0, atol=1e-12)
    # At rest (the 0.12 m start rings down by exp(-ζωn·3 s) = 4e-7) the joint effort holds the weight: m·g.
    assert hw.effort[0] == pytest.approx(MOVING_KG * G, rel=1e-3) and hw.effort[0] == pytest.approx(plain.effort[0])
    data, act = hw.world.data, int(hw.world.actuator_ids[0])
    mujoco.mj_forward(hw.world.model, data)  # the actuator's length and speed of the state read (not the step's start)
    assert data.ctrl[act] == pytest.approx(hw.command_buffer(EFFORT)[0] / reduction, rel=1e-12)
    assert data.actuator_force[act] == pytest.approx(hw.effort[0] / reduction, rel=1e-12)
    assert data.actuator_length[act] == pytest.approx(reduction * hw.position[0], rel=1e-12)
    assert data.actuator_velocity[act] == pytest.approx(reduction * hw.velocity[0], rel=1e-9, abs=1e-15)


@pytest.mark.parametrize("reduction", [50.0, -50.0])
def test_the_effort_limit_is_the_joints_and_the_actuators_is_it_over_the_reduction(one_dof, reduction):
    hw = hardware(geared(one_dof, reduction))
    act = int(hw.world.actuator_ids[0])
    assert list(hw.world.model.actuator_forcerange[act]) == pytest.approx([-LIMIT_N / abs(reduction),
                                                                          LIMIT_N / abs(reduction)])
    hw.command_buffer(EFFORT)[0] = 5000.0  # five times the joint's limit
    hw.write()
    hw.advance(0.001)
    hw.read()
    assert hw.effort[0] == pytest.approx(LIMIT_N, rel=1e-12)
    assert hw.world.data.actuator_force[act] == pytest.approx(LIMIT_N / reduction, rel=1e-12)


def test_a_transmission_jointctl_cannot_model_is_refused_in_one_line(one_dof):
    with pytest.raises(ModelError) as caught:
        hardware(geared(one_dof, 1.0, "transmission_interface/DifferentialTransmission"))
    assert caught.value.field.endswith(".type") and "SimpleTransmission" in str(caught.value)
    assert caught.value.value == "transmission_interface/DifferentialTransmission"

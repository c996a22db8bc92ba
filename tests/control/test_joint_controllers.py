"""Tests of effort_controllers/JointPositionController and JointVelocityController."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from jointctl.control import JointPositionController, JointVelocityController, controller_types
from jointctl.control.manager import ControllerManager
from jointctl.control.params import Params
from jointctl.errors import ConfigError, InvalidCommand
from jointctl.hardware.interface import EFFORT
from jointctl.model.robot_model import Joint, Link, RobotModel

from .conftest import NAMESPACE, POSITION_YAML, VELOCITY_YAML, FakeHardware

DT = 0.001
POSITION_TYPE = "effort_controllers/JointPositionController"
VELOCITY_TYPE = "effort_controllers/JointVelocityController"
BAD_COMMANDS = [math.nan, math.inf, -math.inf, "0.1", None, True, False, [0.1]]


def build(definition: dict[str, Any], hardware, robot, name: str = "ctl"):
    """Build and configure a controller from a YAML-like definition, as the manager does."""
    params = Params(definition, source="test.yaml", field=f"{NAMESPACE}.{name}")
    controller = controller_types()[definition["type"]](name, params)
    controller.configure(hardware, robot)
    return controller


def position_controller(hardware, robot, **pid) -> JointPositionController:
    return build({"type": POSITION_TYPE, "joint": "joint1", "pid": pid}, hardware, robot)


def velocity_controller(hardware, robot, **pid) -> JointVelocityController:
    return build({"type": VELOCITY_TYPE, "joint": "joint1", "pid": pid}, hardware, robot)


def effort(hardware) -> float:
    return hardware.command_buffer(EFFORT)[0]


@pytest.fixture
def chapter_position(hardware, robot) -> JointPositionController:
    manager = ControllerManager(hardware, robot)
    manager.load_file(POSITION_YAML)
    return manager.load("joint1_position_controller")


@pytest.fixture
def chapter_velocity(hardware, robot) -> JointVelocityController:
    manager = ControllerManager(hardware, robot)
    manager.load_file(VELOCITY_YAML)
    return manager.load("joint1_velocity_controller")


# == JointPositionController ============================================================
def test_position_controller_from_the_chapter_yaml(chapter_position) -> None:
    c = chapter_position
    assert isinstance(c, JointPositionController)
    assert c.joint == "joint1" and c.joints == ("joint1",)
    g = c.pid.gains
    assert (g.p, g.i, g.d) == (400.0, 0.0, 0.0)
    assert (g.i_clamp_min, g.i_clamp_max) == (-1000.0, 1000.0)  # defaults to the effort limit
    assert c.pid.output_limit == 1000.0
    assert (c.lower, c.upper, c.effort_limit, c.velocity_limit) == (-1.0, 0.0, 1000.0, 100.0)
    assert c.field == f"{NAMESPACE}.joint1_position_controller"
    assert c.source == str(POSITION_YAML)


def test_position_controller_claims_joint1_effort(chapter_position) -> None:
    assert chapter_position.claimed_interfaces() == (("joint1", "effort"),)


def test_position_controller_writes_into_the_hardware_effort_buffer(hardware, chapter_position) -> None:
    assert chapter_position.effort_command is hardware.command_buffer(EFFORT)


def test_position_effort_is_p_times_position_error(hardware, chapter_position) -> None:
    c = chapter_position
    hardware.set_state("joint1", -0.2, 0.0)
    c.set_reference(-0.5)
    c.update(0.0, DT)
    assert effort(hardware) == pytest.approx(400.0 * (-0.5 - -0.2))  # -120 N
    assert c.reference == -0.5
    hardware.set_state("joint1", -0.7, 3.0)  # d = 0: the velocity does not matter
    c.update(DT, DT)
    assert effort(hardware) == pytest.approx(80.0)


def test_position_effort_d_acts_on_velocity_error(hardware, robot) -> None:
    c = position_controller(hardware, robot, p=400.0, d=20.0)
    hardware.set_state("joint1", -0.2, 0.3)
    c.set_reference(-0.5, 0.1)
    c.update(0.0, DT)
    # 400 * (-0.5 + 0.2) + 20 * (0.1 - 0.3) = -120 - 4
    assert effort(hardware) == pytest.approx(-124.0)
    assert c.reference_input == (-0.5, 0.1, 0.0)


def test_position_step_has_no_derivative_kick_with_derivative_on_measurement(hardware, robot) -> None:
    c = build({"type": POSITION_TYPE, "joint": "joint1", "pid": {"p": 400.0, "d": 20.0},
               "derivative": "measurement"}, hardware, robot)
    hardware.set_state("joint1", -0.2, 0.0)
    c.set_reference(-0.2)
    c.update(0.0, DT)
    assert effort(hardware) == pytest.approx(0.0)
    c.set_reference(-0.6)  # a step of 0.4 m in one period
    c.update(DT, DT)
    assert effort(hardware) == pytest.approx(-160.0)  # p only, no 0.4/dt * d spike


@pytest.mark.parametrize(
    ("command", "reference", "expected_effort"),
    [
        (0.5, 0.0, 400.0 * 0.2),     # above the upper limit 0
        (-3.0, -1.0, 400.0 * -0.8),  # below the lower limit -1
        (0.0, 0.0, 80.0),
        (-1.0, -1.0, -320.0),
        (-0.45, -0.45, -100.0),
    ],
)
def test_position_command_clamped_to_joint_limits(hardware, chapter_position, command, reference,
                                                  expected_effort) -> None:
    hardware.set_state("joint1", -0.2)
    chapter_position.set_reference(command)
    chapter_position.update(0.0, DT)
    assert chapter_position.reference == reference
    assert chapter_position.reference_input == (command, 0.0, 0.0)  # the command is kept as given
    assert effort(hardware) == pytest.approx(expected_effort)


def test_position_output_clamped_to_the_effort_limit(hardware, robot) -> None:
    c = position_controller(hardware, robot, p=4000.0)
    hardware.set_state("joint1", -1.0)
    c.set_reference(0.0)
    c.update(0.0, DT)
    assert effort(hardware) == 1000.0  # 4000 N asked
    hardware.set_state("joint1", 0.0)
    c.set_reference(-1.0)
    c.update(DT, DT)
    assert effort(hardware) == -1000.0
    hardware.set_state("joint1", -0.9)
    c.update(2 * DT, DT)
    assert effort(hardware) == pytest.approx(-400.0)  # unsaturated in between


def test_position_start_holds_the_current_position(hardware, chapter_position) -> None:
    c = chapter_position
    c.set_reference(-0.9)
    hardware.set_state("joint1", -0.37, 0.2)
    reads = hardware.reads
    c.start(0.0)
    assert hardware.reads == reads + 1  # it reads the hardware before taking the position
    assert c.reference_input == (-0.37, 0.0, 0.0)
    hardware.velocity[0] = 0.0
    c.update(0.0, DT)
    assert c.reference == -0.37
    assert effort(hardware) == pytest.approx(0.0)


def test_position_start_resets_the_integral(hardware, robot) -> None:
    c = position_controller(hardware, robot, p=0.0, i=100.0)
    hardware.set_state("joint1", -0.5)
    c.start(0.0)
    c.set_reference(-0.4)
    for k in range(10):
        c.update(k * DT, DT)
    assert c.pid.i_state == pytest.approx(100.0 * 0.1 * 10 * DT)
    c.start(1.0)
    assert c.pid.i_state == 0.0


@pytest.mark.parametrize("bad", BAD_COMMANDS, ids=repr)
def test_position_set_reference_refuses_non_finite_numbers(chapter_position, bad) -> None:
    c = chapter_position
    c.set_reference(-0.4, 0.05)
    with pytest.raises(InvalidCommand) as info:
        c.set_reference(bad)
    assert info.value.field == "reference.position"
    assert info.value.source == "joint1_position_controller"
    assert c.reference_input == (-0.4, 0.05, 0.0)
    with pytest.raises(InvalidCommand) as info:
        c.set_reference(-0.1, bad)
    assert info.value.field == "reference.velocity"
    assert c.reference_input == (-0.4, 0.05, 0.0)  # neither half of the refused command was taken


def test_position_set_reference_accepts_ints_and_numpy_floats(chapter_position) -> None:
    c = chapter_position
    c.set_reference(0)
    assert c.reference_input == (0.0, 0.0, 0.0) and type(c.reference_input[0]) is float
    c.set_reference(np.float64(-0.25), np.float64(0.5))
    assert c.reference_input == (-0.25, 0.5, 0.0)


def test_position_controller_closes_the_loop_on_a_double_integrator(hardware, robot) -> None:
    # Unit mass, p = 400 N/m, d = 40 N s/m: critically damped at 20 rad/s.
    c = position_controller(hardware, robot, p=400.0, d=40.0)
    hardware.set_state("joint1", -0.2)
    c.start(0.0)
    c.set_reference(-0.5)
    peak = 0.0
    lowest = 0.0
    for k in range(2000):
        c.update(k * DT, DT)
        hardware.write()
        hardware.advance(DT)
        peak = max(peak, abs(effort(hardware)))
        lowest = min(lowest, hardware.position[0])
    assert hardware.position[0] == pytest.approx(-0.5, abs=1e-6)
    assert lowest > -0.5 - 1e-3  # no overshoot to speak of
    assert peak == pytest.approx(120.0)  # the first period: 400 * 0.3


# -- configuration refusals ------------------------------------------------------------------
def test_missing_joint_is_refused(hardware, robot) -> None:
    with pytest.raises(ConfigError) as info:
        build({"type": POSITION_TYPE, "pid": {"p": 1.0}}, hardware, robot)
    assert info.value.field == f"{NAMESPACE}.ctl.joint"
    assert "required" in info.value.message


def test_unknown_controller_key_is_refused(hardware, robot) -> None:
    with pytest.raises(ConfigError) as info:
        build({"type": POSITION_TYPE, "joint": "joint1", "joints": ["joint1"]}, hardware, robot)
    assert info.value.field == f"{NAMESPACE}.ctl.joints"
    assert info.value.value == ["joint1"]


def test_bad_gain_is_refused_naming_the_pid_field(hardware, robot) -> None:
    with pytest.raises(ConfigError) as info:
        position_controller(hardware, robot, p=-400.0)
    assert info.value.field == f"{NAMESPACE}.ctl.pid.p"
    assert info.value.value == -400.0
    assert info.value.source == "test.yaml"


def test_pid_must_be_a_mapping(hardware, robot) -> None:
    with pytest.raises(ConfigError) as info:
        build({"type": POSITION_TYPE, "joint": "joint1", "pid": 400}, hardware, robot)
    assert info.value.field == f"{NAMESPACE}.ctl.pid"


def test_no_pid_entry_means_zero_gains(hardware, robot) -> None:
    c = build({"type": POSITION_TYPE, "joint": "joint1"}, hardware, robot)
    g = c.pid.gains
    assert (g.p, g.i, g.d, g.i_clamp_max) == (0.0, 0.0, 0.0, 1000.0)


def test_joint_unknown_to_the_hardware_is_refused(hardware, robot) -> None:
    with pytest.raises(ConfigError) as info:
        build({"type": POSITION_TYPE, "joint": "joint7"}, hardware, robot)
    assert info.value.field == f"{NAMESPACE}.ctl.joint"
    assert info.value.value == "joint7"
    assert info.value.source == "test.yaml"


def test_joint_without_effort_interface_is_refused(robot) -> None:
    hw = FakeHardware(("joint1",), effort_joints=())
    with pytest.raises(ConfigError) as info:
        build({"type": VELOCITY_TYPE, "joint": "joint1"}, hw, robot)
    assert info.value.field == f"{NAMESPACE}.ctl.joint"
    assert info.value.value == "joint1"
    assert "effort" in info.value.message


def test_joint_on_the_hardware_but_not_in_the_model_is_refused_with_config_error(robot) -> None:
    hw = FakeHardware(("joint1", "joint9"))
    with pytest.raises(ConfigError) as info:
        build({"type": POSITION_TYPE, "joint": "joint9"}, hw, robot)
    assert info.value.field == f"{NAMESPACE}.ctl.joint"
    assert info.value.value == "joint9"


# -- a joint without limits ----------------------------------------------------------------
def wheel_robot() -> RobotModel:
    return RobotModel(
        name="wheel_bot",
        links=(Link("base"), Link("wheel")),
        joints=(Joint("wheel", "continuous", "base", "wheel", axis=(0.0, 0.0, 1.0), limits=None),),
    )


def test_a_joint_without_limits_clamps_nothing() -> None:
    hw = FakeHardware(("wheel",))
    robot = wheel_robot()
    c = build({"type": POSITION_TYPE, "joint": "wheel", "pid": {"p": 1e3}}, hw, robot)
    c.set_reference(50.0)
    c.update(0.0, DT)
    assert c.reference == 50.0
    # A continuous joint servos the shortest way round: 50 rad is 8 turns less 0.27 rad.
    assert effort(hw) == pytest.approx(1e3 * (50.0 - 16 * math.pi))
    v = build({"type": VELOCITY_TYPE, "joint": "wheel", "pid": {"p": 1.0}}, hw, robot)
    v.set_reference(1e4)
    v.update(0.0, DT)
    assert v.reference == 1e4


def test_i_gain_works_without_i_clamp_on_a_joint_without_limits() -> None:
    hw = FakeHardware(("wheel",))
    c = build({"type": VELOCITY_TYPE, "joint": "wheel", "pid": {"p": 0.0, "i": 5.0}}, hw,
              wheel_robot())
    c.start(0.0)
    c.set_reference(1.0)
    for k in range(10):
        c.update(k * 0.01, 0.01)
    assert effort(hw) == pytest.approx(5.0 * 1.0 * 0.01 * 10)


# == JointVelocityController ============================================================
def test_velocity_controller_from_the_chapter_yaml(chapter_velocity) -> None:
    c = chapter_velocity
    assert isinstance(c, JointVelocityController)
    assert (c.pid.gains.p, c.pid.gains.i, c.pid.gains.d) == (200.0, 0.0, 0.0)
    assert c.pid.output_limit == 1000.0
    assert c.velocity_limit == 100.0
    assert c.claimed_interfaces() == (("joint1", "effort"),)


def test_velocity_effort_is_p_times_velocity_error(hardware, chapter_velocity) -> None:
    c = chapter_velocity
    hardware.set_state("joint1", -0.5, 0.3)
    c.set_reference(1.0)
    c.update(0.0, DT)
    assert effort(hardware) == pytest.approx(200.0 * (1.0 - 0.3))  # 140 N
    assert c.reference == 1.0
    hardware.set_state("joint1", -0.9, -0.2)  # the position does not matter
    c.set_reference(-0.5)
    c.update(DT, DT)
    assert effort(hardware) == pytest.approx(-60.0)


@pytest.mark.parametrize(("command", "reference"), [(500.0, 100.0), (-500.0, -100.0),
                                                    (100.0, 100.0), (-99.5, -99.5)])
def test_velocity_command_clamped_to_the_velocity_limit(hardware, robot, command, reference) -> None:
    c = velocity_controller(hardware, robot, p=5.0)
    c.set_reference(command)
    c.update(0.0, DT)
    assert c.reference == reference
    assert c.reference_input == command
    assert effort(hardware) == pytest.approx(5.0 * reference)


def test_velocity_output_clamped_to_the_effort_limit(hardware, chapter_velocity) -> None:
    chapter_velocity.set_reference(50.0)
    chapter_velocity.update(0.0, DT)
    assert effort(hardware) == 1000.0  # 200 * 50 = 10000 asked
    chapter_velocity.set_reference(-50.0)
    chapter_velocity.update(DT, DT)
    assert effort(hardware) == -1000.0


def test_velocity_start_resets_the_command_to_zero(hardware, chapter_velocity) -> None:
    c = chapter_velocity
    c.set_reference(2.0)
    hardware.set_state("joint1", -0.5, 0.5)
    c.start(0.0)
    assert c.reference_input == 0.0
    c.update(0.0, DT)
    assert c.reference == 0.0
    assert effort(hardware) == pytest.approx(-100.0)  # 200 * (0 - 0.5)


def test_velocity_d_acts_on_the_backward_difference_of_the_error(hardware, robot) -> None:
    c = velocity_controller(hardware, robot, p=0.0, d=2.0)
    c.start(0.0)
    c.set_reference(1.0)
    hardware.set_state("joint1", 0.0, 0.0)
    c.update(0.0, 0.01)  # error 1
    hardware.set_state("joint1", 0.0, 0.5)
    c.update(0.01, 0.01)  # error 0.5: rate (0.5 - 1) / 0.01 = -50
    assert effort(hardware) == pytest.approx(-100.0)
    c.update(0.02, 0.01)  # error unchanged: no derivative term
    assert effort(hardware) == pytest.approx(0.0)


@pytest.mark.parametrize("bad", BAD_COMMANDS, ids=repr)
def test_velocity_set_reference_refuses_non_finite_numbers(chapter_velocity, bad) -> None:
    c = chapter_velocity
    c.set_reference(0.75)
    with pytest.raises(InvalidCommand) as info:
        c.set_reference(bad)
    assert info.value.field == "reference"
    assert info.value.source == "joint1_velocity_controller"
    assert c.reference_input == 0.75


def test_velocity_controller_tracks_on_a_double_integrator(hardware, chapter_velocity) -> None:
    c = chapter_velocity
    c.start(0.0)
    c.set_reference(-0.8)
    for k in range(200):
        c.update(k * DT, DT)
        hardware.write()
        hardware.advance(DT)
    assert hardware.velocity[0] == pytest.approx(-0.8, abs=1e-6)  # time constant m/p = 5 ms

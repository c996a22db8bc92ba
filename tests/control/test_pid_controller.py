"""``pid_controller/PidController`` computing as ros2_controllers 4.18 (``pid_controller.cpp``) with control_toolbox
3.4.0: numbers worked by hand from that source, and its doors."""

from __future__ import annotations

import math

import pytest

from jointctl.control.manager import ControllerManager
from jointctl.control.pid_controller import DofState, PidController
from jointctl.errors import ConfigError, InvalidCommand
from jointctl.hardware.interface import EFFORT, POSITION, VELOCITY, HardwareInterface
from jointctl.model.urdf_parser import parse_urdf
from tests.control.conftest import FakeHardware

H = 0.01  # 100 Hz
TWO_JOINTS = parse_urdf("""<robot name="two">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="joint1" type="continuous"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/></joint>
  <joint name="joint2" type="prismatic"><parent link="a"/><child link="b"/>
    <limit lower="-1" upper="1" effort="100" velocity="5"/></joint>
</robot>""", source="two.urdf")


def ros2_file(pid: dict, *, update_rate: int = 100) -> dict:
    return {"controller_manager": {"ros__parameters": {
                "update_rate": update_rate, "pid_controller": {"type": "pid_controller/PidController"}}},
            "pid_controller": {"ros__parameters": pid}}


def pid_params(**changes) -> dict:
    params = {"dof_names": ["joint1"], "command_interface": "effort", "reference_and_state_interfaces": ["position"],
              "gains": {"joint1": {"p": 2.0, "d": 0.5}}}
    params.update(changes)
    return params


def started(write_yaml, hardware: HardwareInterface, **changes) -> tuple[ControllerManager, PidController]:
    manager = ControllerManager(hardware, TWO_JOINTS)
    manager.load_file(write_yaml(ros2_file(pid_params(**changes))))
    manager.start(["pid_controller"])
    return manager, manager.controller("pid_controller")


@pytest.fixture
def hardware() -> FakeHardware:
    return FakeHardware(("joint1", "joint2"))


def test_before_a_reference_it_writes_nothing_and_reports_nan(write_yaml, hardware):
    manager, pid = started(write_yaml, hardware)
    effort = hardware.command_buffer(EFFORT)
    effort[0] = 7.0  # what the hardware had
    hardware.set_state("joint1", 0.25)
    manager.update(0.0, H)
    assert effort[0] == 7.0
    (state,) = pid.latest_state.dof_states
    assert state.name == "joint1" and state.feedback == 0.25 and state.time_step == H
    assert math.isnan(state.reference) and math.isnan(state.error) and math.isnan(state.output)
    assert state.feedback_dot == 0.0 and state.error_dot == 0.0  # one interface: left at the message's 0


def test_the_first_command_kicks_by_the_error_over_the_period_then_differentiates_the_error(write_yaml, hardware):
    manager, pid = started(write_yaml, hardware)
    hardware.set_state("joint1", 0.25)
    pid.set_reference([1.0])
    manager.update(0.0, H)
    effort = hardware.command_buffer(EFFORT)
    assert effort[0] == pytest.approx(2.0 * 0.75 + 0.5 * 0.75 / H, rel=1e-15)  # p_error_last was 0
    hardware.set_state("joint1", 0.35)
    manager.update(H, H)
    assert effort[0] == pytest.approx(2.0 * 0.65 + 0.5 * (0.65 - 0.75) / H, rel=1e-12)
    state = pid.latest_state.dof_states[0]
    assert (state.reference, state.feedback, state.error) == (1.0, 0.35, pytest.approx(0.65))
    assert state.output == effort[0]


def test_two_interfaces_take_the_derivative_error_from_the_references_and_the_states_rates(write_yaml, hardware):
    gains = {"joint1": {"p": 2.0, "d": 0.5, "feedforward_gain": 3.0}}
    manager, pid = started(write_yaml, hardware, reference_and_state_interfaces=["position", "velocity"], gains=gains)
    hardware.set_state("joint1", 0.25, velocity=0.4)
    pid.set_reference([1.0])  # no values_dot: the derivative falls back to the error's difference
    manager.update(0.0, H)
    effort = hardware.command_buffer(EFFORT)
    assert effort[0] == pytest.approx(2.0 * 0.75 + 0.5 * 0.75 / H, rel=1e-15)
    pid.set_reference([1.0], [0.1])
    manager.update(H, H)
    assert effort[0] == pytest.approx(2.0 * 0.75 + 0.5 * (0.1 - 0.4), rel=1e-15)
    state = pid.latest_state.dof_states[0]
    assert state.feedback_dot == 0.4 and state.error_dot == pytest.approx(0.1 - 0.4)
    pid.set_feedforward(True)  # ~/set_feedforward_control: + feedforward_gain · values_dot
    manager.update(2 * H, H)
    assert effort[0] == pytest.approx(3.0 * 0.1 + 2.0 * 0.75 + 0.5 * (0.1 - 0.4), rel=1e-15)


def test_nan_keeps_a_dofs_reference_and_names_reorder_the_values(write_yaml, hardware):
    gains = {"joint1": {"p": 1.0}, "joint2": {"p": 10.0}}
    manager, pid = started(write_yaml, hardware, dof_names=["joint1", "joint2"], gains=gains)
    pid.set_reference([0.5, -0.5], dof_names=["joint2", "joint1"])
    manager.update(0.0, H)
    effort = hardware.command_buffer(EFFORT)
    assert effort[:2] == [pytest.approx(-0.5), pytest.approx(5.0)]
    pid.set_reference([math.nan, 0.2])
    manager.update(H, H)
    assert effort[:2] == [pytest.approx(-0.5), pytest.approx(2.0)]
    assert [s.reference for s in pid.latest_state.dof_states] == [-0.5, 0.2]


@pytest.mark.parametrize(("call", "field"), [
    (lambda pid: pid.set_reference([1.0, 2.0]), "reference.values"),
    (lambda pid: pid.set_reference([math.inf]), "reference.values[0]"),
    (lambda pid: pid.set_reference(["up"]), "reference.values[0]"),
    (lambda pid: pid.set_reference([1.0], [0.5]), "reference.values_dot"),
    (lambda pid: pid.set_reference([1.0], dof_names=["joint9"]), "reference.dof_names"),
    (lambda pid: pid.set_feedforward(True), "feedforward"),
    (lambda pid: pid.set_measured_state([0.0]), "measured_state"),
    (lambda pid: pid.set_parameter("dof_names", ["joint2"]), "dof_names"),
    (lambda pid: pid.set_parameter("gains.joint1.q", 1.0), "gains.joint1.q"),
    (lambda pid: pid.set_parameter("gains.joint1.i_clamp_min", 1.0), "gains.joint1.i_clamp_min"),
    (lambda pid: pid.set_parameter("gains.joint1.antiwindup", 1), "gains.joint1.antiwindup"),
    (lambda pid: pid.set_gains("joint2", p=1.0), "gains"),
])
def test_a_refused_door_call_names_the_field_and_changes_nothing(write_yaml, hardware, call, field):
    manager, pid = started(write_yaml, hardware)
    pid.set_reference([1.0])
    manager.update(0.0, H)
    with pytest.raises(InvalidCommand) as info:
        call(pid)
    assert info.value.field == field and info.value.source == "pid_controller"
    manager.update(H, H)
    assert pid.reference == [1.0] and pid.gains[0].p == 2.0 and pid.feedforward is False


def test_a_gain_set_by_its_parameter_name_applies_at_the_next_cycle_keeping_the_integral(write_yaml, hardware):
    gains = {"joint1": {"p": 0.0, "i": 1.0, "i_clamp_max": 10.0, "i_clamp_min": -10.0}}
    manager, pid = started(write_yaml, hardware, gains=gains)
    pid.set_reference([1.0])
    for k in range(10):  # error 1 for 0.1 s
        manager.update(k * H, H)
    effort = hardware.command_buffer(EFFORT)
    assert effort[0] == pytest.approx(0.1, rel=1e-12)
    pid.set_parameter("gains.joint1.i", 2.0)  # ros2 param set /pid_controller gains.joint1.i 2.0
    manager.update(10 * H, H)
    assert effort[0] == pytest.approx(2.0 * 0.11, rel=1e-12)


def test_angle_wraparound_takes_the_short_way_round(write_yaml, hardware):
    manager, pid = started(write_yaml, hardware, gains={"joint1": {"p": 1.0, "angle_wraparound": True}})
    hardware.set_state("joint1", -3.0)
    pid.set_reference([3.0])
    manager.update(0.0, H)
    assert hardware.command_buffer(EFFORT)[0] == pytest.approx(6.0 - 2 * math.pi, abs=1e-12)
    assert pid.latest_state.dof_states[0].error == pytest.approx(6.0 - 2 * math.pi, abs=1e-12)


def test_started_again_its_reference_is_nan_and_its_integral_carries_over(write_yaml, hardware):
    # ros2_controllers 4.18's on_activate clears the references, not the PIDs.
    manager, pid = started(write_yaml, hardware, gains={"joint1": {"i": 1.0, "i_clamp_max": 10.0,
                                                                   "i_clamp_min": -10.0}})
    pid.set_reference([1.0])
    for k in range(10):
        manager.update(k * H, H)
    manager.stop(["pid_controller"])
    manager.start(["pid_controller"])
    effort = hardware.command_buffer(EFFORT)
    manager.update(0.2, H)
    assert math.isnan(pid.latest_state.dof_states[0].reference) and effort[0] == pytest.approx(0.1)
    pid.set_reference([1.0])
    manager.update(0.21, H)
    assert effort[0] == pytest.approx(0.11, rel=1e-12)


def test_an_external_measured_state_replaces_the_hardwares(write_yaml, hardware):
    manager, pid = started(write_yaml, hardware, use_external_measured_states=True, gains={"joint1": {"p": 1.0}})
    pid.set_reference([1.0])
    manager.update(0.0, H)
    assert math.isnan(pid.latest_state.dof_states[0].feedback)  # nothing measured yet: no command
    pid.set_measured_state([0.4])
    manager.update(H, H)
    assert hardware.command_buffer(EFFORT)[0] == pytest.approx(0.6)


class MockVelocityJoints(HardwareInterface):
    """mock_components/GenericSystem with calculate_dynamics, as the control_demo runs it: a velocity command is the
    velocity, integrated into the position over each period; a position command is the position."""

    def __init__(self, joints):
        super().__init__(joints)

    def command_interfaces(self, joint):
        return frozenset({VELOCITY, POSITION})

    def read(self):
        pass

    def write(self):
        pass

    def advance(self, period_s):
        velocity = self.command_buffer(VELOCITY)
        for k in range(len(self.joint_names)):
            self.velocity[k] = velocity[k]
            self.position[k] += velocity[k] * period_s


def test_the_control_demo_pid_drives_a_velocity_joint_as_on_ros2_controls_mock(tmp_path):
    from tests.model.test_ros2_control import CONTROL_DEMO

    hardware = MockVelocityJoints(("joint1", "joint2"))
    manager = ControllerManager(hardware, TWO_JOINTS)
    manager.load_file(CONTROL_DEMO.parent / "controllers.yaml")
    assert manager.update_rate_hz == 100
    manager.start(["pid_controller"])
    pid = manager.controller("pid_controller")
    pid.set_reference([1.0])
    for k in range(200):  # 2 s at 100 Hz of u = 2·(1 - q), q += 0.01·u: 1 - 0.98^k
        manager.update(k * H, H)
        hardware.advance(H)
    assert hardware.position[0] == pytest.approx(1.0 - 0.98 ** 200, rel=1e-12)


def test_a_command_interface_the_hardware_lacks_is_refused_naming_joint_and_interface(write_yaml, hardware):
    manager = ControllerManager(hardware, TWO_JOINTS)
    manager.load_file(write_yaml(ros2_file(pid_params(command_interface="velocity"))))
    with pytest.raises(ConfigError) as info:
        manager.load("pid_controller")
    assert info.value.field == "pid_controller.ros__parameters.command_interface"
    assert info.value.value == "velocity" and "'joint1'" in str(info.value)


@pytest.mark.parametrize(("changes", "field", "value"), [
    ({"dof_names": []}, "dof_names", []),
    ({"dof_names": ["joint1", "joint1"]}, "dof_names", "joint1"),
    ({"reference_and_state_interfaces": ["position", "velocity", "effort"]}, "reference_and_state_interfaces",
     ["position", "velocity", "effort"]),
    ({"reference_and_state_dof_names": ["joint1", "joint2"]}, "reference_and_state_dof_names", ["joint1", "joint2"]),
    ({"gains": {"joint1": {"i_clamp_min": 1.0, "i_clamp_max": -1.0}}}, "gains.joint1.i_clamp_min", 1.0),
    ({"gains": {"joint1": {"p": 1.0, "pp": 2.0}}}, "gains.joint1.pp", 2.0),
    ({"gains": {"joint3": {"p": 1.0}}}, "gains.joint3", {"p": 1.0}),
    ({"gains": {"joint1": {"antiwindup": "yes"}}}, "gains.joint1.antiwindup", "yes"),
])
def test_bad_parameters_are_refused_naming_the_field(write_yaml, hardware, changes, field, value):
    manager = ControllerManager(hardware, TWO_JOINTS)
    manager.load_file(write_yaml(ros2_file(pid_params(**changes))))
    with pytest.raises(ConfigError) as info:
        manager.load("pid_controller")
    assert info.value.field == f"pid_controller.ros__parameters.{field}" and info.value.value == value


def test_the_state_is_one_dof_state_per_dof_each_cycle(write_yaml, hardware):
    manager, pid = started(write_yaml, hardware)
    seen = []
    pid.subscribe(seen.append)
    pid.set_reference(0.5)  # a single number: every dof's (a scenario's command source)
    for k in range(3):
        manager.update(k * H, H)
    assert [s.time_s for s in seen] == [0.0, H, 2 * H]
    assert isinstance(seen[-1].dof_states[0], DofState) and seen[-1].dof_states[0].reference == 0.5


def test_the_trace_reference_is_the_pids_reference(write_yaml, hardware):
    manager, pid = started(write_yaml, hardware)
    pid.set_reference([0.5])
    manager.update(0.0, H)
    assert manager.references[0] == 0.5 and math.isnan(manager.references[1])

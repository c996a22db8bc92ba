"""``joint_trajectory_controller/JointTrajectoryController`` as ros2_controllers 4.18 computes it
(``joint_trajectory_controller.cpp``, ``tolerances.hpp``): the effort PID on the desired state, the command a
period ahead, trajectories from the measured state, its goal checks and tolerances, and the control_demo goal."""

from __future__ import annotations

import math

import pytest

from jointctl.control.manager import ControllerManager
from jointctl.errors import ConfigError
from jointctl.hardware.interface import EFFORT, POSITION, VELOCITY, HardwareInterface
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.executor import GoalStatus
from jointctl.trajectory.joint_trajectory_controller import JointTrajectoryController
from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint
from tests.control.conftest import FakeHardware, write_yaml
from tests.control.test_pid_controller import TWO_JOINTS
from tests.model.test_ros2_control import CONTROL_DEMO
from tests.servoed_hardware import ServoedHardware

H = 0.01
write_yaml = write_yaml  # the control tests' fixture: a YAML file in tmp_path
JTC = "joint_trajectory_controller/JointTrajectoryController"


def jtc_params(**changes) -> dict:
    params = {"joints": ["joint2"], "command_interfaces": ["effort"], "state_interfaces": ["position", "velocity"],
              "gains": {"joint2": {"p": 100.0, "d": 10.0}}}
    params.update(changes)
    return params


def manager_for(write_yaml, hardware: HardwareInterface, **changes) -> ControllerManager:
    manager = ControllerManager(hardware, TWO_JOINTS)
    manager.load_file(write_yaml({"controller_manager": {"ros__parameters": {"update_rate": 100,
                                                                              "jtc": {"type": JTC}}},
                                  "jtc": {"ros__parameters": jtc_params(**changes)}}))
    return manager


def started(write_yaml, hardware, **changes) -> tuple[ControllerManager, JointTrajectoryController]:
    manager = manager_for(write_yaml, hardware, **changes)
    manager.start(["jtc"])
    return manager, manager.controller("jtc")


def goal(*points, joints=("joint2",), velocities=None) -> JointTrajectory:
    rows = [JointTrajectoryPoint(positions=(q,) if isinstance(q, float) else tuple(q),
                                 velocities=() if velocities is None else velocities[k], time_from_start_s=t)
            for k, (t, q) in enumerate(points)]
    return JointTrajectory(tuple(joints), tuple(rows))


def run(manager, cycles: int, start: int = 0, hardware=None) -> int:
    for k in range(start, start + cycles):
        manager.update(k * H, H)
        if hardware is not None:
            hardware.write()
            hardware.advance(H)
    return start + cycles


def test_holding_the_effort_is_controltoolboxs_pid_on_the_position_and_velocity_errors(write_yaml):
    hardware = FakeHardware(("joint1", "joint2"))
    manager, jtc = started(write_yaml, hardware, gains={"joint2": {"p": 100.0, "i": 50.0, "d": 10.0,
                                                                   "i_clamp": 0.3}})
    hardware.set_state("joint2", 0.1, velocity=0.2)  # it holds 0.0, where it started
    manager.update(0.0, H)
    effort = hardware.command_buffer(EFFORT)
    # e = -0.1, ė = -0.2; the integral 50·(0.01·-0.1) = -0.05 within ±0.3
    assert effort[1] == pytest.approx(100.0 * -0.1 - 0.05 + 10.0 * -0.2, rel=1e-12)
    for k in range(1, 20):  # the integral term stops at -i_clamp (no antiwindup: it is the term that is clamped)
        manager.update(k * H, H)
    assert effort[1] == pytest.approx(100.0 * -0.1 - 0.3 + 10.0 * -0.2, rel=1e-12)
    assert jtc.pids[0].i_error == pytest.approx(20 * H * -0.1, rel=1e-9)


def test_a_trajectory_starts_from_the_measured_state_unless_open_loop(write_yaml):
    for open_loop, start in ((False, 0.2), (True, 0.0)):
        hardware = FakeHardware(("joint1", "joint2"))
        manager, jtc = started(write_yaml, hardware, open_loop_control=open_loop)
        hardware.set_state("joint2", 0.2)  # it drifted from where it was held (0.0)
        jtc.submit(goal((1.0, 0.5)), now_s=0.0)
        manager.update(0.0, H)  # the goal is taken up this cycle: its first desired state
        assert jtc.desired[0] == start, open_loop  # the point before the trajectory, at this cycle's time
        manager.update(H, H)
        assert jtc.desired[0] == pytest.approx(start + (0.5 - start) * H / 1.0, abs=1e-12), open_loop


def test_a_position_command_is_the_desired_position_a_period_ahead(write_yaml):
    hardware = ServoedHardware(("joint1", "joint2"))
    manager, jtc = started(write_yaml, hardware, command_interfaces=["position"], state_interfaces=["position"])
    jtc.submit(goal((1.0, 0.5)), now_s=0.0)
    run(manager, 30, hardware=hardware)
    desired = jtc.desired[0]
    assert hardware.sent[-1][1] == pytest.approx(desired + 0.5 * H, abs=1e-12)  # linear, 0.5 per s


def test_the_stopped_velocity_is_checked_at_the_goal_without_a_goal_tolerance(write_yaml):
    hardware = FakeHardware(("joint1", "joint2"))
    manager, jtc = started(write_yaml, hardware)
    handle = jtc.submit(goal((0.1, 0.0)), now_s=0.0)
    hardware.set_state("joint2", 0.0, velocity=0.05)  # held still by the test: moving at 0.05 > 0.01
    k = run(manager, 100)
    assert handle.status is GoalStatus.ACTIVE  # goal_time 0: it waits
    hardware.set_state("joint2", 0.3, velocity=0.005)  # far off, but slower than 0.01: no position tolerance
    run(manager, 1, k)
    assert handle.status is GoalStatus.SUCCEEDED and handle.result.error_code is TrajectoryErrorCode.SUCCESSFUL


def test_a_goal_time_aborts_a_goal_outside_its_tolerance(write_yaml):
    hardware = FakeHardware(("joint1", "joint2"))
    constraints = {"goal_time": 0.5, "joint2": {"goal": 0.01}}
    manager, jtc = started(write_yaml, hardware, constraints=constraints)
    handle = jtc.submit(goal((0.1, 0.2)), now_s=0.0)
    hardware.set_state("joint2", 0.1)  # held 0.1 off its goal
    run(manager, 60)  # the last point at 0.1 s, + 0.5 s
    assert handle.status is GoalStatus.ACTIVE
    run(manager, 2, 60)
    assert handle.status is GoalStatus.ABORTED
    assert handle.result.error_code is TrajectoryErrorCode.GOAL_TOLERANCE_VIOLATED


def test_a_path_tolerance_aborts_a_straying_goal(write_yaml):
    hardware = FakeHardware(("joint1", "joint2"))
    manager, jtc = started(write_yaml, hardware, constraints={"joint2": {"trajectory": 0.05}})
    handle = jtc.submit(goal((1.0, 0.5)), now_s=0.0)
    run(manager, 30)  # held still by the test while the desired position moves on at 0.5 per s
    assert handle.status is GoalStatus.ABORTED
    assert handle.result.error_code is TrajectoryErrorCode.PATH_TOLERANCE_VIOLATED


def test_a_partial_goal_and_a_moving_end_are_refused_unless_allowed(write_yaml):
    hardware = FakeHardware(("joint1", "joint2"))
    manager, jtc = started(write_yaml, hardware, joints=["joint1", "joint2"],
                           gains={"joint1": {"p": 10.0}, "joint2": {"p": 10.0}})
    with pytest.raises(InvalidTrajectory) as info:
        jtc.submit(goal((1.0, 0.5)), now_s=0.0)
    assert info.value.error_code is TrajectoryErrorCode.INVALID_JOINTS
    with pytest.raises(InvalidTrajectory) as info:
        jtc.submit(goal((1.0, (0.1, 0.5)), joints=("joint1", "joint2"), velocities=[(0.0, 0.1)]), now_s=0.0)
    assert info.value.error_code is TrajectoryErrorCode.INVALID_GOAL and info.value.joint == "joint2"
    assert [h.status for h in jtc.goals.history] == [GoalStatus.REJECTED] * 2
    manager, jtc = started(write_yaml, FakeHardware(("joint1", "joint2")), joints=["joint1", "joint2"],
                           allow_partial_joints_goal=True, allow_nonzero_velocity_at_trajectory_end=True)
    jtc.submit(goal((1.0, 0.5)), now_s=0.0)
    jtc.submit(goal((1.0, (0.1, 0.5)), joints=("joint1", "joint2"), velocities=[(0.0, 0.1)]), now_s=0.0)


class MockComponents(HardwareInterface):
    """mock_components/GenericSystem with calculate_dynamics, as the control_demo runs it: a joint's position
    command is its position; a velocity command its velocity, integrated over the period."""

    def __init__(self, commands: dict[str, str]) -> None:
        super().__init__(tuple(commands))
        self.commands = commands

    def command_interfaces(self, joint):
        return frozenset({self.commands[joint]})

    def read(self):
        pass

    def write(self):
        pass

    def advance(self, period_s):
        for k, joint in enumerate(self.joint_names):
            if self.commands[joint] == POSITION:
                command = self.command_buffer(POSITION)[k]
                self.velocity[k] = (command - self.position[k]) / period_s
                self.position[k] = command
            else:
                self.velocity[k] = self.command_buffer(VELOCITY)[k]
                self.position[k] += self.velocity[k] * period_s


def test_the_control_demo_goal_succeeds_on_its_position_joint():
    # The reference's run: send_goal joint2 -> 0.5 at 1 s: "Goal finished with status: SUCCEEDED", joint2 = 0.5.
    hardware = MockComponents({"joint1": VELOCITY, "joint2": POSITION})
    manager = ControllerManager(hardware, TWO_JOINTS)
    manager.load_file(CONTROL_DEMO.parent / "controllers.yaml")
    manager.start(["joint_state_broadcaster", "pid_controller", "joint_trajectory_controller"])
    jtc = manager.controller("joint_trajectory_controller")
    handle = jtc.submit(goal((1.0, 0.5)), now_s=0.0)
    k = 0
    while handle.status is not GoalStatus.SUCCEEDED and k < 200:
        manager.update(k * H, H)
        hardware.advance(H)
        k += 1
    assert handle.status is GoalStatus.SUCCEEDED and hardware.position[1] == pytest.approx(0.5, abs=1e-12)
    assert k * H == pytest.approx(1.0 + 2 * H, abs=1.5 * H)  # at the end, once the joint has stopped


@pytest.mark.parametrize(("changes", "field", "value"), [
    ({"command_interfaces": ["velocity"]}, "command_interfaces", ["velocity"]),
    ({"command_interfaces": ["position", "velocity"]}, "command_interfaces", ["position", "velocity"]),
    ({"state_interfaces": ["position"]}, "state_interfaces", ["position"]),
    ({"interpolation_method": "none"}, "interpolation_method", "none"),
    ({"cmd_timeout": 1.0}, "cmd_timeout", 1.0),
    ({"gains": {"joint2": {"p": 1.0, "i_clamp_max": 1.0}}}, "gains.joint2.i_clamp_max", 1.0),
    ({"gains": {"joint2": {"i_clamp": -1.0}}}, "gains.joint2.i_clamp", -1.0),
    ({"constraints": {"joint3": {"goal": 0.1}}}, "constraints.joint3", {"goal": 0.1}),
    ({"constraints": {"goal_time": -1.0}}, "constraints.goal_time", -1.0),
    ({"command_joints": ["joint1"]}, "command_joints", ["joint1"]),
    ({"allow_integration_in_goal_trajectories": True}, "allow_integration_in_goal_trajectories", True),
])
def test_bad_parameters_are_refused_naming_the_field(write_yaml, changes, field, value):
    manager = manager_for(write_yaml, FakeHardware(("joint1", "joint2")), **changes)
    with pytest.raises(ConfigError) as info:
        manager.load("jtc")
    assert info.value.field == f"jtc.ros__parameters.{field}" and info.value.value == value, str(info.value)


def test_a_command_interface_the_hardware_lacks_is_refused(write_yaml):
    manager = manager_for(write_yaml, FakeHardware(("joint1", "joint2")), command_interfaces=["position"],
                          state_interfaces=["position"])
    with pytest.raises(ConfigError) as info:
        manager.load("jtc")
    assert info.value.field == "jtc.ros__parameters.command_interfaces" and "'joint2'" in str(info.value)


def test_an_integer_tolerance_is_refused_as_ros2_refuses_it(write_yaml):
    with pytest.raises(ConfigError) as info:
        manager_for(write_yaml, FakeHardware(("joint1", "joint2")), constraints={"goal_time": 1})
    assert info.value.field == "jtc.ros__parameters.constraints.goal_time" and math.isfinite(info.value.value)

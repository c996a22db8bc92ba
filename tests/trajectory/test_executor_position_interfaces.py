"""The executor without position controllers: it commands the joints' position interfaces itself,
for hardware that servos its joints (an industrial controller), as ros_control's
position_controllers/JointTrajectoryController does."""

from __future__ import annotations

import math

import pytest
import yaml

from jointctl.control import ControllerManager
from jointctl.errors import ConfigError
from jointctl.hardware.interface import POSITION
from jointctl.model import load_robot_model
from jointctl.paths import robots_dir
from jointctl.runtime.loop import ControlLoop
from tests.servoed_hardware import ServoedHardware
from jointctl.trajectory.errors import InvalidTrajectory
from jointctl.trajectory.executor import GoalStatus
from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint

TRAJ = "arm7dof_trajectory_controller"
JOINTS = tuple(f"joint{k}" for k in range(7))


def servoed(start: float | None = None, **kwargs) -> ServoedHardware:
    return ServoedHardware(JOINTS, None if start is None else [start] * 7, **kwargs)


@pytest.fixture
def write_yaml(tmp_path):
    def write(content, name: str = "controllers.yaml"):
        path = tmp_path / name
        path.write_text(yaml.safe_dump(content, sort_keys=False))
        return path
    return write


@pytest.fixture(scope="module")
def arm():
    return load_robot_model(robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro")


def manager_of(hardware, arm, write_yaml, **changes) -> ControllerManager:
    executor = {"type": "trajectory_controllers/JointTrajectoryExecutor", "joints": list(JOINTS),
                "interpolation": "cubic", **changes}
    manager = ControllerManager(hardware, arm)
    manager.load_file(write_yaml({"arm7dof": {TRAJ: executor}}))
    return manager


def goal(q_end: list[float], t_s: float) -> JointTrajectory:
    return JointTrajectory(JOINTS, (JointTrajectoryPoint(positions=tuple(q_end), time_from_start_s=t_s),))


def test_it_claims_and_writes_the_position_interfaces(arm, write_yaml) -> None:
    hw = servoed(0.1)
    manager = manager_of(hw, arm, write_yaml)
    executor = manager.load(TRAJ)
    assert executor.claimed_interfaces() == tuple((j, POSITION) for j in JOINTS)
    assert executor.downstream == () and executor.joints == JOINTS
    manager.start([TRAJ])
    loop = ControlLoop(hw, manager)
    loop.run(cycles=1)
    assert hw.sent[-1] == [0.1] * 7  # holds where it starts
    target = [0.1, 0.3, -0.1, -0.2, 0.2, 0.3, 0.0]
    handle = executor.submit(goal(target, 4.0), now_s=loop.time_s)
    loop.run(2.0)
    # Halfway through a cubic from rest to rest: the midpoint (symmetric profile).
    midpoint = [0.1 + (q - 0.1) / 2 for q in target]
    assert hw.sent[-1] == pytest.approx(midpoint, abs=5e-3)
    assert manager.references == pytest.approx(hw.sent[-1], abs=1e-12)  # the trace's reference
    loop.run(3.0)
    assert hw.sent[-1] == pytest.approx(target, abs=1e-12)
    assert handle.status is GoalStatus.SUCCEEDED


def test_a_joint_without_a_position_interface_is_refused_naming_it(arm, write_yaml) -> None:
    manager = manager_of(servoed(interfaces={"effort"}), arm, write_yaml)
    with pytest.raises(ConfigError, match="no position command interface") as info:
        manager.load(TRAJ)
    assert info.value.field == f"arm7dof.{TRAJ}.joints[0]"
    assert info.value.value == "joint0"


def test_a_failing_executor_leaves_the_joints_holding_their_measured_position(arm, write_yaml) -> None:
    hw = servoed(0.2)
    manager = manager_of(hw, arm, write_yaml)
    executor = manager.load(TRAJ)
    manager.start([TRAJ])
    loop = ControlLoop(hw, manager)
    handle = executor.submit(goal([0.6] * 7, 3.0), now_s=0.0)
    loop.run(1.5)
    moving = list(hw.position)
    assert all(0.2 < q < 0.6 for q in moving)
    executor._plan.at = lambda t, dt: [math.nan] * 21  # a broken plan: non-finite positions this cycle
    loop.run(cycles=1)
    assert manager.failures and manager.failures[0].controller == TRAJ
    assert handle.status is GoalStatus.ABORTED
    assert hw.sent[-1] == pytest.approx(moving, abs=1e-12)  # the safe action: the measured position


def test_a_hardware_fault_aborts_the_goal_refuses_new_ones_and_holds(arm, write_yaml) -> None:
    hw = servoed(0.2)
    manager = manager_of(hw, arm, write_yaml)
    executor = manager.load(TRAJ)
    manager.start([TRAJ])
    loop = ControlLoop(hw, manager)
    handle = executor.submit(goal([0.6] * 7, 3.0), now_s=0.0)
    loop.run(1.5)
    assert handle.status is GoalStatus.ACTIVE
    hw.fault = "no joint state from 10.0.0.2:11002 for 1.0 s"
    loop.run(cycles=1)
    assert handle.status is GoalStatus.ABORTED
    assert "no joint state from 10.0.0.2:11002" in handle.result.error_string
    held = list(hw.position)
    loop.run(0.5)
    assert hw.sent[-1] == pytest.approx(held, abs=1e-12)  # holds the measured position
    with pytest.raises(InvalidTrajectory, match="the hardware cannot be commanded: no joint state"):
        executor.submit(goal([0.3] * 7, 3.0), now_s=loop.time_s)
    hw.fault = None  # the state flows again: goals are accepted and run from where the robot is
    again = executor.submit(goal([0.3] * 7, 3.0), now_s=loop.time_s)
    loop.run(4.0)
    assert again.status is GoalStatus.SUCCEEDED
    assert hw.sent[-1] == pytest.approx([0.3] * 7, abs=1e-12)


def running(hardware, arm, write_yaml, **changes):
    """The executor started on ``hardware`` and a loop to run it: (executor, loop)."""
    manager = manager_of(hardware, arm, write_yaml, **changes)
    executor = manager.load(TRAJ)
    manager.start([TRAJ])
    return executor, ControlLoop(hardware, manager)


class StoppingHardware(ServoedHardware):
    """Servoed joints that, on stop_motion, coast on by themselves for ``stop_cycles`` cycles (an
    industrial controller braking at its own limits) and report a fault meanwhile."""

    def __init__(self, *args, stop_cycles: int = 50, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.stop_calls = 0
        self.stop_cycles = stop_cycles
        self._coast = 0
        self._step = [0.0] * len(self.joint_names)

    def stop_motion(self) -> None:
        self.stop_calls += 1
        if len(self.sent) >= 2:
            self._step = [a - b for a, b in zip(self.sent[-1], self.sent[-2])]
        self._coast = self.stop_cycles
        self.fault = "stopping"

    def advance(self, period_s: float) -> None:
        if self._coast:  # keeps moving, slower each cycle, whatever is commanded
            self._coast -= 1
            scale = self._coast / self.stop_cycles
            self.position[:] = [q + d * scale for q, d in zip(self.position, self._step)]
            if not self._coast:
                self.fault = None
        else:
            super().advance(period_s)


def test_a_cancel_stops_the_hardware_and_the_reference_follows_it_to_rest(arm, write_yaml) -> None:
    hw = StoppingHardware(JOINTS, [0.2] * 7)
    executor, loop = running(hw, arm, write_yaml)
    handle = executor.submit(goal([0.6] * 7, 3.0), now_s=0.0)
    loop.run(1.0)
    assert hw.stop_calls == 0
    handle.cancel()
    loop.run(cycles=2)
    assert handle.status is GoalStatus.PREEMPTED and hw.stop_calls == 1
    loop.run(cycles=10)
    assert hw.fault == "stopping"
    assert hw.sent[-1] == pytest.approx(hw.position, abs=0.01)  # the reference follows the coasting joints
    loop.run(0.5)
    assert hw.fault is None
    rest = list(hw.position)
    loop.run(0.5)
    assert hw.position == rest and hw.sent[-1] == rest  # nothing moves when the stop is over


def test_without_a_cancel_the_hardware_is_never_asked_to_stop(arm, write_yaml) -> None:
    hw = StoppingHardware(JOINTS, [0.2] * 7)
    executor, loop = running(hw, arm, write_yaml)
    handle = executor.submit(goal([0.6] * 7, 3.0), now_s=0.0)
    loop.run(4.0)
    assert handle.status is GoalStatus.SUCCEEDED and hw.stop_calls == 0


def test_a_path_tolerance_abort_stops_the_hardware_too(arm, write_yaml) -> None:
    hw = StoppingHardware(JOINTS, [0.2] * 7)
    executor, loop = running(hw, arm, write_yaml, path_tolerance=0.05)
    handle = executor.submit(goal([0.6] * 7, 3.0), now_s=0.0)
    loop.run(1.0)
    hw.position[3] += 0.2  # joint3 knocked off its path
    loop.run(cycles=1)
    assert handle.status is GoalStatus.ABORTED and "joint3" in handle.result.error_string
    assert hw.stop_calls == 1


def test_a_goal_succeeds_only_once_the_hardware_says_the_robot_is_at_rest(arm, write_yaml) -> None:
    hw = servoed(0.2)
    executor, loop = running(hw, arm, write_yaml, goal_time_s=1.0)
    handle = executor.submit(goal([0.4] * 7, 2.0), now_s=0.0)
    hw.in_motion = True  # e.g. an industrial controller's STATUS while its servos settle
    loop.run(2.5)
    assert handle.status is GoalStatus.ACTIVE  # within tolerance, but the controller says it moves
    hw.in_motion = False
    loop.run(cycles=2)
    assert handle.status is GoalStatus.SUCCEEDED


def test_a_robot_reported_in_motion_for_ever_ends_the_goal_aborted_saying_so(arm, write_yaml) -> None:
    hw = servoed(0.2)
    executor, loop = running(hw, arm, write_yaml, goal_time_s=1.0)
    handle = executor.submit(goal([0.4] * 7, 2.0), now_s=0.0)
    hw.in_motion = True
    loop.run(3.5)
    assert handle.status is GoalStatus.ABORTED
    assert handle.result.error_string == "the hardware still reports the robot in motion 1.0 s after the end"

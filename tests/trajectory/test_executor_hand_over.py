"""Goals handed whole to hardware that executes trajectories itself (an industrial controller): which
points it gets, and when such a goal ends: by the hardware's word and timing, not the plan's."""

from __future__ import annotations

import pytest
import yaml

from jointctl.control import ControllerManager
from jointctl.model import load_robot_model
from jointctl.paths import robots_dir
from jointctl.runtime.loop import ControlLoop
from jointctl.trajectory.executor import GoalStatus
from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint
from tests.servoed_hardware import ServoedHardware

TRAJ = "arm7dof_trajectory_controller"
JOINTS = tuple(f"joint{k}" for k in range(7))


class TakingHardware(ServoedHardware):
    """Servoed joints that are handed trajectories: each call kept in ``handed``; ``executing`` and
    ``in_motion`` set by the test (the controller's word)."""

    takes_trajectories = True

    def __init__(self, sample_period_s=None) -> None:
        super().__init__(JOINTS, [0.0] * 7)
        self.trajectory_sample_period_s = sample_period_s
        self.executing = False
        self.handed: list[tuple] = []
        self.stops = 0

    def execute_trajectory(self, joint_indices, times_s, positions, velocities=None, accelerations=None):
        self.handed.append((list(joint_indices), list(times_s), [list(p) for p in positions], velocities))
        self.executing = True

    def stop_motion(self) -> None:
        self.stops += 1
        self.executing = False


@pytest.fixture(scope="module")
def arm():
    return load_robot_model(robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro")


def setup(arm, tmp_path, hardware, **changes):
    path = tmp_path / "controllers.yaml"
    executor = {"type": "trajectory_controllers/JointTrajectoryExecutor", "joints": list(JOINTS), **changes}
    path.write_text(yaml.safe_dump({"arm7dof": {TRAJ: executor}}))
    manager = ControllerManager(hardware, arm)
    manager.load_file(path)
    manager.start([TRAJ])
    return manager.controller(TRAJ), ControlLoop(hardware, manager)


def two_points(end: float = 0.1) -> JointTrajectory:
    return JointTrajectory(JOINTS, (
        JointTrajectoryPoint(positions=(end / 2,) * 7, velocities=(0.05,) * 7, time_from_start_s=1.0),
        JointTrajectoryPoint(positions=(end,) * 7, velocities=(0.0,) * 7, time_from_start_s=2.0)))


def test_the_goals_own_points_are_handed_over_with_their_times(arm, tmp_path) -> None:
    hw = TakingHardware()
    executor, loop = setup(arm, tmp_path, hw)
    executor.submit(two_points(), now_s=loop.time_s)
    loop.run(cycles=2)
    assert len(hw.handed) == 1
    indices, times, positions, velocities = hw.handed[0]
    assert indices == list(range(7)) and times == [1.0, 2.0]
    assert positions == [[0.05] * 7, [0.1] * 7] and [list(v) for v in velocities] == [[0.05] * 7, [0.0] * 7]


def test_a_sampling_hardware_gets_the_plan_every_period_and_at_its_end(arm, tmp_path) -> None:
    hw = TakingHardware(sample_period_s=0.02)
    executor, loop = setup(arm, tmp_path, hw)
    executor.submit(two_points(), now_s=loop.time_s)
    loop.run(cycles=2)
    _, times, positions, _ = hw.handed[0]
    assert len(times) == 100 and times[0] == pytest.approx(0.02) and times[-1] == pytest.approx(2.0)
    assert positions[-1] == pytest.approx([0.1] * 7)


def test_a_goal_succeeds_only_once_the_hardware_has_executed_it_however_late(arm, tmp_path) -> None:
    hw = TakingHardware()
    executor, loop = setup(arm, tmp_path, hw, goal_tolerance=0.01)
    handle = executor.submit(two_points(), now_s=loop.time_s)
    loop.run(6.0)  # three times the goal's 2 s: the controller still executes (its speed fractions)
    assert handle.status is GoalStatus.ACTIVE
    hw.executing = False
    loop.run(0.1)
    assert handle.status is GoalStatus.SUCCEEDED and hw.stops == 0


def test_the_user_set_goal_time_bounds_the_execution_beyond_the_end(arm, tmp_path) -> None:
    hw = TakingHardware()
    executor, loop = setup(arm, tmp_path, hw, goal_time_s=1.0)
    handle = executor.submit(two_points(), now_s=loop.time_s)
    loop.run(2.9)
    assert handle.status is GoalStatus.ACTIVE
    loop.run(0.2)  # past 2 s + 1 s
    assert handle.status is GoalStatus.ABORTED and hw.stops == 1
    assert "still executes the goal 1.0 s after its end" in handle.result.error_string


def test_a_goal_the_hardware_ended_elsewhere_is_aborted_naming_the_joint(arm, tmp_path) -> None:
    hw = TakingHardware()
    executor, loop = setup(arm, tmp_path, hw, goal_tolerance=0.01)
    handle = executor.submit(two_points(), now_s=loop.time_s)
    loop.run(1.0)
    hw.executing = False  # the controller says done, but its joints are not at the goal
    hw.position[3] = hw.position[3] - 0.05
    hw.lag_s = 1e9  # and they stay there
    loop.run(2.0)
    assert handle.status is GoalStatus.ABORTED
    assert "joint 'joint3' ended" in handle.result.error_string
    assert "after the controller executed it" in handle.result.error_string

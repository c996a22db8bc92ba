"""Every registered controller type loads from a chapter YAML file, starts, updates and stops, on
the robots it is written for (ros2_controllers' test-load pattern): a type added without a robot
file that uses it fails here."""

from __future__ import annotations

import math

import pytest
import yaml

from jointctl.control.registry import controller_types
from jointctl.control.ros2_parameters import controller_entries
from jointctl.paths import robots_dir
from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot
from jointctl.model import load_robot_model
from tests.servoed_hardware import ServoedHardware

ROBOTS = ("one_dof", "arm7dof", "minimal_robot")
#: Types meant for any robot: each must run on the 1-DOF robot and on the arm.
JOINT_LEVEL = ("joint_state_controller/JointStateController", "effort_controllers/JointPositionController",
               "trajectory_controllers/JointTrajectoryExecutor")


def controller_files(robot: str) -> list[str]:
    manifest = yaml.safe_load((robots_dir() / robot / "robot.yaml").read_text())
    return list(manifest["controllers"])


CASES = [(robot, key) for robot in ROBOTS for key in controller_files(robot)]


def types_used(robot: str) -> set[type]:
    """The controller classes a robot's controller files name."""
    registry = controller_types()
    manifest = yaml.safe_load((robots_dir() / robot / "robot.yaml").read_text())
    used = set()
    for path in manifest["controllers"].values():
        used.update(registry[t] for t in controller_entries(yaml.safe_load((robots_dir() / robot / path).read_text()))
                    .values())
    return used


#: Controller files for hardware that servos its joints (position interfaces only): run on a double of it.
SERVOED = ("industrial",)


def session_of(robot: str, key: str) -> Session:
    scenario = scenario_for_robot(robot, key)
    if key not in SERVOED:
        return Session(scenario)
    joints = [j.name for j in load_robot_model(scenario.robot.description).movable_joints]
    start = [scenario.initial_positions.get(j, 0.0) for j in joints]
    return Session(scenario, hardware=ServoedHardware(joints, start))


@pytest.mark.parametrize(("robot", "key"), CASES, ids=[f"{r}-{k}" for r, k in CASES])
def test_every_controller_of_every_robot_file_starts_updates_and_stops(robot, key):
    with session_of(robot, key) as session:
        manager = session.manager
        names = [c.name for c in manager.active]
        assert names, "the file starts no controller"
        session.loop.run(cycles=50)
        assert not manager.failures, manager.failures
        assert all(math.isfinite(v) for buf in session.hardware.command_buffers for v in buf)
        manager.stop(names, time_s=session.loop.time_s)  # chains stop together
        assert not manager.active
        session.loop.run(cycles=5)  # the loop runs on with nothing started


def test_every_registered_type_is_used_by_a_robot_file_and_joint_level_ones_by_both_robots():
    registry = controller_types()
    used = {robot: types_used(robot) for robot in ROBOTS}
    unused = sorted(name for name, cls in registry.items()
                    if not any(cls in u for u in used.values()) and not name.startswith("test_controllers/"))
    assert not unused, f"types no robot file uses: {unused}"
    for name in JOINT_LEVEL:
        assert registry[name] in used["one_dof"] and registry[name] in used["arm7dof"], name

"""What a command's robot argument is taken for: a built-in robot or scenario, a robot folder, a
manifest, a bare URDF/xacro with its controller file, a scenario; and the mistakes named as such."""

from __future__ import annotations

from pathlib import Path

import pytest

from jointctl.errors import ConfigError
from jointctl.scenario.targets import resolve_target, robot_files
from tests.planar_arm import write_urdf

CONTROLLERS = """planar_arm:
  joint_state_controller: {type: joint_state_controller/JointStateController, publish_rate: 50}
  shoulder_position_controller:
    type: effort_controllers/JointPositionController
    joint: shoulder
    pid: {p: 300.0, i: 0.0, d: 40.0}
  elbow_position_controller:
    type: effort_controllers/JointPositionController
    joint: elbow
    pid: {p: 60.0, i: 0.0, d: 3.0}
"""


@pytest.fixture
def arm(tmp_path) -> dict[str, Path]:
    """The user's planar arm: its URDF, a ros_control YAML beside it, and a folder naming both."""
    urdf = write_urdf(tmp_path / "arm")
    controllers = tmp_path / "arm" / "planar_arm_control.yaml"
    controllers.write_text(CONTROLLERS)
    manifest = tmp_path / "arm" / "robot.yaml"
    manifest.write_text("description: planar_arm.urdf\ncontrollers: {position: planar_arm_control.yaml}\n"
                        "serve: {initial_positions: {elbow: 0.3}}\n")
    scenario = tmp_path / "hold.yaml"
    scenario.write_text("robot: arm\ncontroller_file: position\nstart_controllers: [joint_state_controller]\n"
                        "duration_s: 1.0\n")
    return {"urdf": urdf, "controllers": controllers, "manifest": manifest, "folder": manifest.parent,
            "scenario": scenario}


def test_a_built_in_robot_and_a_built_in_scenario() -> None:
    robot = resolve_target("one_dof", controllers="velocity")
    assert robot.taken_as == "took one_dof as a built-in robot, controllers velocity" and robot.is_robot
    assert robot.scenario.controller_file.name == "one_dof_vel_ctl_params.yaml"
    assert robot.scenario.initial_positions == {"joint1": -0.5}  # the manifest's serve defaults
    scenario = resolve_target("one_dof_step")
    assert scenario.taken_as == "took one_dof_step as the built-in scenario" and not scenario.is_robot
    assert scenario.scenario.commands  # the scenario's own, not a robot's bring-up


def test_a_robot_folder_and_its_manifest_bring_the_robot_up_with_every_controller(arm) -> None:
    for ref, taken in ((arm["folder"], "a robot folder"), (arm["manifest"], "a robot manifest")):
        target = resolve_target(str(ref))
        assert target.taken_as.startswith(f"took {ref} as {taken}") and target.taken_as.endswith("controllers position")
        scenario = target.scenario
        assert scenario.robot.description == arm["urdf"].resolve()
        assert scenario.start_controllers == ("joint_state_controller", "shoulder_position_controller",
                                              "elbow_position_controller")
        assert scenario.initial_positions == {"elbow": 0.3}


def test_a_bare_description_takes_its_controllers_from_a_file(arm, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    target = resolve_target("arm/planar_arm.urdf", controllers="arm/planar_arm_control.yaml",
                            robot_defaults=["duration_s=5"], overrides=["duration_s=2", "gravity=-5"])
    assert target.taken_as == ("took arm/planar_arm.urdf as a robot description (URDF), controllers "
                               "planar_arm_control.yaml")
    scenario = target.scenario
    assert scenario.controller_file == arm["controllers"].resolve()
    assert scenario.duration_s == 2.0 and scenario.gravity_m_s2 == (0.0, 0.0, -5.0)  # --set after the defaults
    assert len(scenario.start_controllers) == 3


def test_a_scenario_file(arm) -> None:
    target = resolve_target(str(arm["scenario"]))
    assert target.taken_as == f"took {arm['scenario']} as a scenario" and not target.is_robot
    assert target.scenario.robot.description == arm["urdf"].resolve()


@pytest.mark.parametrize("case, kwargs, fragments", [
    ("urdf", {}, ["--controllers", "ros_control YAML"]),
    ("missing_urdf", {}, ["no such robot description file"]),
    ("controllers", {}, ["ros_control controller file", "--controllers"]),
    ("scenario", {"controllers": "position"}, ["--controllers", "a scenario names its own"]),
    ("folder", {"controllers": "servo"}, ["--controllers", "servo", "position"]),
    ("empty_folder", {}, ["without a robot.yaml", "jointctl init"]),
    ("nothing", {}, ["no such file, robot or scenario", "one_dof"]),
    ("text", {}, ["neither a robot", "nor a scenario"]),
])
def test_mistakes_are_named(arm, tmp_path, case, kwargs, fragments) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "notes.txt").write_text("hello")
    ref = {"urdf": arm["urdf"], "missing_urdf": tmp_path / "gone.urdf", "controllers": arm["controllers"],
           "scenario": arm["scenario"], "folder": arm["folder"], "empty_folder": tmp_path / "empty",
           "nothing": tmp_path / "nothing", "text": tmp_path / "notes.txt"}[case]
    with pytest.raises(ConfigError) as caught:
        resolve_target(str(ref), **kwargs)
    message = str(caught.value)
    for fragment in fragments:
        assert fragment in message, message


def test_what_is_not_a_robot_is_none(arm) -> None:
    assert robot_files(str(arm["scenario"])) is None
    assert robot_files(str(arm["controllers"])) is None
    files, taken = robot_files(str(arm["urdf"]))
    assert taken == "a robot description (URDF)" and files.controller_files == {} and files.manifest is None

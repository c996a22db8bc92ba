"""``jointctl init`` writes the ROS 2 files beside the ROS 1 ones, and they load back: the description with its
``<ros2_control>`` system, the controller_manager parameters with the same gains as doubles, and a run under
pid_controller that is the ros_control file's run (the same law for a reference without values_dot)."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest

from jointctl.cli import main
from jointctl.control.manager import read_yaml
from jointctl.model.loader import load_robot_model
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from tests import planar_arm


def init(root: Path, description: str) -> str:
    err = io.StringIO()
    with contextlib.chdir(root), contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert main(["init", description, "--out", "arm"]) == 0
    return err.getvalue()


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("init_ros2")
    planar_arm.write_urdf(root)
    (root / "init.err").write_text(init(root, "planar_arm.urdf"))
    return root


def test_the_description_with_its_ros2_control_loads_back(written):
    folder = written / "arm"
    assert "wrote arm/urdf/planar_arm.ros2_control.urdf.xacro" in (written / "init.err").read_text()
    robot = load_robot_model(folder / "urdf" / "planar_arm.ros2_control.urdf.xacro")
    plain = load_robot_model(written / "planar_arm.urdf")
    assert robot.name == "planar_arm" and robot.joints == plain.joints and robot.links == plain.links
    (system,) = robot.ros2_control
    assert system.plugin == "mock_components/GenericSystem" and system.type == "system"
    assert [(j.name, j.command_names, j.state_names) for j in system.joints] == [
        ("shoulder", ("effort",), ("position", "velocity", "effort")),
        ("elbow", ("effort",), ("position", "velocity", "effort"))]
    manifest = read_yaml(folder / "robot.yaml")
    assert robot.initial_positions == manifest["serve"]["initial_positions"] == {"shoulder": 0.0, "elbow": 0.0}
    assert manifest["controllers"]["ros2"] == "config/ros2_controllers.yaml"


def test_the_ros2_controllers_carry_the_ros1_gains_as_doubles(written):
    folder = written / "arm"
    ros1 = read_yaml(folder / "config" / "planar_arm_control.yaml")["planar_arm"]
    ros2 = read_yaml(folder / "config" / "ros2_controllers.yaml")
    manager = ros2["controller_manager"]["ros__parameters"]
    assert manager["update_rate"] == 1000 and set(manager) == {"update_rate", "joint_state_broadcaster",
                                                               "pid_controller"}
    pid = ros2["pid_controller"]["ros__parameters"]
    assert pid["dof_names"] == ["shoulder", "elbow"] and pid["command_interface"] == "effort"
    for joint in ("shoulder", "elbow"):
        gains = pid["gains"][joint]
        assert all(isinstance(v, float) for v in gains.values()), gains  # ROS 2 refuses an int for a double
        assert gains["p"] == pytest.approx(ros1[f"{joint}_position_controller"]["pid"]["p"], rel=1e-5)
        assert gains["d"] == pytest.approx(ros1[f"{joint}_position_controller"]["pid"]["d"], rel=1e-5)


@pytest.mark.slow
def test_holding_home_under_pid_controller_is_the_ros_control_files_run(written, tmp_path):
    # Both loops start at home with the reference there: control_toolbox's first rate (e - 0)/h and ros_control's
    # 0 are both 0, and from then on both differentiate the error. Same gains, same law: the same run.
    folder = written / "arm"
    scenario = folder / "scenarios" / "step_shoulder.yaml"
    common = ["duration_s=1.0", "commands={}", "analysis=null"]
    runs = {}
    for name, settings in {
        "ros1": common,
        "ros2": common + ["controller_file=ros2", "start_controllers=[joint_state_broadcaster,pid_controller]",
                          "commands.pid_controller={type: constant, value: 0.0}"],
    }.items():
        with Session(load_scenario(scenario, settings), out_dir=tmp_path / name) as session:
            session.run()
        runs[name] = np.genfromtxt(session.trace_path, delimiter=",", names=True)
    for column in ("shoulderposition", "elbowposition"):
        assert np.max(np.abs(runs["ros2"][column] - runs["ros1"][column])) < 1e-12, column
    assert np.max(np.abs(runs["ros1"]["shoulderposition"])) > 1e-3  # it moved: gravity sagged it


def test_a_description_with_its_own_ros2_control_gets_no_second_one(tmp_path):
    text = planar_arm.urdf_text()
    for joint in ("shoulder", "elbow"):
        text = text.replace(planar_arm.transmission(joint), "")
    assert "<transmission" not in text
    system = ('<ros2_control name="arm_hw" type="system"><hardware><plugin>my_robot/Driver</plugin></hardware>'
              + "".join(f'<joint name="{j}"><command_interface name="effort"/><state_interface name="position"/>'
                        '<state_interface name="velocity"/></joint>' for j in ("shoulder", "elbow"))
              + "</ros2_control></robot>")
    (tmp_path / "ros2_arm.urdf").write_text(text.replace("</robot>", system))
    err = init(tmp_path, "ros2_arm.urdf")
    assert not (tmp_path / "arm" / "urdf").exists()
    assert "jointctl's simulated robot stands in for the hardware plugin my_robot/Driver" in err
    pid = read_yaml(tmp_path / "arm" / "config" / "ros2_controllers.yaml")["pid_controller"]["ros__parameters"]
    assert pid["dof_names"] == ["shoulder", "elbow"]


def test_a_run_says_what_the_simulation_stood_in_for(written, tmp_path):
    from jointctl.scenario.run import run_scenario

    robot = written / "arm" / "urdf" / "planar_arm.ros2_control.urdf.xacro"
    scenario = load_scenario(written / "arm" / "scenarios" / "step_shoulder.yaml",
                             [f"robot={robot}",
                              f"controller_file={written / 'arm' / 'config' / 'ros2_controllers.yaml'}",
                              "start_controllers=[joint_state_broadcaster]", "commands={}", "analysis=null",
                              "duration_s=0.01"])
    metrics = run_scenario(scenario, tmp_path / "out", mcap=False)
    assert metrics["stands_in_for"] == [
        "ros2_control system 'planar_arm_system': jointctl's simulated robot stands in for the hardware plugin "
        "mock_components/GenericSystem (joints shoulder (effort), elbow (effort))"]

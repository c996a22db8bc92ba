"""``jointctl serve --ros2``: the 1-DOF robot as a ros2_control robot, checked with ROS 2's own command line.

Theory: the chapter's position loop is a P loop (p = 400 N/m, no integral) on a vertical piston, so it rests where
``p·(r - q) = τ_hold(q)`` (the robot model's holding effort, :func:`jointctl.identification.safety.real_rest`): a
sag of τ_hold/p below the reference, which doubles when p is halved. With the trajectory configuration the
position loop has the model's gravity feed-forward, so a goal is reached without sag.
"""

from __future__ import annotations

import pytest

from jointctl.identification.safety import real_rest
from jointctl.model.loader import load_robot_model
from jointctl.paths import robots_dir
from tests.ros2.environment import ros2
from tests.ros2.served import ServedRobot
from tests.waiting import wait_until

pytestmark = pytest.mark.slow

ROBOT = load_robot_model(robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro")
P = 400.0
#: The probe's "at rest": |v| < 1e-4 m/s; with the joint's 10 N·s/m damping the position is then within
#: 1e-4·10/400 m of its rest (the spring's force balances what damping still takes): far below the tolerance.
REST_TOLERANCE_M = 5e-4


@pytest.fixture(scope="module")
def position_robot(ros2_env, tmp_path_factory):
    served = ServedRobot(ros2_env, tmp_path_factory.mktemp("serve") / "serve.log", "one_dof",
                         "--controllers", "position")
    try:
        served.wait_up(["joint_state_controller", "joint1_position_controller"])
        yield served
    finally:
        served.stop()


def reference(env, value: float) -> None:
    """Publish pid_controller's reference a few times (its subscription is best effort, depth 1)."""
    out = ros2(env, "topic", "pub", "-r", "20", "-t", "10", "/joint1_position_controller/reference",
               "control_msgs/msg/MultiDOFCommand", f"{{dof_names: [joint1], values: [{value}]}}")
    assert out.returncode == 0, out.stderr


def test_the_cli_lists_jointctls_controllers_and_joints(position_robot):
    env = position_robot.env
    listed = ros2(env, "control", "list_controllers").stdout
    assert "effort_controllers/JointPositionController" in listed and "joint_state_controller" in listed, listed
    interfaces = ros2(env, "control", "list_hardware_interfaces").stdout
    assert "joint1/effort" in interfaces and "[claimed]" in interfaces, interfaces
    echoed = ros2(env, "topic", "echo", "--once", "/joint_states", "sensor_msgs/msg/JointState").stdout
    assert "- joint1" in echoed, echoed


def test_a_reference_on_the_topic_moves_the_joint_to_its_sagged_rest(position_robot):
    reference(position_robot.env, -0.3)
    rest = position_robot.rest("joint1")["position"]
    expected = real_rest(ROBOT, "joint1", {}, -0.3, P)
    assert expected < -0.3 - 0.01  # the sag is there to see (τ_hold/p ≈ 25 mm)
    assert rest == pytest.approx(expected, abs=REST_TOLERANCE_M)


def test_a_gain_set_with_ros2_param_changes_the_sag_as_theory_says(position_robot):
    env = position_robot.env
    done = ros2(env, "param", "set", "/joint1_position_controller", "gains.joint1.p", "200.0")
    assert "successful" in done.stdout, done.stdout + done.stderr
    reference(env, -0.4)
    rest = position_robot.rest("joint1")["position"]
    assert rest == pytest.approx(real_rest(ROBOT, "joint1", {}, -0.4, P / 2), abs=REST_TOLERANCE_M)
    refused = ros2(env, "param", "set", "/joint1_position_controller", "gains.joint1.p", "-5.0")
    said = refused.stdout + refused.stderr
    assert "failed" in said and "must not be negative (value -5.0)" in said, said
    kept = ros2(env, "param", "get", "/joint1_position_controller", "gains.joint1.p").stdout
    assert "200.0" in kept, kept
    done = ros2(env, "param", "set", "/joint1_position_controller", "gains.joint1.p", str(P))
    assert "successful" in done.stdout


def test_a_bad_reference_is_refused_and_the_joint_holds(position_robot):
    env = position_robot.env
    reference(env, -0.3)
    before = position_robot.rest("joint1")["position"]
    out = ros2(env, "topic", "pub", "-r", "20", "-t", "10", "/joint1_position_controller/reference",
               "control_msgs/msg/MultiDOFCommand", "{dof_names: [joint2], values: [-0.6]}")
    assert out.returncode == 0
    wait_until(lambda: "refused a reference for dof_names ['joint2']" in position_robot.log.read_text(),
               "the refusal in the served node's log")
    assert position_robot.rest("joint1")["position"] == pytest.approx(before, abs=REST_TOLERANCE_M)

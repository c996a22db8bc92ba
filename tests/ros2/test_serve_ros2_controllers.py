"""``jointctl serve --ros2`` with ros2_controllers' own types from the robot's ROS 2 controller_manager files.

Theory, on the 1.01 kg vertical piston with 10 N·s/m joint damping:
- pid_controller (p 400, d 20, no integral): rests where ``p·(r - q) = τ_hold(q)`` (the model's holding effort);
- forward_command_controller on the effort: an effort ``τ_hold + ΔF`` leaves ``ΔF`` to the damping, so the piston
  reaches the terminal speed ``ΔF / b`` (time constant m/b = 0.1 s).
"""

from __future__ import annotations

import pytest

from jointctl.identification.safety import real_rest
from jointctl.metrics.step_loop import holding_effort
from tests.ros2.environment import ros2
from tests.ros2.served import ServedRobot
from tests.ros2.test_serve import REST_TOLERANCE_M, ROBOT
from tests.waiting import wait_until

pytestmark = pytest.mark.slow

DAMPING_N_S_M = 10.0


@pytest.fixture
def served(ros2_env, tmp_path):
    made = []

    def serve(controllers: str, *names: str) -> ServedRobot:
        robot = ServedRobot(ros2_env, tmp_path / f"{controllers}.log", "one_dof", "--controllers", controllers)
        made.append(robot)
        robot.wait_up(list(names))
        return robot

    yield serve
    for robot in made:
        robot.stop()


def test_pid_controller_rests_where_theory_says_and_takes_gains_live(served):
    robot = served("ros2", "joint_state_broadcaster", "pid_controller")
    env = robot.env
    listed = ros2(env, "control", "list_controllers").stdout
    assert "pid_controller/PidController" in listed, listed
    # The controller manager's update_rate is the loop's (the file's 1000 Hz), as a ROS 2 client reads it.
    rate = ros2(env, "param", "get", "/controller_manager", "update_rate").stdout
    assert rate.strip().endswith("1000"), rate

    def reference(value: float) -> None:
        ros2(env, "topic", "pub", "-r", "20", "-t", "10", "/pid_controller/reference",
             "control_msgs/msg/MultiDOFCommand", f"{{dof_names: [joint1], values: [{value}]}}")

    reference(-0.3)
    assert robot.rest("joint1")["position"] == pytest.approx(real_rest(ROBOT, "joint1", {}, -0.3, 400.0),
                                                            abs=REST_TOLERANCE_M)
    done = ros2(env, "param", "set", "/pid_controller", "gains.joint1.p", "800.0")
    assert "successful" in done.stdout, done.stdout + done.stderr
    reference(-0.35)
    assert robot.rest("joint1")["position"] == pytest.approx(real_rest(ROBOT, "joint1", {}, -0.35, 800.0),
                                                            abs=REST_TOLERANCE_M)
    refused = ros2(env, "param", "set", "/pid_controller", "dof_names", "[joint2]")
    assert "failed" in (refused.stdout + refused.stderr).lower(), refused.stdout + refused.stderr


def test_forward_command_effort_gives_the_terminal_speed_of_the_damping(served):
    robot = served("ros2_forward", "joint_state_broadcaster", "effort_controller")
    env = robot.env
    hold = holding_effort(ROBOT, "joint1", {})(-0.5)
    extra_n = 0.5

    def command(effort) -> None:
        ros2(env, "topic", "pub", "-r", "20", "-t", "10", "/effort_controller/commands",
             "std_msgs/msg/Float64MultiArray", f"{{data: [{effort}]}}")

    command(hold + extra_n)
    steady = robot.rest("joint1", 60.0, "steady", "--still", "1e-5", "--samples", "20")
    assert steady["velocity"] == pytest.approx(extra_n / DAMPING_N_S_M, rel=0.02)
    command(".nan")
    wait_until(lambda: "refused commands" in robot.log.read_text(), "the NaN command's refusal in the log")

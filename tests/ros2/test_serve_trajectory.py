"""``jointctl serve --ros2`` with a trajectory executor: joint_trajectory_controller's action, driven by
``ros2 action send_goal``. The position loop under the executor has the model's gravity feed-forward, so a goal
ends where it asks, without the P loop's sag (test_serve.py has the sag)."""

from __future__ import annotations

import pytest

from tests.ros2.environment import ros2
from tests.ros2.served import ServedRobot
from tests.waiting import wait_until

pytestmark = pytest.mark.slow

ACTION = "/joint1_trajectory_controller/follow_joint_trajectory"
GOAL_TOLERANCE_M = 1e-3  # the feed-forward model is the plant's: what is left is the probe's rest criterion


@pytest.fixture(scope="module")
def trajectory_robot(ros2_env, tmp_path_factory):
    served = ServedRobot(ros2_env, tmp_path_factory.mktemp("serve") / "serve.log", "one_dof",
                         "--controllers", "trajectory")
    try:
        served.wait_up(["joint1_trajectory_controller", "joint1_position_controller"])
        yield served
    finally:
        served.stop()


def goal(position: float, seconds: int = 1) -> str:
    return (f"{{trajectory: {{joint_names: [joint1], points: [{{positions: [{position}], "
            f"time_from_start: {{sec: {seconds}}}}}]}}}}")


def test_a_goal_sent_with_the_cli_succeeds_where_it_asks(trajectory_robot):
    env = trajectory_robot.env
    out = ros2(env, "action", "send_goal", ACTION, "control_msgs/action/FollowJointTrajectory", goal(-0.3))
    assert "SUCCEEDED" in out.stdout and "error_code: 0" in out.stdout, out.stdout + out.stderr
    state = ros2(env, "topic", "echo", "--once", "--field", "reference.positions",
                 "/joint1_trajectory_controller/controller_state", "control_msgs/msg/JointTrajectoryControllerState")
    assert "[-0.3]" in state.stdout, state.stdout + state.stderr  # the reference held at the goal's end
    assert trajectory_robot.rest("joint1")["position"] == pytest.approx(-0.3, abs=GOAL_TOLERANCE_M)


def test_a_goal_beyond_the_joint_limit_is_rejected_and_nothing_moves(trajectory_robot):
    env = trajectory_robot.env
    ros2(env, "action", "send_goal", ACTION, "control_msgs/action/FollowJointTrajectory", goal(-0.6))
    before = trajectory_robot.rest("joint1")["position"]
    assert before == pytest.approx(-0.6, abs=GOAL_TOLERANCE_M)  # the server takes goals: the next refusal is its own
    out = ros2(env, "action", "send_goal", ACTION, "control_msgs/action/FollowJointTrajectory", goal(0.5))
    assert "Goal was rejected" in out.stdout, out.stdout + out.stderr
    wait_until(lambda: "rejected a goal (INVALID_GOAL -1)" in trajectory_robot.log.read_text(),
               "the rejection's reason and JTC's error code in the served node's log")
    assert trajectory_robot.rest("joint1")["position"] == pytest.approx(before, abs=GOAL_TOLERANCE_M)


def test_the_goals_own_path_tolerance_aborts_with_jtcs_error_code(trajectory_robot):
    """A path tolerance of 1e-12 m in the goal (the controller has none): a 0.2 m move's tracking error, however good
    the feed-forward, is larger (the loop's discretisation alone), so the goal ends aborted with
    PATH_TOLERANCE_VIOLATED (-4) and the joint is brought to rest. The move starts from a goal's end (-0.3 m)."""
    env = trajectory_robot.env
    out = ros2(env, "action", "send_goal", ACTION, "control_msgs/action/FollowJointTrajectory", goal(-0.3))
    assert "SUCCEEDED" in out.stdout, out.stdout + out.stderr
    strict = ("{trajectory: {joint_names: [joint1], points: [{positions: [-0.5], time_from_start: {sec: 1}}]}, "
              "path_tolerance: [{name: joint1, position: 1.0e-12}]}")
    out = ros2(env, "action", "send_goal", ACTION, "control_msgs/action/FollowJointTrajectory", strict)
    assert "ABORTED" in out.stdout and "error_code: -4" in out.stdout, out.stdout + out.stderr
    assert trajectory_robot.rest("joint1")["velocity"] == pytest.approx(0.0, abs=1e-3)

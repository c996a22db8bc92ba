"""``jointctl tune --ros2``: the tuning page's robot is also a ros2_control robot on ROS 2 (the same faces as
``serve --ros2``): a reference sent with ``ros2 topic pub`` moves it to the P loop's sagged rest."""

from __future__ import annotations

import pytest

from jointctl.identification.safety import real_rest
from tests.ros2.served import ServedRobot
from tests.ros2.test_serve import P, REST_TOLERANCE_M, ROBOT, reference

pytestmark = pytest.mark.slow


def test_the_tuning_pages_robot_answers_on_ros2(ros2_env, tmp_path):
    tuned = ServedRobot(ros2_env, tmp_path / "tune.log", "one_dof", "--port", "0", command="tune")
    try:
        tuned.wait_up(["joint_state_controller", "joint1_position_controller"])
        reference(ros2_env, -0.35)
        rest = tuned.rest("joint1")["position"]
        assert rest == pytest.approx(real_rest(ROBOT, "joint1", {}, -0.35, P), abs=REST_TOLERANCE_M)
    finally:
        tuned.stop()

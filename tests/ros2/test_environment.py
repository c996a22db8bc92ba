"""The ROS 2 the tests use is a working one, and a module's domain is its own."""

from __future__ import annotations

import subprocess

from tests.processes import stop_process
from tests.ros2.environment import ros2


def test_the_cli_sees_a_cpp_talker_on_the_modules_domain(ros2_env):
    talker = subprocess.Popen([f"{ros2_env['AMENT_PREFIX_PATH'].split(':')[0]}/lib/demo_nodes_cpp/talker"],
                              env=ros2_env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        out = ros2(ros2_env, "topic", "echo", "--once", "/chatter", "std_msgs/msg/String", timeout_s=60)
        assert "Hello World" in out.stdout, out.stdout + out.stderr
        other = dict(ros2_env, ROS_DOMAIN_ID=str(int(ros2_env["ROS_DOMAIN_ID"]) + 1))
        listed = ros2(other, "topic", "list", "--no-daemon", timeout_s=60).stdout.split()
        assert "/chatter" not in listed, listed
    finally:
        stop_process(talker)

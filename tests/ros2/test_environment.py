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


def test_a_ros1_command_works_in_a_shell_where_ros2_is_sourced_too(ros2_env):
    """ROS 2's std_msgs and rosgraph_msgs carry ROS 1's names and come first on a ROS 2 shell's PYTHONPATH:
    jointctl's ROS 1 edge sets them aside (jointctl.python_path.set_aside_ros2) and imports Debian's."""
    import sys

    code = ("from jointctl.cli.common import ros_edge; import rosgraph_msgs.msg as m; "
            "ros_edge('conversions'); import rosgraph_msgs.msg as n; print(n.__file__)")
    done = subprocess.run([sys.executable, "-c", code], env=ros2_env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().startswith("/usr/lib/python3/dist-packages/rosgraph_msgs"), done.stdout

"""jointctl on ROS 2 (rclpy): the only package that imports rclpy and ROS 2's messages.

ROS 2's Python packages carry the names of ROS 1's (``std_msgs``, ``sensor_msgs``, ``control_msgs``) and rclpy
finds its libraries through the environment its ``setup.bash`` makes before the process starts: a process is
either a ROS 1 one (:mod:`jointctl.ros`) or a ROS 2 one (this package), started from a shell where the user's
ROS 2 is sourced (``source /opt/ros/jazzy/setup.bash``).
"""

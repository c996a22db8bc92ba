"""ROS 2 on the wire: the only package of jointctl that imports rclpy (and ROS 2's message packages).

Its modules run in a process where the user sourced ROS 2 (``source /opt/ros/jazzy/setup.bash``): rclpy
finds its libraries only through the environment that script sets, and ROS 2's message packages have
the names of ROS 1's.
"""

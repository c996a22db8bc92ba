#!/usr/bin/env bash
# Install the Debian packages that give a working ROS 1 for jointctl's ROS edge and its tests:
# master, rospy, actionlib, rostopic, rosbag, roslaunch/rosparam, the message packages, genpy and
# genmsg (to generate the action messages jointctl ships as .action files), dynamic_reconfigure,
# robot_state_publisher with visualization_msgs and tf2_msgs (serve's robot_description, the
# spawned objects' markers, /tf in the tests), and Debian's numpy (a ROS user's machine has it: tf2 pulls it in;
# the tests check that it on PYTHONPATH does not shadow the environment's). rviz (serve --rviz) is optional:
# apt-get install rviz.
# Debian packages these for its own /usr/bin/python3; the project's venv sees them through
# --system-site-packages. Does nothing when everything is already installed.
set -euo pipefail
PACKAGES=(
  python3-rosmaster python3-rospy python3-actionlib python3-rostopic python3-rosbag python3-rosparam
  python3-roslaunch python3-std-msgs python3-sensor-msgs python3-geometry-msgs python3-trajectory-msgs
  python3-actionlib-msgs python3-genpy python3-genmsg python3-rosnode python3-rosmsg python3-rosservice
  ros-std-msgs ros-actionlib-msgs ros-geometry-msgs ros-sensor-msgs ros-trajectory-msgs
  python3-dynamic-reconfigure
  ros-robot-state-publisher python3-visualization-msgs ros-visualization-msgs python3-tf2-msgs ros-tf2-msgs
  python3-numpy
)
source "$(dirname "$0")/apt_packages.sh"
install_missing install_ros "${PACKAGES[@]}"

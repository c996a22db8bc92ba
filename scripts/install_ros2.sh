#!/usr/bin/env bash
# ROS 2 for jointctl's ROS 2 edge and its tests. A machine with a ROS 2 of its own (JOINTCTL_ROS2_SETUP
# pointing at its setup.bash, or /opt/ros/<distro>/setup.bash with rclpy inside) keeps it; otherwise the
# prebuilt ROS 2 Jazzy for Debian 12 beside the project (../shared/ros2/, or ROS2_PEER_DIR) is installed
# into /opt/ros/jazzy (Debian packages and a 9 MB archive, seconds). Does nothing when one is found.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/.." && pwd)
found() {
  local setup
  for setup in ${JOINTCTL_ROS2_SETUP:-} /opt/ros/*/setup.bash; do
    [ -f "$setup" ] || continue
    local prefix; prefix=$(dirname "$setup")
    if ls "$prefix"/lib/python3*/site-packages/rclpy/__init__.py >/dev/null 2>&1; then
      echo "$setup"; return 0
    fi
  done
  return 1
}
if setup=$(found); then
  echo "install_ros2: ROS 2 found: $setup"
  exit 0
fi
PEER=${ROS2_PEER_DIR:-$ROOT/../shared/ros2}
if [ ! -f "$PEER/install.sh" ]; then
  echo "install_ros2: no ROS 2 found and no installer at $PEER/install.sh (set ROS2_PEER_DIR, or" \
       "JOINTCTL_ROS2_SETUP=<your ROS 2>/setup.bash); the ROS 2 tests will skip" >&2
  [ -z "${JOINTCTL_REQUIRE_ROS2:-}" ] || exit 1
  exit 0
fi
SUDO=""; [ "$(id -u)" = 0 ] || SUDO=sudo
$SUDO bash "$PEER/install.sh"
found >/dev/null || { echo "install_ros2: installed, but no rclpy under /opt/ros" >&2; exit 1; }

#!/usr/bin/env bash
# Generate Python classes for the message and action definitions under ros/ (no catkin):
# genaction turns each .action into its seven .msg files, genpy turns .msg and .srv files into Python.
# Output: $OUT/src/<pkg>/ (package.xml + msg/*.msg, srv/*.srv, findable by rostopic/rosbag/rosservice
# through ROS_PACKAGE_PATH) and $OUT/py/<pkg>/{msg,srv}/*.py (importable). Needs Debian's ROS packages.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${OUT:-$ROOT/build/ros}
PY=/usr/bin/python3
GENACTION=$ROOT/scripts/genaction.py
GENPY=/usr/lib/genpy/genmsg_py.py
GENSRV=/usr/lib/genpy/gensrv_py.py
rm -rf "$OUT"
mkdir -p "$OUT/src" "$OUT/py"
includes=(-Istd_msgs:/usr/share/std_msgs/msg -Iactionlib_msgs:/usr/share/actionlib_msgs/msg
          -Itrajectory_msgs:/usr/share/trajectory_msgs/msg -Igeometry_msgs:/usr/share/geometry_msgs/msg)
for pkg_dir in "$ROOT"/ros/*/; do
  pkg=$(basename "$pkg_dir")
  src="$OUT/src/$pkg"
  mkdir -p "$src/msg"
  cp "$pkg_dir/package.xml" "$src/"
  cp "$pkg_dir"/msg/*.msg "$src/msg/" 2>/dev/null || true
  if compgen -G "$pkg_dir/srv/*.srv" >/dev/null; then
    mkdir -p "$src/srv" && cp "$pkg_dir"/srv/*.srv "$src/srv/"
  fi
  for action in "$pkg_dir"/action/*.action; do
    [ -e "$action" ] || continue
    mkdir -p "$src/action" && cp "$action" "$src/action/"
    "$PY" "$GENACTION" "$action" "$src/msg"
  done
  includes+=(-I"$pkg:$src/msg")
done
for src in "$OUT"/src/*/; do
  pkg=$(basename "$src")
  "$PY" "$GENPY" -p "$pkg" -o "$OUT/py/$pkg/msg" "${includes[@]}" "$src"/msg/*.msg >/dev/null
  "$PY" "$GENPY" --initpy -p "$pkg" -o "$OUT/py/$pkg/msg" >/dev/null
  if compgen -G "$src/srv/*.srv" >/dev/null; then
    "$PY" "$GENSRV" -p "$pkg" -o "$OUT/py/$pkg/srv" "${includes[@]}" "$src"/srv/*.srv >/dev/null
    "$PY" "$GENSRV" --initpy -p "$pkg" -o "$OUT/py/$pkg/srv" >/dev/null
  fi
  touch "$OUT/py/$pkg/__init__.py"
done
echo "gen_ros_msgs: generated $(ls "$OUT/py" | tr '\n' ' ')into $OUT"
cat > "$OUT/setup.sh" <<SETUP
# Source this so ROS tools (rostopic, rosbag, rosmsg) find jointctl's message types:
#   source $OUT/setup.sh
export ROS_PACKAGE_PATH="$OUT/src\${ROS_PACKAGE_PATH:+:\$ROS_PACKAGE_PATH}"
export PYTHONPATH="$OUT/py\${PYTHONPATH:+:\$PYTHONPATH}"
SETUP

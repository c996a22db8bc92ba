"""rclpy's own serialization of ``sensor_msgs/msg/JointState``, run in a child process with ROS 2 sourced (the
test process stays a ROS 1 process: see :mod:`tests.ros2.environment`).

:func:`serialize_joint_states` gives the CDR bytes ``rclpy.serialization.serialize_message`` makes of
messages given as dicts; :func:`deserialize_joint_states` what ``deserialize_message`` reads from bytes.
Messages cross the pipe as JSON (floats as Python writes them: exactly), bytes as base64.
"""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys
from pathlib import Path

from tests.ros2.environment import sourced_variables

PROBE = r"""
import base64, json, sys
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

request = json.load(sys.stdin)
out = []
for item in request["messages"]:
    if request["op"] == "serialize":
        msg = JointState()
        msg.header.stamp.sec, msg.header.stamp.nanosec = item["sec"], item["nanosec"]
        msg.header.frame_id = item["frame_id"]
        msg.name, msg.position, msg.velocity, msg.effort = (item[k] for k in ("name", "position", "velocity",
                                                                            "effort"))
        out.append(base64.b64encode(serialize_message(msg)).decode())
    else:
        msg = deserialize_message(base64.b64decode(item), JointState)
        out.append({"sec": msg.header.stamp.sec, "nanosec": msg.header.stamp.nanosec,
                    "frame_id": msg.header.frame_id, "name": list(msg.name), "position": list(msg.position),
                    "velocity": list(msg.velocity), "effort": list(msg.effort)})
json.dump(out, sys.stdout)
"""


def run_with_ros2(setup: Path, script: str, request):
    """Run the Python ``script`` with ROS 2 sourced, ``request`` as JSON on its standard input; what it writes
    on its standard output, read as JSON."""
    env = dict(os.environ)
    env.update(sourced_variables(setup))
    done = subprocess.run([sys.executable, "-c", script], input=json.dumps(request), env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def _run(setup: Path, op: str, messages: list) -> list:
    return run_with_ros2(setup, PROBE, {"op": op, "messages": messages})


def serialize_joint_states(setup: Path, messages: list[dict]) -> list[bytes]:
    """rclpy's CDR of each message: a dict of ``sec``, ``nanosec``, ``frame_id``, ``name``, ``position``,
    ``velocity``, ``effort``."""
    return [base64.b64decode(text) for text in _run(setup, "serialize", messages)]


def deserialize_joint_states(setup: Path, data: list[bytes]) -> list[dict]:
    """What rclpy reads from each CDR message (dicts as :func:`serialize_joint_states` takes)."""
    return _run(setup, "deserialize", [base64.b64encode(d).decode() for d in data])


__all__ = ["deserialize_joint_states", "run_with_ros2", "serialize_joint_states"]

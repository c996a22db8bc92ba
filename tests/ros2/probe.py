"""A small rclpy client the ROS 2 tests run as a child process (ROS 2 sourced): it reads ``/joint_states`` and prints
JSON on stdout, so a test asks "where did the joint come to rest" in one call.

    python probe.py rest|steady JOINT [--still RATE] [--samples N] [--timeout S]

``rest`` waits until the joint's speed |v| [m/s or rad/s] stays below ``--still`` for ``--samples`` messages in a row;
``steady`` until its speed changes by less than ``--still`` from one message to the next for ``--samples`` messages
in a row (a terminal speed). Both print ``{"position": q, "velocity": v, "stamp": s, "messages": n}``; exit 1 with a
JSON ``error`` on timeout.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import JointState


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("what", choices=("rest", "steady"))
    parser.add_argument("joint")
    parser.add_argument("--still", type=float, default=1e-4)
    parser.add_argument("--samples", type=int, default=50)
    parser.add_argument("--timeout", type=float, default=60.0)
    args = parser.parse_args()
    rclpy.init()
    node = Node("jointctl_test_probe")
    seen = {"run": 0, "count": 0, "last": None}

    def on_state(msg: JointState) -> None:
        if args.joint not in msg.name:
            return
        k = list(msg.name).index(args.joint)
        seen["count"] += 1
        change = msg.velocity[k] - (seen["last"][1] if seen["last"] else float("inf"))
        moving = abs(msg.velocity[k] if args.what == "rest" else change)
        seen["run"] = seen["run"] + 1 if moving < args.still else 0
        seen["last"] = (msg.position[k], msg.velocity[k], msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec)

    node.create_subscription(JointState, "/joint_states", on_state, 10)
    deadline = time.monotonic() + args.timeout
    while seen["run"] < args.samples and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    if seen["run"] < args.samples:
        print(json.dumps({"error": f"{args.joint} not {args.what} within {args.timeout} s", "last": seen["last"],
                          "messages": seen["count"]}))
        return 1
    q, v, stamp = seen["last"]
    print(json.dumps({"position": q, "velocity": v, "stamp": stamp, "messages": seen["count"]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())

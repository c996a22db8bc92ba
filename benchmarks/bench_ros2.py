"""jointctl serve --ros2 on a real ROS 2 (loopback DDS): /joint_states at 1 kHz, beside the ROS 1 figures
(bench_ros.py measures the same things on ROS 1).

*Latency*: ``jointctl serve one_dof --ros2`` with the joint state controller at 1000 Hz, and an rclpy subscriber
process recording receive time minus header stamp for 10 s: delivered rate, latency p50/p99 (the stamp is the wall
clock at loop time zero plus loop time, so the latency includes how late the loop runs).
*Jitter*: the spacing of receive times (an upper bound of the loop's period jitter with ROS 2 attached), and the
node's own ``loop_lateness`` reports. Its target is 1 ms where ROS 1's is 0.5 ms: rclpy builds and publishes each
message in Python with the GIL held (about 70 µs a message at 1 kHz, against rospy's queue hand-off), measured on an
idle machine at 0.50 ms (ROS 1: 0.19 ms) in the same minute.

Needs a ROS 2 (make ros2); without one, returns no rows.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.bench_ros import _percentile
from benchmarks.common import Result

ROOT = Path(__file__).resolve().parent.parent
LISTEN_S = 10.0
RATE = "--set=controllers.joint_state_controller.publish_rate=1000"
DOMAIN = "197"

_LISTENER = r'''
import json, sys, time
import rclpy
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
seconds = float(sys.argv[1])
rclpy.init()
node = Node("bench_listener")
rows, lateness = [], []
node.create_subscription(JointState, "/joint_states",
                         lambda m: rows.append((time.time(), m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec)), 1000)
node.create_subscription(Float64MultiArray, "/jointctl_one_DOF_robot/loop_lateness",
                         lambda m: lateness.append(list(m.data)), 100)
deadline = time.time() + 60
while not rows and time.time() < deadline:
    rclpy.spin_once(node, timeout_sec=0.1)
end = time.time() + 1.0  # warm-up
while time.time() < end:
    rclpy.spin_once(node, timeout_sec=0.01)
rows.clear(); lateness.clear()
end = time.time() + seconds
while time.time() < end:
    rclpy.spin_once(node, timeout_sec=0.01)
print(json.dumps({"rows": rows, "lateness": lateness}))
'''


def _environment(home: str) -> dict | None:
    sys.path.insert(0, str(ROOT))
    from tests.ros2.environment import LOOPBACK_DDS, ros2_setup, sourced_variables

    setup = ros2_setup()
    if setup is None:
        return None
    import os

    env = dict(os.environ)
    env.update(sourced_variables(setup))
    env.update({"ROS_DOMAIN_ID": DOMAIN, "CYCLONEDDS_URI": LOOPBACK_DDS.as_uri(), "ROS_LOG_DIR": home,
                "PYTHONPATH": f"{ROOT / 'src'}:{env.get('PYTHONPATH', '')}".rstrip(":")})
    return env


def latency() -> list[Result]:
    with tempfile.TemporaryDirectory() as home:
        env = _environment(home)
        if env is None:
            print("bench ros2: no ROS 2 (make ros2): skipped", file=sys.stderr)
            return []
        serve = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--ros2", "--controllers",
                                  "position", RATE], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            out = subprocess.run([sys.executable, "-c", _LISTENER, str(LISTEN_S)], env=env, capture_output=True,
                                 text=True, timeout=LISTEN_S + 90, check=True)
        finally:
            serve.terminate()
            try:
                serve.wait(10)
            except subprocess.TimeoutExpired:
                serve.kill()
    heard = json.loads(out.stdout.strip().splitlines()[-1])
    rows, lateness = heard["rows"], heard["lateness"]
    name = "ros2 one_dof joint_states"
    lat_ms = [(recv - stamp) * 1e3 for recv, stamp in rows]
    spacing = [(b[0] - a[0]) * 1e3 - 1.0 for a, b in zip(rows, rows[1:])]
    p50, p99 = statistics.median(lat_ms), _percentile(lat_ms, 0.99)
    typical_p99 = statistics.median(r[1] for r in lateness) if lateness else float("nan")
    rate = len(rows) / LISTEN_S
    return [
        Result(name, "delivered rate (published at 1000 Hz)", rate, "Hz", ">= 990", rate >= 990),
        Result(name, "latency p50 (receive - header stamp)", p50, "ms"),
        Result(name, "latency p99", p99, "ms", "<= 1", p99 <= 1.0),
        Result(name, "receive spacing |dt - 1 ms| p99 (jitter bound)", _percentile([abs(s) for s in spacing], 0.99),
               "ms"),
        Result(name, "loop period jitter p99 (node's own lateness, median second)", typical_p99, "ms",
               "<= 1", typical_p99 <= 1.0),
        Result(name, "loop period jitter p99, worst second", max(r[1] for r in lateness) if lateness else
               float("nan"), "ms"),
    ]


def run() -> list[Result]:
    return latency()

"""What ``--hardware ros2`` hears and sends: ROS 2's own ``ros2_control_node`` at 1 kHz on loopback.

The rig of the ROS 2 tools' tests (tests/ros2/mock_rig: the mock hardware under pid_controllers), its
controller manager at 1000 Hz, and one rclpy process built as the tools' hardware is
(``jointctl.ros2.graph_client``: its own context, spun in a background thread), for ``LISTEN_S``:

*State*: ``/joint_states`` from the joint_state_broadcaster, every message's receive time minus its header
stamp (the time the controller manager gave that cycle's update, so the cycle's own work is in it):
delivered rate, latency p50/p99/max, the largest gap between stamps (the manager's late cycles).
*Reference*: a new position reference to ``/pid_controller/reference`` every 10 ms (best effort, as the
tools send it), and the stamp of the first ``~/controller_state`` that shows it, minus the time it was
sent: how long a reference takes to reach the loop (the topic and the wait for the next cycle, 0.5 ms on
average at 1 kHz).

Needs a ROS 2 with ros2_control (``/opt/ros/<distro>/setup.bash``, or ``JOINTCTL_ROS2_SETUP``); without
it, returns no rows.
"""

from __future__ import annotations

import glob
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import Result

ROOT = Path(__file__).resolve().parent.parent
RIG = ROOT / "tests" / "ros2" / "mock_rig"
LOOPBACK = ROOT / "tests" / "ros2" / "cyclonedds-loopback.xml"
LISTEN_S = 10.0
DOMAIN = 229  # outside the tests' 120..199

_LISTENER = r'''
import json, math, sys, threading, time
from control_msgs.msg import MultiDOFCommand, MultiDOFStateStamped
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from jointctl.ros2.graph_client import GraphClient

seconds = float(sys.argv[1])
graph = GraphClient("bench_ros2_tools")
node = graph.node
states, seen = [], []
stamp = lambda h: h.stamp.sec + 1e-9 * h.stamp.nanosec
node.create_subscription(JointState, "/joint_states", lambda m: states.append((time.time(), stamp(m.header))),
                         QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE))
node.create_subscription(MultiDOFStateStamped, "/pid_controller/controller_state",
                         lambda m: seen.append((stamp(m.header), m.dof_states[0].reference)),
                         QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE))
publisher = node.create_publisher(MultiDOFCommand, "/pid_controller/reference",
                                  QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
graph.wait(lambda: publisher.get_subscription_count() > 0 and states, 30)
time.sleep(1.0)  # warm-up
states.clear()
sent = []
start = time.time()
end = start + seconds
k = 0
while time.time() < end:
    k += 1
    value = 1e-4 * k  # a new value each time: the first state showing it is its arrival
    sent.append((time.time(), value))
    publisher.publish(MultiDOFCommand(dof_names=["joint1"], values=[value], values_dot=[math.nan]))
    time.sleep(0.01)
time.sleep(0.2)
received = [row for row in states if start <= row[0] < end]
arrivals = {}
for at, reference in seen:
    arrivals.setdefault(reference, at)
delays = [arrivals[value] - t for t, value in sent if value in arrivals]
print(json.dumps({"states": received, "delays": delays, "sent": len(sent)}))
graph.close()
'''


def _setup() -> Path | None:
    given = os.environ.get("JOINTCTL_ROS2_SETUP")
    for setup in ([given] if given else sorted(glob.glob("/opt/ros/*/setup.bash"))):
        prefix = Path(setup).parent
        if Path(setup).is_file() and (prefix / "lib" / "controller_manager" / "ros2_control_node").exists():
            return Path(setup)
    return None


def _env(setup: Path, log_dir: str) -> dict:
    out = subprocess.run(["bash", "-c", f'source "{setup}" >/dev/null 2>&1; env -0'], capture_output=True,
                         check=True).stdout.decode()
    env = dict(item.split("=", 1) for item in out.split("\0") if "=" in item)
    env.update({"ROS_DOMAIN_ID": str(DOMAIN), "CYCLONEDDS_URI": LOOPBACK.as_uri(), "ROS_LOG_DIR": log_dir,
                "PYTHONPATH": f"{ROOT / 'src'}:{env.get('PYTHONPATH', '')}"})
    env.pop("ROS_MASTER_URI", None)
    return env


def _percentile(values: list[float], q: float) -> float:
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))]


def run() -> list[Result]:
    setup = _setup()
    if setup is None:
        print("bench_ros2_tools: no ROS 2 with ros2_control (make ros2): skipped", file=sys.stderr)
        return []
    import yaml

    with tempfile.TemporaryDirectory() as folder:
        env = _env(setup, folder)
        prefix = setup.parent
        controllers = yaml.safe_load((RIG / "controllers.yaml").read_text())
        controllers["controller_manager"]["ros__parameters"]["update_rate"] = 1000
        (Path(folder) / "controllers.yaml").write_text(yaml.safe_dump(controllers))
        (Path(folder) / "rsp.yaml").write_text(yaml.safe_dump({"robot_state_publisher": {"ros__parameters": {
            "robot_description": (RIG / "robot.urdf").read_text()}}}))
        processes = [subprocess.Popen([str(prefix / "lib/robot_state_publisher/robot_state_publisher"), "--ros-args",
                                       "--params-file", f"{folder}/rsp.yaml"], env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL),
                     subprocess.Popen([str(prefix / "lib/controller_manager/ros2_control_node"), "--ros-args",
                                       "--params-file", f"{folder}/controllers.yaml"], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
        try:
            subprocess.run([str(prefix / "lib/controller_manager/spawner"), "joint_state_broadcaster",
                            "pid_controller", "--controller-manager-timeout", "60"], env=env, check=True,
                           capture_output=True, timeout=120)
            out = subprocess.run([sys.executable, "-c", _LISTENER, str(LISTEN_S)], env=env, capture_output=True,
                                 text=True, timeout=LISTEN_S + 90, check=True)
        finally:
            for process in processes:
                process.terminate()
                try:
                    process.wait(10)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait(5)
            subprocess.run(["ros2", "daemon", "stop"], env=env, capture_output=True, timeout=20)
            time.sleep(0.1)
    heard = json.loads(out.stdout.strip().splitlines()[-1])
    states, delays = heard["states"], heard["delays"]
    latency = [(received - stamp) * 1e3 for received, stamp in states]
    gaps = [(b[1] - a[1]) * 1e3 for a, b in zip(states, states[1:])]
    rate = len(states) / LISTEN_S
    delays_ms = [d * 1e3 for d in delays]
    name = "ros2 tools: ros2_control_node at 1 kHz"
    return [
        Result(name, "joint_states delivered rate (published at 1000 Hz)", rate, "Hz", ">= 990", rate >= 990),
        Result(name, "joint_states latency p50 (receive - header stamp)", statistics.median(latency), "ms"),
        # The stamp is the cycle's start (before the hardware's read and the controllers' update): two cycles.
        Result(name, "joint_states latency p99", _percentile(latency, 0.99), "ms", "<= 2",
               _percentile(latency, 0.99) <= 2.0),
        Result(name, "joint_states latency max", max(latency), "ms"),
        Result(name, "joint_states stamp spacing max (late cycles)", max(gaps), "ms"),
        Result(name, f"reference -> controller p50 ({len(delays)} of {heard['sent']} seen)",
               statistics.median(delays_ms), "ms"),
        Result(name, "reference -> controller p99", _percentile(delays_ms, 0.99), "ms"),
    ]

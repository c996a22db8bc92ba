"""jointctl serve on a real ROS 1 graph (loopback): joint_states at 1 kHz and a short soak.

*Latency*: a master, ``jointctl serve one_dof`` with the joint state controller at 1000 Hz, and a
subscriber process recording receive time minus header stamp for 10 s: delivered rate, latency
p50/p99. The header stamp is the wall clock at loop time zero plus loop time, so the latency
includes how late the loop runs against its ideal schedule.
*Jitter*: the stamps are ideal (loop time is k x 1 ms), so their spacing shows nothing; the
spacing of *receive* times is reported instead: an upper bound of the loop's period jitter with
ROS attached (loop lateness plus transport).
*Soak*: two phases of JOINTCTL_SOAK_S / 2 each (default 60 s in all): the position controllers with
a command stream at 100 Hz, then the trajectory controllers with a FollowJointTrajectory goal every
3 s; joint_states at 1 kHz subscribed throughout. Resident memory growth of the serve process from
10 s in to the end.

Needs ROS 1 (make ros); without it, returns no rows.
"""

from __future__ import annotations

import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import Result

ROOT = Path(__file__).resolve().parent.parent
ROS_BUILD = ROOT / "build" / "ros"
LISTEN_S = 10.0
SOAK_S = float(os.environ.get("JOINTCTL_SOAK_S", "60"))
RATE = "--set=controllers.joint_state_controller.publish_rate=1000"
JOINT_STATES = "/one_DOF_robot/joint_states"

_LISTENER = r'''
import json, sys, time, rospy
from sensor_msgs.msg import JointState
seconds = float(sys.argv[1])
rospy.init_node("bench_listener", anonymous=True)
from std_msgs.msg import Float64MultiArray
rows, lateness = [], []
rospy.Subscriber("/one_DOF_robot/joint_states", JointState,
                 lambda m: rows.append((time.time(), m.header.stamp.to_sec())), queue_size=1000)
rospy.Subscriber("/one_DOF_robot/loop_lateness", Float64MultiArray,
                 lambda m: lateness.append(list(m.data)), queue_size=100)
deadline = time.time() + 30
while not rows and time.time() < deadline:
    time.sleep(0.01)
time.sleep(1.0)  # warm-up
rows.clear()
lateness.clear()
time.sleep(seconds)
print(json.dumps({"rows": list(rows), "lateness": list(lateness)}))
'''

_DRIVER = r'''
import json, math, sys, time, rospy
mode, seconds = sys.argv[1], float(sys.argv[2])
rospy.init_node("bench_driver", anonymous=True)
from sensor_msgs.msg import JointState
count = [0]
rospy.Subscriber("/one_DOF_robot/joint_states", JointState, lambda m: count.__setitem__(0, count[0] + 1),
                 queue_size=1000)
sent = ok = 0
end = time.time() + seconds
if mode == "commands":
    from std_msgs.msg import Float64
    pub = rospy.Publisher("/one_DOF_robot/joint1_position_controller/command", Float64, queue_size=10)
    t0 = time.time()
    while time.time() < end:
        pub.publish(Float64(-0.5 + 0.05 * math.sin(2 * math.pi * 0.5 * (time.time() - t0))))
        sent += 1
        time.sleep(0.01)
    ok = sent
else:
    import actionlib
    from control_msgs.msg import FollowJointTrajectoryAction, FollowJointTrajectoryGoal
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    client = actionlib.SimpleActionClient(
        "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory", FollowJointTrajectoryAction)
    client.wait_for_server(rospy.Duration(20))
    k = 0
    while time.time() < end - 3.5:
        goal = FollowJointTrajectoryGoal()
        goal.trajectory = JointTrajectory(joint_names=["joint1"])
        goal.trajectory.points.append(JointTrajectoryPoint(positions=[-0.45 if k % 2 else -0.35],
                                                           time_from_start=rospy.Duration(2.0)))
        client.send_goal(goal)
        sent += 1
        if client.wait_for_result(rospy.Duration(10)) and client.get_state() == 3:
            ok += 1
        k += 1
        time.sleep(max(0.0, 3.0 - 2.0))
print(json.dumps({"sent": sent, "ok": ok, "states": count[0]}))
'''


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(home: str) -> dict:
    port = _free_port()
    env = dict(os.environ)
    env.update({
        "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_HOSTNAME": "127.0.0.1", "ROS_HOME": home,
        "ROS_PACKAGE_PATH": f"{ROS_BUILD / 'src'}:{env.get('ROS_PACKAGE_PATH', '')}".rstrip(":"),
        "PYTHONPATH": f"{ROS_BUILD / 'py'}:{ROOT / 'src'}:{env.get('PYTHONPATH', '')}".rstrip(":"),
    })
    return env


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


class _Graph:
    """A master and ``jointctl serve one_dof --controllers NAME`` at 1 kHz joint states."""

    def __init__(self, controllers: str) -> None:
        self.home = tempfile.TemporaryDirectory()
        self.env = _env(self.home.name)
        port = int(self.env["ROS_MASTER_URI"].rsplit(":", 1)[1])
        self.master = subprocess.Popen(["rosmaster", "--core", "-p", str(port)], env=self.env,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.serve = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--controllers",
                                       controllers, RATE], env=self.env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def python(self, code: str, *args: str, timeout: float) -> object:
        out = subprocess.run([sys.executable, "-c", code, *args], env=self.env, capture_output=True, text=True,
                             timeout=timeout, check=True)
        return json.loads(out.stdout.strip().splitlines()[-1])

    def close(self) -> None:
        for p in (self.serve, self.master):
            p.terminate()
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(5)
        self.home.cleanup()


def _percentile(values: list[float], q: float) -> float:
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))]


def latency() -> list[Result]:
    graph = _Graph("position")
    try:
        heard = graph.python(_LISTENER, str(LISTEN_S), timeout=LISTEN_S + 60)
    finally:
        graph.close()
    rows, lateness = heard["rows"], heard["lateness"]
    loop_p99 = max(r[1] for r in lateness) if lateness else float("nan")
    typical_p99 = statistics.median(r[1] for r in lateness) if lateness else float("nan")
    name = "ros one_dof joint_states"
    lat_ms = [(recv - stamp) * 1e3 for recv, stamp in rows]
    spacing = [(b[0] - a[0]) * 1e3 - 1.0 for a, b in zip(rows, rows[1:])]
    stamp_spacing = [(b[1] - a[1]) * 1e3 for a, b in zip(rows, rows[1:])]
    p50, p99 = statistics.median(lat_ms), _percentile(lat_ms, 0.99)
    jitter = _percentile([abs(s) for s in spacing], 0.99)
    rate = len(rows) / LISTEN_S
    return [
        Result(name, "delivered rate (published at 1000 Hz)", rate, "Hz", ">= 990", rate >= 990),
        Result(name, "latency p50 (receive - header stamp)", p50, "ms"),
        Result(name, "latency p99", p99, "ms", "<= 1", p99 <= 1.0),
        Result(name, "latency max", max(lat_ms), "ms"),
        Result(name, "receive spacing |dt - 1 ms| p99 (jitter bound)", jitter, "ms"),
        Result(name, "stamp spacing max (gaps in loop time)", max(stamp_spacing), "ms"),
        Result(name, "loop period jitter p99 (node's own lateness, median second)", typical_p99, "ms",
               "<= 0.5", typical_p99 <= 0.5),
        Result(name, "loop period jitter p99, worst second", loop_p99, "ms"),
    ]


def soak_phase(controllers: str, mode: str, seconds: float) -> list[Result]:
    graph = _Graph(controllers)
    try:
        driver = subprocess.Popen([sys.executable, "-c", _DRIVER, mode, str(seconds)], env=graph.env,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(min(10.0, seconds / 3))
        start = _rss_mb(graph.serve.pid)
        out, err = driver.communicate(timeout=seconds + 60)
        end = _rss_mb(graph.serve.pid)
        alive = graph.serve.poll() is None
    finally:
        graph.close()
    if driver.returncode != 0:
        raise RuntimeError(f"soak driver failed: {err[-1000:]}")
    stats = json.loads(out.strip().splitlines()[-1])
    growth = end - start
    name = f"ros soak {controllers} ({seconds:.0f} s)"
    what = "commands at 100 Hz" if mode == "commands" else "goals every 3 s"
    rows = [
        Result(name, f"{what}: sent", stats["sent"], ""),
        Result(name, "resident memory at the end", end, "MB"),
        Result(name, "resident memory growth", growth, "MB", "< 10", growth < 10 and alive),
    ]
    if mode == "goals":
        rows.insert(1, Result(name, "goals succeeded", stats["ok"], "", f"= {stats['sent']}",
                              stats["ok"] == stats["sent"] > 0))
    return rows


def run() -> list[Result]:
    try:
        import rospy  # noqa: F401
    except ImportError:
        print("bench_ros: ROS 1 is not installed (make ros): skipped", file=sys.stderr)
        return []
    half = SOAK_S / 2
    return latency() + soak_phase("position", "commands", half) + soak_phase("trajectory", "goals", half)

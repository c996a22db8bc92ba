"""The industrial bridge (simple_message on loopback): throughput, state latency, tracking.

*Points per second*: ``jointctl controller one_dof`` in its own process and a client here streaming
2000 JOINT_TRAJ_PT requests of 1 ms each through the streaming handshake: one request in flight,
the controller holding its reply while its 32-point queue is full, so the rate is set by the
controller taking one point per 1 ms cycle (the ideal is 1000/s). Baseline in the same run: PING
round trips per second on the same connection (what the socket and the framing allow).
*State latency*: a simple_message peer here reports JOINT_POSITION at 50 Hz (each a distinct value,
its send time kept) to ``jointctl serve one_dof --hardware industrial``; a ROS subscriber process
records when each value arrives on ``/joint_states``: p50/p99 of arrival minus send. Baseline: the
serve loop's period (1 ms: what a report relayed at the next cycle would wait at most; the node
relays each as it reads it).
*Tracking*: the arm's pre-pose (zeros -> [0, 1, 0, -2, 0, 1, 0], the chapter's 13.33 s) through
the bridge (the executor streaming 50 Hz points to ``jointctl controller arm7dof``, 50 Hz state)
and in-process, both as the chapter's streamer does it (linear points at 50 Hz, positions only:
the baseline) and with jointctl's defaults (cubic at 1 kHz, model feed-forward); RMS over the
motion of the executor's desired minus the measured position as the executor sees it, all joints.

*Stop*: ``jointctl controller arm7dof``, every joint at its URDF speed limit (one point, speed
fraction 1), STOP sent 1.5 s into it: time from the STOP until the reported joints move less than
1e-4 rad in the next 0.5 s (target <= 0.5 s, an industrial controller's category-2 stop).
*Goal completion*: a 4 s goal of the arm (10 points of a smoothstep, with velocities, within the
limits) through IndustrialHardware against the controllers users own (tests/hardware/
controller_doubles.py): completion (the goal's SUCCEEDED) over the goal's duration; target <= 1.05
against the one reaching points over their durations (10 ms tick a point) and the one taking FULL
points by time. The same goal resampled at 50 Hz against the first, for comparison.

Needs ROS 1 (make ros) for the latency only; the rest runs without it.
"""

from __future__ import annotations

import json
import math
import os
import re
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from benchmarks.common import Result

ROOT = Path(__file__).resolve().parent.parent
ROS_BUILD = ROOT / "build" / "ros"
PRE_POSE = [0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0]
POINTS = 2000
PINGS = 2000
LATENCY_REPORTS = 250
#: The chapter's streamer in-process (the arm7dof_pose experiment's chapter_mode): linear points at
#: 50 Hz, positions only, gravity feed-forward only: what the bridge does, without the socket.
CHAPTER_STREAMER = (
    "controllers.arm7dof_trajectory_controller.interpolation=linear",
    "controllers.arm7dof_trajectory_controller.stream_rate_hz=50",
    "controllers.arm7dof_trajectory_controller.velocity_feedforward=false",
    *(f"controllers.joint{k}_position_controller.feedforward.{term}=false"
      for k in range(7) for term in ("damping", "inertia")),
)


def _controller(robot: str, *extra: str) -> tuple[subprocess.Popen, int, int]:
    process = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "controller", robot, "--host", "127.0.0.1",
                                "--motion-port", "0", "--state-port", "0", *extra],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                               env=dict(os.environ, PYTHONPATH=f"{ROOT / 'src'}:{os.environ.get('PYTHONPATH', '')}"))
    match = re.search(r"motion port (\d+), state port (\d+)", process.stdout.readline())
    if match is None:
        process.kill()
        raise RuntimeError(f"jointctl controller {robot} did not start")
    return process, int(match.group(1)), int(match.group(2))


def _stop(process: subprocess.Popen) -> None:
    process.terminate()
    try:
        process.wait(15)
    except subprocess.TimeoutExpired:
        process.kill()


def _throughput() -> list[Result]:
    from jointctl.wire.simple_message import CommType, JointTrajPt, PacketReader, Ping, ReplyCode, encode

    process, motion, _ = _controller("one_dof")
    try:
        sock = socket.create_connection(("127.0.0.1", motion), timeout=30)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        reader = PacketReader()

        def request(packet: bytes) -> None:
            sock.sendall(packet)
            while not (replies := reader.feed(sock.recv(4096))):
                pass
            if replies[0].reply_code != ReplyCode.SUCCESS:  # a refusal is fast, and no throughput
                raise RuntimeError(f"the controller refused a request: {replies[0]}")

        ping = encode(Ping(), CommType.SERVICE_REQUEST)
        t0 = time.perf_counter()
        for _ in range(PINGS):
            request(ping)
        ping_rate = PINGS / (time.perf_counter() - t0)
        request(encode(JointTrajPt(0, (-0.5,), 1.0, 0.0), CommType.SERVICE_REQUEST))
        points = [encode(JointTrajPt(k, (-0.5 + 1e-4 * (k % 2),), 1.0, 0.001), CommType.SERVICE_REQUEST)
                  for k in range(1, POINTS + 1)]
        t0 = time.perf_counter()
        for packet in points:
            request(packet)
        point_rate = POINTS / (time.perf_counter() - t0)
        sock.close()
    finally:
        _stop(process)
    return [
        Result("industrial", "PING round trips (baseline)", ping_rate, "/s"),
        Result("industrial", "points through the streaming handshake", point_rate, "/s", ">= 500/s",
               point_rate >= 500),
        Result("industrial", "points / PING rate", point_rate / ping_rate, "x"),
    ]


_LISTENER = r'''
import json, sys, time, rospy
from sensor_msgs.msg import JointState
count = int(sys.argv[1])
rospy.init_node("bench_industrial_listener", anonymous=True)
rows = []
rospy.Subscriber("/joint_states", JointState, lambda m: rows.append((time.time(), m.position[0])), queue_size=1000)
deadline = time.time() + 60
while len(rows) < count and time.time() < deadline:
    time.sleep(0.01)
print(json.dumps(rows))
'''


class _ReportingPeer:
    """A controller stand-in: JOINT_POSITION every 20 ms with a new value each, send times kept."""

    def __init__(self) -> None:
        from jointctl.wire.simple_message import JointPosition, RobotStatus, encode

        self.sent: dict[float, float] = {}
        self.closing = threading.Event()
        self.servers = [socket.create_server(("127.0.0.1", 0)) for _ in range(2)]
        self.motion_port, self.state_port = (s.getsockname()[1] for s in self.servers)
        self._encode, self._position, self._status = encode, JointPosition, RobotStatus
        threading.Thread(target=self._state, daemon=True).start()
        threading.Thread(target=self._motion, daemon=True).start()

    def _motion(self) -> None:
        conn, _ = self.servers[0].accept()
        while not self.closing.is_set() and conn.recv(4096):
            pass

    def _state(self) -> None:
        conn, _ = self.servers[1].accept()
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        k = 0
        status = self._encode(self._status(1, 0, 0, 0, 0, 2, 1))
        while not self.closing.is_set():
            value = -0.75 + (k % 4096) * 2.0**-14  # exact in float32, distinct for 4096 reports
            packet = self._encode(self._position(k, (value,)))
            self.sent[value] = time.time()
            try:
                conn.sendall(packet + status)
            except OSError:  # the node went away: the run is over
                return
            k += 1
            time.sleep(0.02)

    def close(self) -> None:
        self.closing.set()
        for server in self.servers:
            server.close()


def _latency() -> list[Result]:
    try:
        import rospy  # noqa: F401
    except ImportError:
        return []
    home = tempfile.TemporaryDirectory()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = dict(os.environ)
    env.update({"ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_HOSTNAME": "127.0.0.1", "ROS_HOME": home.name,
                "ROS_PACKAGE_PATH": f"{ROS_BUILD / 'src'}:{env.get('ROS_PACKAGE_PATH', '')}".rstrip(":"),
                "PYTHONPATH": f"{ROS_BUILD / 'py'}:{ROOT / 'src'}:{env.get('PYTHONPATH', '')}".rstrip(":")})
    peer = _ReportingPeer()
    master = subprocess.Popen(["rosmaster", "--core", "-p", str(port)], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    serve = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--hardware", "industrial",
                              "--robot-ip", "127.0.0.1", "--motion-port", str(peer.motion_port), "--state-port",
                              str(peer.state_port)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        out = subprocess.run([sys.executable, "-c", _LISTENER, str(LATENCY_REPORTS)], env=env, capture_output=True,
                             text=True, timeout=120)
        rows = json.loads(out.stdout.strip().splitlines()[-1])
    finally:
        for process in (serve, master):
            _stop(process)
        peer.close()
        home.cleanup()
    delays = sorted((received - peer.sent[value]) * 1e3 for received, value in rows[20:] if value in peer.sent)
    if not delays:
        return [Result("industrial", "state latency p99", math.nan, "ms", "<= 5 ms", False)]
    p99 = delays[min(len(delays) - 1, int(0.99 * len(delays)))]
    return [
        Result("industrial", "state latency controller -> joint_states p50", statistics.median(delays), "ms"),
        Result("industrial", "state latency controller -> joint_states p99", p99, "ms", "<= 5 ms", p99 <= 5.0),
        Result("industrial", "state latency p99 / loop period (1 ms)", p99 / 1.0, "x"),
    ]


def _tracking_rms(session, executor, duration_s: float) -> float:
    """Run ``session`` with the pre-pose goal sent at 0.5 s; RMS of desired - actual while it moves."""
    errors: list[float] = []
    last = [None]

    def observe(time_s: float) -> None:
        feedback = executor.latest_feedback
        if feedback is not last[0] and 0.5 < time_s < 0.5 + 13.4:
            last[0] = feedback
            errors.extend(feedback.errors)

    session.loop.add_observer(observe)
    session.loop.add_input(_send_once(executor, 0.5))
    session.run(duration_s)
    return math.sqrt(sum(e * e for e in errors) / len(errors))


def _send_once(executor, at_s: float):
    sent = []

    def send(time_s: float) -> None:
        if not sent and time_s >= at_s:
            sent.append(executor.submit(executor.plan_path([PRE_POSE], timing="chapter"), now_s=time_s))

    return send


def _tracking() -> list[Result]:
    from jointctl.hardware.industrial import IndustrialHardware
    from jointctl.scenario.session import Session
    from jointctl.scenario.spec import scenario_for_robot

    def in_process(overrides=()) -> float:
        session = Session(scenario_for_robot("arm7dof", "trajectory", overrides))
        return _tracking_rms(session, session.manager.controller("arm7dof_trajectory_controller"), 15.0)

    rms_in_process = in_process()
    rms_chapter = in_process(CHAPTER_STREAMER)
    process, motion, state = _controller("arm7dof")
    try:
        scenario = scenario_for_robot("arm7dof", "industrial")
        # The chapter's timing gives no velocities: a speed fraction of 1 leaves the timing to the points'
        # durations (ROS-I's 10 % default would make the controller take 5x as long).
        hardware = IndustrialHardware([f"joint{k}" for k in range(7)], robot_ip="127.0.0.1", motion_port=motion,
                                      state_port=state, default_speed=1.0)
        hardware.connect()
        bridged = Session(scenario, hardware=hardware, realtime=True)
        rms_bridge = _tracking_rms(bridged, bridged.manager.controller("arm7dof_trajectory_controller"), 15.0)
        hardware.close()
    finally:
        _stop(process)
    ratio = rms_bridge / rms_chapter
    return [
        Result("industrial", "pre-pose tracking RMS in-process, chapter's streamer (baseline)", rms_chapter * 1e3,
               "mrad"),
        Result("industrial", "pre-pose tracking RMS in-process, jointctl's default", rms_in_process * 1e3, "mrad"),
        Result("industrial", "pre-pose tracking RMS through the bridge", rms_bridge * 1e3, "mrad"),
        Result("industrial", "bridge / in-process chapter's streamer", ratio, "x", "<= 2x", ratio <= 2.0),
        Result("industrial", "bridge / in-process default", rms_bridge / rms_in_process, "x"),
    ]


def _stop_time() -> list[Result]:
    from jointctl.hardware.industrial import IndustrialHardware

    speeds = [0.2, 0.2, 0.3, 0.3, 0.4, 0.5, 0.4]  # the arm's URDF limits [rad/s]
    process, motion, state = _controller("arm7dof")
    try:
        hardware = IndustrialHardware([f"joint{k}" for k in range(7)], robot_ip="127.0.0.1", motion_port=motion,
                                      state_port=state, max_velocities=speeds)
        hardware.connect()
        start = list(hardware.position)
        target = [q + 3.0 * v for q, v in zip(start, speeds)]  # 3 s at full speed on every joint
        hardware.execute_trajectory(range(7), [3.0], [target], [speeds])  # speed fraction 1
        time.sleep(1.5)
        stopped_at = time.monotonic()
        hardware.stop_motion()
        samples = []
        while time.monotonic() < stopped_at + 3.0:
            hardware.read()
            samples.append((time.monotonic() - stopped_at, list(hardware.position)))
            time.sleep(0.005)
        hardware.close()
    finally:
        _stop(process)
    still = None
    for k, (t, q) in enumerate(samples):
        later = [p for s, p in samples[k:] if s <= t + 0.5]
        if samples[-1][0] >= t + 0.5 and max(max(abs(a - b) for a, b in zip(p, q)) for p in later) < 1e-4:
            still = t
            break
    value = still if still is not None else math.inf
    return [Result("industrial", "STOP at the arm's full speed -> still (< 1e-4 rad / 0.5 s)", value, "s",
                   "<= 0.5 s", value <= 0.5)]


def _completion() -> list[Result]:
    import numpy as np

    from jointctl.hardware.industrial import IndustrialHardware
    from jointctl.model.loader import load_robot_model
    from jointctl.scenario.session import Session
    from jointctl.scenario.spec import scenario_for_robot
    from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint
    from tests.hardware.controller_doubles import ControllerDouble

    scenario = scenario_for_robot("arm7dof", "industrial")
    robot = load_robot_model(scenario.robot.description)
    joints = tuple(j.name for j in robot.movable_joints)
    vmax = tuple(j.range_and_speed()[2] for j in robot.movable_joints)
    duration, delta = 4.0, 0.3  # peak speed 1.5 x 0.3 / 4 = 0.11 rad/s, within every limit
    times = duration * np.arange(1, 11) / 10
    tau = times / duration
    goal = JointTrajectory(joints, tuple(
        JointTrajectoryPoint(positions=tuple(q + delta * (3 * x**2 - 2 * x**3) for q in PRE_POSE),
                             velocities=(delta * 6 * x * (1 - x) / duration,) * 7, time_from_start_s=float(t))
        for t, x in zip(times, tau)))

    def complete(kind: str, **options) -> float:
        double = ControllerDouble(kind, PRE_POSE, vmax)
        hardware = IndustrialHardware(joints, robot_ip="127.0.0.1", motion_port=double.motion_port,
                                      state_port=double.state_port, max_velocities=vmax, **options)
        try:
            hardware.connect()
            session = Session(scenario, hardware=hardware, realtime=True)
            executor = session.manager.controller("arm7dof_trajectory_controller")
            handle = executor.submit(goal, now_s=session.loop.time_s)
            session.loop.add_input(lambda t: session.loop.request_stop() if handle.done else None)
            session.run(4 * duration)
            assert handle.result is not None and handle.result.status.name == "SUCCEEDED", handle.result
            return handle.result.time_s / duration
        finally:
            hardware.close()
            double.close()

    by_duration, by_time = complete("duration"), complete("full", message="full")
    by_speed = complete("speed")
    resampled = complete("duration", points="resampled")
    return [
        Result("industrial", "goal completion / duration, controller by durations (10 ms tick a point)", by_duration,
               "x", "<= 1.05", by_duration <= 1.05),
        Result("industrial", "goal completion / duration, controller taking FULL points by time", by_time, "x",
               "<= 1.05", by_time <= 1.05),
        Result("industrial", "goal completion / duration, controller by speed fraction (last point at 10 %)",
               by_speed, "x"),
        Result("industrial", "goal completion / duration, resampled at 50 Hz, controller by durations", resampled,
               "x"),
    ]


def run() -> list[Result]:
    return _throughput() + _latency() + _tracking() + _stop_time() + _completion()


if __name__ == "__main__":
    for row in run():
        print(row)

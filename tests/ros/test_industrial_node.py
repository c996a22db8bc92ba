"""jointctl serve --hardware industrial on a real ROS graph, against a simple_message controller
double on loopback built from ROS-I's reference behaviour (tests/hardware/controller_doubles.py, the
"duration" kind): it interpolates to each point over the point's duration, its joints lag behind, it reports
in_motion truthfully and holds replies while its buffer is full. The node's wiring, ROS-Industrial's
names (joint_trajectory_action, the joint_path_command topic and service, stop_motion), stale state
and an unreachable controller."""

from __future__ import annotations

import functools
import json
import socket
import subprocess
import sys

import pytest

from jointctl.wire.simple_message import STOP_TRAJECTORY
from tests.hardware.controller_doubles import ControllerDouble
from tests.ros.conftest import run, wait_for_topic
from tests.waiting import wait_until

SERVER = "/joint_trajectory_action"
START_M = -0.5
TIMEOUT_S = 60.0

#: A rospy client in its own process (one node per process): ``follow`` sends a goal to
#: joint_trajectory_action and prints its end and the server's stamp on the result message;
#: ``publish`` puts a trajectory on the joint_path_command topic once the node subscribes.
CLIENT = r'''
import json, sys
import actionlib, rospy
from actionlib_msgs.msg import GoalStatus
from control_msgs.msg import FollowJointTrajectoryAction, FollowJointTrajectoryActionResult, FollowJointTrajectoryGoal
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

mode, points = sys.argv[1], json.loads(sys.argv[2])
rospy.init_node("jointctl_test_industrial_client", anonymous=True)
trajectory = JointTrajectory(joint_names=["joint1"])
for t, q in points:
    trajectory.points.append(JointTrajectoryPoint(positions=q, time_from_start=rospy.Duration(t)))

def wait(condition, what):
    deadline = rospy.get_time() + 30
    while not condition():
        if rospy.get_time() > deadline:
            sys.exit("timed out waiting for " + what)
        rospy.sleep(0.01)

if mode == "publish":
    # queue_size None: publish() writes to the subscriber's connection before it returns.
    pub = rospy.Publisher("/joint_path_command", JointTrajectory, queue_size=None)
    wait(lambda: pub.get_num_connections() > 0, "the node to subscribe to joint_path_command")
    pub.publish(trajectory)
else:
    stamps = []
    sub = rospy.Subscriber(SERVER + "/result", FollowJointTrajectoryActionResult,
                           lambda m: stamps.append(m.header.stamp.to_sec()))
    client = actionlib.SimpleActionClient(SERVER, FollowJointTrajectoryAction)
    if not client.wait_for_server(rospy.Duration(30)):
        sys.exit("no action server")
    wait(lambda: sub.get_num_connections() > 0, "the result topic")
    client.send_goal(FollowJointTrajectoryGoal(trajectory=trajectory))
    client.wait_for_result(rospy.Duration(60))
    wait(lambda: stamps, "the result message")
    states = {getattr(GoalStatus, n): n for n in ("PREEMPTED", "SUCCEEDED", "ABORTED", "REJECTED")}
    print(json.dumps({"state": states.get(client.get_state(), "?"), "text": client.get_goal_status_text(),
                      "stamp": stamps[-1]}))
'''.replace("SERVER", repr(SERVER))


wait_for = functools.partial(wait_until, timeout_s=TIMEOUT_S, every_s=0.01)


@pytest.fixture
def peer():
    p = ControllerDouble("duration", [START_M])
    yield p
    p.close()


def serve_industrial(serve, peer, *extra):
    return serve("one_dof", "--hardware", "industrial", "--robot-ip", "127.0.0.1",
                 "--motion-port", str(peer.motion_port), "--state-port", str(peer.state_port), *extra,
                 wait_topic="/feedback_states")


def client(env, mode: str, points, **kwargs) -> subprocess.CompletedProcess:
    return run(env, sys.executable, "-c", CLIENT, mode, json.dumps(points), timeout=90, **kwargs)


def follow(env, points) -> dict:
    return json.loads(client(env, "follow", points).stdout.strip().splitlines()[-1])


def at_rest_at(peer: ControllerDouble, target: float) -> bool:
    """The double's joint has arrived at ``target`` (float32 on the wire) and settled."""
    return not peer.moving and peer.positions[0] == pytest.approx(target, abs=1e-6)


#: The node, once the stop is over, streams the position it measured (float32) as a new trajectory:
#: the double then moves by that rounding, |q|·2⁻²⁴ < 1e-7 m. A robot still going would move mm.
STILL_M = 1e-6


def held_still(peer: ControllerDouble, reports: int = 20) -> tuple[float, float]:
    """The double's position now and after ``reports`` more state reports (0.2 s at its 100 Hz)."""
    first = peer.positions[0]
    count = len(peer.reports)
    wait_for(lambda: len(peer.reports) >= count + reports, f"{reports} more state reports")
    return first, peer.positions[0]


def rosservice(env, *args) -> str:
    return run(env, "rosservice", "call", "--wait", *args, timeout=60).stdout


def test_a_goal_through_joint_trajectory_action_succeeds_once_the_robot_is_at_rest_there(ros_env, serve, peer):
    serve_industrial(serve, peer)
    assert run(ros_env, "rosparam", "get", "/controller_joint_names").stdout.strip() == "- joint1"
    assert run(ros_env, "rosparam", "get", "/robot_ip_address").stdout.strip() == "127.0.0.1"
    status = wait_for_topic(ros_env, "/robot_status")
    assert "mode: \n  val: 2" in status and "in_motion: \n  val: 0" in status
    assert "-0.5" in wait_for_topic(ros_env, "/feedback_states")  # the double's reported position
    done = follow(ros_env, [[1.0, [-0.4]], [2.0, [-0.3]]])
    assert done["state"] == "SUCCEEDED", done
    assert peer.points[0].sequence == 0  # a motion from rest: a new trajectory
    # The goal's own points, as ROS-I's client sends them: each with its duration since the previous
    # one, and (no velocities in the goal) ROS-I's default speed fraction of 0.1
    assert [p.sequence for p in peer.points] == [0, 1]
    assert [p.duration for p in peer.points] == pytest.approx([1.0, 1.0])
    assert [p.velocity for p in peer.points] == pytest.approx([0.1, 0.1])
    assert peer.points[-1].positions[0] == pytest.approx(-0.3, abs=1e-6)
    # The double moved by itself, behind the stream, and said so; the goal succeeded only after the
    # double had reported its joint at rest at -0.3 (its first such report came before the result).
    moving = [t for t, q, in_motion in peer.reports if in_motion == 1]
    assert moving, "the double never reported in_motion"
    at_rest = [t for t, q, in_motion in peer.reports
               if t > moving[0] and in_motion == 0 and q[0] == pytest.approx(-0.3, abs=1e-6)]
    assert at_rest and at_rest[0] <= done["stamp"], (at_rest[:1], done["stamp"])
    assert "-0.3" in wait_for_topic(ros_env, "/joint_states")  # ROS-I's global joint_states


def test_the_joint_path_command_topic_moves_the_robot_and_an_empty_one_stops_it(ros_env, serve, peer):
    serve_industrial(serve, peer)
    client(ros_env, "publish", [[1.0, [-0.4]]])
    wait_for(lambda: at_rest_at(peer, -0.4), "the robot at rest at -0.4 m")
    assert [(p.sequence, p.duration) for p in peer.points] == [(0, 1.0)]  # the trajectory's own point
    # A long motion (6 s), stopped on its way by an empty trajectory.
    client(ros_env, "publish", [[6.0, [-0.1]]])
    wait_for(lambda: peer.positions[0] > -0.35 and peer.moving, "the robot on its way to -0.1 m")
    client(ros_env, "publish", [])
    wait_for(lambda: any(p.sequence == STOP_TRAJECTORY for p in peer.points), "STOP at the controller")
    wait_for(lambda: not peer.moving, "the robot at rest")
    first, later = held_still(peer)
    # It stopped where it was when STOP came: the double's 6 s line from -0.4 m passes -0.35 m at 1 s and
    # -0.2 m at 4 s, so -0.2 m allows the stop 3 s on its way; and it stays there.
    assert -0.35 < first < -0.2 and later == pytest.approx(first, abs=STILL_M)


def test_the_joint_path_command_service_moves_refuses_and_stop_motion_stops(ros_env, serve, peer):
    serve_industrial(serve, peer)
    out = rosservice(ros_env, "/joint_path_command",
                     "{trajectory: {joint_names: [joint1], points: [{positions: [-0.4], time_from_start: {secs: 1}}]}}")
    assert "val: 1" in out, out  # ServiceReturnCode SUCCESS
    wait_for(lambda: at_rest_at(peer, -0.4), "the robot at rest at -0.4 m")
    sent = len(peer.points)
    out = rosservice(ros_env, "/joint_path_command",
                     "{trajectory: {joint_names: [joint1], points: [{positions: [0.5], time_from_start: {secs: 1}}]}}")
    assert "val: -1" in out, out  # FAILURE: beyond joint1's upper limit (0 m); answered after the refusal
    # Nothing was queued for the refused one: the next accepted motion is the next thing streamed.
    out = rosservice(ros_env, "/joint_path_command",
                     "{trajectory: {joint_names: [joint1], points: [{positions: [-0.1], time_from_start: {secs: 6}}]}}")
    assert "val: 1" in out, out
    wait_for(lambda: peer.positions[0] > -0.35 and peer.moving, "the robot on its way to -0.1 m")
    assert peer.points[sent].sequence == 0 and all(-0.4 - 1e-6 <= p.positions[0] <= -0.1 + 1e-6
                                                   for p in peer.points[sent:])
    out = rosservice(ros_env, "/stop_motion")
    assert "val: 1" in out, out
    wait_for(lambda: any(p.sequence == STOP_TRAJECTORY for p in peer.points), "STOP at the controller")
    wait_for(lambda: not peer.moving, "the robot at rest")
    first, later = held_still(peer)
    assert -0.35 < first < -0.2 and later == pytest.approx(first, abs=STILL_M)  # as for the topic's stop


def test_stale_state_aborts_the_goal_saying_why(ros_env, serve, peer):
    serve_industrial(serve, peer)
    process = subprocess.Popen([sys.executable, "-c", CLIENT, "follow", json.dumps([[6.0, [-0.2]]])],
                               env=ros_env, stdout=subprocess.PIPE, text=True)
    wait_for(lambda: len(peer.points) >= 1 and peer.moving, "the goal's point sent and the robot moving")
    peer.publishing.clear()  # the controller stops reporting
    out, _ = process.communicate(timeout=60)
    done = json.loads(out.strip().splitlines()[-1])
    assert done["state"] == "ABORTED", done
    assert "no joint state from 127.0.0.1" in done["text"]


def test_an_unreachable_controller_is_one_error_line_and_exit_2(ros_env):
    with socket.socket() as bound:  # bound, not listening, and kept: nobody listens on its port
        bound.bind(("127.0.0.1", 0))
        port = bound.getsockname()[1]
        result = run(ros_env, sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--hardware", "industrial",
                     "--robot-ip", "127.0.0.1", "--motion-port", str(port), "--state-port", str(port),
                     timeout=60, check=False)
    assert result.returncode == 2
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert lines == ["jointctl: took one_dof as a built-in robot, controllers industrial",
                     f"jointctl: error: robot_ip: no industrial controller answers on its state port "
                     f"(Connection refused) (got '127.0.0.1:{port}')"], result.stderr


def test_robot_ip_is_required_with_industrial_hardware(ros_env):
    result = run(ros_env, sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--hardware", "industrial",
                 timeout=60, check=False)
    assert result.returncode == 2 and "--robot-ip: is required with --hardware industrial" in result.stderr


class BurstPeer(ControllerDouble):
    """The double whose next ``burst`` state reports leave back to back (no wait between them, so the
    node reads them within one of its 1 ms cycles, as it would after being descheduled), and then one
    every ``every_s`` again. (``state_period_s`` is read once after each report sent.)"""

    every_s = 0.05
    burst = 0

    @property
    def state_period_s(self) -> float:
        if self.burst > 0:
            self.burst -= 1
            return 0.0
        return self.every_s

    @state_period_s.setter
    def state_period_s(self, value: float) -> None:
        self.every_s = value


def test_every_state_report_is_relayed_once_as_ros_is_robot_state_does(ros_env, serve, probe):
    """ROS-I's robot_state publishes joint_states and feedback_states for each JOINT_POSITION it reads.
    Each report of the double carries its own value (2^-10 m more than the one before, exact in
    float32); 20 of them sent back to back, between two of the node's cycles, are 20 messages too."""
    peer = BurstPeer("duration", [START_M], state_period_s=0.05)  # 20 Hz between the bursts
    try:
        serve_industrial(serve, peer)
        step = peer.step_per_report = 2**-10
        fields = {"/joint_states": lambda m: m["position"][0],
                  "/feedback_states": lambda m: m["actual"]["positions"][0]}
        cursors = {topic: probe.cursor(topic) for topic in fields}
        # The probe is connected once a report sent after the cursor has come through.
        wait_for(lambda: all(probe.since(t, c) for t, c in cursors.items()), "a relayed report on both topics")
        sent = len(peer.reports)
        peer.burst = 20
        wait_for(lambda: len(peer.reports) >= sent + 20 + 2, "the burst and two reports after it")
        burst = [q for _, (q,), _ in peer.reports[sent:sent + 20]]
        last = peer.reports[-1][1][0]  # the value of the last report sent so far
        for topic, value in fields.items():
            def relayed(topic=topic, value=value):
                values = [value(m) for m in probe.since(topic, cursors[topic])]
                return values if values[-1] == last else None

            values = wait_for(relayed, f"the last report sent on {topic}")
            # One message per report, in order, from before the burst to the last: none skipped, none twice.
            assert [round((b - a) / step, 6) for a, b in zip(values, values[1:])] == [1.0] * (len(values) - 1)
            assert values[0] < burst[0]
    finally:
        peer.close()

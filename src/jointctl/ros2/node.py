"""Serve a scenario's control loop on ROS 2 the way a ros2_control robot is served (``jointctl serve --ros2``).

What a ROS 2 user's tools expect of a ros2_control robot, with jointctl's simulated robot as the hardware:

- ``/controller_manager`` and its services (:mod:`jointctl.ros2.controller_manager`): ``ros2 control
  list_controllers``, ``switch_controllers``, ``list_hardware_interfaces``... work;
- each running controller as a node of its name with ros2_controllers' topics, actions and parameters
  (:mod:`jointctl.ros2.controllers`): ``/joint_states``, pid_controller's ``~/reference`` and ``gains.*``,
  joint_trajectory_controller's ``~/follow_joint_trajectory``;
- from the node ``/jointctl_<robot>`` (robot_state_publisher's part): ``/robot_description`` (std_msgs/msg/String,
  reliable, transient local: a late subscriber gets it), ``/tf`` (tf2_msgs/msg/TFMessage: every URDF joint's
  parent -> child transform, from the robot's own kinematics, at ``tf_rate_hz``), and with ``sim_time``
  ``/clock`` (rosgraph_msgs/msg/Clock, loop time, every cycle) with ``use_sim_time`` set on jointctl's nodes;
  ``~/loop_lateness`` (std_msgs/msg/Float64MultiArray, once a second: p50, p99, max [ms] of how late the loop's
  cycles end against their ideal wall-clock times, :mod:`jointctl.runtime.lateness`).

Stamps: loop time on simulated time, else the wall clock at loop time zero plus loop time. The loop runs paced
to the wall clock in the calling thread; rclpy's executor runs the callbacks on threads of its own until
SIGINT or SIGTERM stops both.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from geometry_msgs.msg import TransformStamped
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String
from tf2_msgs.msg import TFMessage

from jointctl.model.loader import description_text
from jointctl.recording.foxglove_messages import RobotFrames
from jointctl.ros2.controller_manager import ControllerManagerServices
from jointctl.ros2.controllers import faces
from jointctl.ros2.conversions import time_msg
from jointctl.runtime.clock import StampClock, WallClockPacer
from jointctl.runtime.lateness import watch_lateness
from jointctl.scenario.session import Session

SWITCH_INTERVAL_S = 2e-4  # GIL hand-over interval while serving [s] (the loop thread must get it back quickly)
EXECUTOR_THREADS = 4
#: /robot_description as robot_state_publisher offers it: reliable, transient local, depth 1.
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class LoopClock(StampClock):
    """Loop time [s] -> ROS 2 stamps (:class:`~jointctl.runtime.clock.StampClock`, as builtin_interfaces/Time)."""

    def stamp(self, loop_s: float):
        return time_msg(self.seconds(loop_s))


class Ros2Robot:
    """The session's robot on the ROS 2 graph: its nodes, made and spun here (see the module's docstring)."""

    def __init__(self, session: Session, *, sim_time: bool = False, state_rate_hz: float = 50.0,
                 tf_rate_hz: float = 50.0) -> None:
        self.session = session
        self.speed = 1.0
        self.clock = LoopClock(session.loop, sim_time)
        overrides = [Parameter("use_sim_time", value=True)] if sim_time else []
        self.nodes: list[Node] = []

        def node(name: str) -> Node:
            made = Node(name, parameter_overrides=overrides)
            self.nodes.append(made)
            return made

        robot_node = node(f"jointctl_{session.robot.name}")
        self.manager_services = ControllerManagerServices(node("controller_manager"), session)
        self.faces = faces(node, session, self.clock, state_rate_hz)
        description = robot_node.create_publisher(String, "/robot_description", LATCHED)
        description.publish(String(data=description_text(session.robot)))
        self._description = description
        if sim_time:
            clock = robot_node.create_publisher(Clock, "/clock", 10)
            session.loop.add_observer(lambda t: clock.publish(Clock(clock=time_msg(t))))
        self._frames = RobotFrames(session.robot, session.hardware.joint_names)
        self._tf = robot_node.create_publisher(TFMessage, "/tf", 100)
        robot_node.create_timer(1.0 / tf_rate_hz, self._publish_tf)
        lateness = robot_node.create_publisher(Float64MultiArray, "~/loop_lateness", 1)
        watch_lateness(session.loop, lambda *ms: lateness.publish(Float64MultiArray(data=list(ms))),
                       lambda: self.speed)
        manager = session.manager
        manager.add_failure_listener(
            lambda f: robot_node.get_logger().error(f"controller {f.controller} {f.error().message}"))

    def _publish_tf(self) -> None:
        hardware = self.session.hardware
        positions = list(hardware.position)  # one snapshot of the loop's last read
        translation, quaternion = self._frames.transforms([positions])
        stamp = self.clock.stamp(self.session.loop.time_s)
        message = TFMessage()
        for (parent, child), t, q in zip(self._frames.pairs, translation[0], quaternion[0]):
            transform = TransformStamped()
            transform.header.stamp = stamp
            transform.header.frame_id, transform.child_frame_id = parent, child
            v, r = transform.transform.translation, transform.transform.rotation
            v.x, v.y, v.z = (float(x) for x in t)
            r.x, r.y, r.z, r.w = (float(x) for x in q)
            message.transforms.append(transform)
        self._tf.publish(message)

    def start_callbacks(self) -> None:
        """Spin rclpy's executor on threads of its own: the callbacks run from now on (the loop runs elsewhere)."""
        self._executor = MultiThreadedExecutor(num_threads=EXECUTOR_THREADS)
        for made in self.nodes:
            self._executor.add_node(made)
        threading.Thread(target=_spin, args=(self._executor, self.nodes[0].get_logger()), daemon=True,
                         name="jointctl-ros2-executor").start()
        self.clock.start()

    def close(self) -> None:
        """Stop the callbacks and take the nodes off the graph."""
        executor, self._executor = getattr(self, "_executor", None), None
        if executor is not None:
            executor.shutdown(timeout_sec=2.0)
        nodes, self.nodes = self.nodes, []
        for made in nodes:
            made.destroy_node()

    def spin(self, speed: float = 1.0) -> None:
        """Run the loop paced to the wall clock and the callbacks beside it, until SIGINT/SIGTERM."""
        loop = self.session.loop
        self.speed = speed
        loop.clock = WallClockPacer(speed)
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: loop.request_stop())
        self.start_callbacks()
        try:
            loop.run()
        finally:
            self.close()


def _spin(executor, logger) -> None:
    """Spin until shutdown; a callback that raises is logged and the others go on being served."""
    while rclpy.ok():
        try:
            executor.spin_once(timeout_sec=0.1)
        except (ExternalShutdownException, rclpy.executors.ShutdownException):
            return
        except Exception as exc:  # noqa: BLE001 - one bad request must not take the robot off the graph
            logger.error(f"a callback failed: {type(exc).__name__}: {exc}")


def serve(session: Session, *, sim_time: bool = False, speed: float = 1.0) -> None:
    """Bring the session up on ROS 2 (the DDS domain of ``ROS_DOMAIN_ID``) and run until stopped."""
    with on_ros2(session, sim_time=sim_time) as robot:
        robot.spin(speed)


@contextlib.contextmanager
def on_ros2(session: Session, *, sim_time: bool = False, speed: float = 1.0):
    """rclpy up and the session's :class:`Ros2Robot` made (callbacks not started yet), then everything down."""
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    rclpy.init(args=None, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    robot = None
    try:
        robot = Ros2Robot(session, sim_time=sim_time)
        robot.speed = speed
        names = ", ".join(f"/{n.get_name()}" for n in robot.nodes)
        robot.nodes[0].get_logger().info(f"jointctl: {session.robot.name} up on ROS 2 as {names}")
        yield robot
    finally:
        if robot is not None:
            robot.close()
        rclpy.try_shutdown()


__all__ = ["LoopClock", "Ros2Robot", "on_ros2", "serve"]

"""Run a scenario's control loop as a ROS 1 node, with the chapter's topic and action names.

Under the robot's namespace (``one_DOF_robot``, ``arm7dof``):

- ``joint_states`` (sensor_msgs/JointState) at the joint state controller's ``publish_rate``;
- ``<controller>/command`` (std_msgs/Float64) for every started joint controller that no other
  controller commands; non-finite values are refused, logged and ignored;
- ``<controller>/state`` (control_msgs/JointControllerState) at ``state_rate_hz``;
- the command topics named in the robot's ``robot.yaml`` under ``ros.command_topics`` (topic ->
  controller; Part 2's minimal robot: the global ``/pos_cmd``), while nothing else commands it;
- ``<executor>/follow_joint_trajectory`` (control_msgs/FollowJointTrajectory) for every
  trajectory executor (joint_trajectory_controller semantics), plus the chapter's servers named
  in the robot's ``robot.yaml`` (``example_traj_action_server``, ``trajActionServer``) with the
  book's SimpleActionServer semantics (see :mod:`jointctl.ros.actions`);
- each force-torque sensor's topic from the URDF (``/ft_sensor_topic``) at its update rate;
- a dynamic_reconfigure server per PID at ``<controller>/pid``: gains change while running,
  validated (finite, non-negative), applied at the next cycle;
- ``loop_lateness`` once a second: the loop's jitter (p50, p99, max, ms);
- on an industrial controller (``serve --hardware industrial``), ROS-Industrial's names as well
  (see :mod:`jointctl.ros.industrial`).
- ``/robot_description`` (the URDF, xacro expanded) and the spawned objects' markers on
  ``/jointctl/object_markers``; with ``serve --rviz``, robot_state_publisher (remapped onto
  ``<ns>/joint_states``) and rviz (see :mod:`jointctl.ros.robot_description`).

The controller YAML is loaded onto the parameter server as roslaunch's ``rosparam load`` would.
The loop runs paced to the wall clock; with ``sim_time`` it publishes ``/clock`` (loop time) and
sets ``/use_sim_time``. If no master answers at ``ROS_MASTER_URI`` one is started.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
import urllib.parse
from collections.abc import Mapping

import rosgraph
import rospy
from control_msgs.msg import JointControllerState
from geometry_msgs.msg import WrenchStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray

from jointctl.control.joint_controllers import _EffortJointController
from jointctl.control.joint_state_controller import JointStateController
from jointctl.control.manager import read_yaml
from jointctl.errors import ConfigError, InvalidCommand, JointCtlError
from jointctl.ros.actions import TrajectoryActionServer, action_server
from jointctl.ros.conversions import joint_state_to_ros, wrench_to_ros
from jointctl.hardware.industrial import IndustrialHardware
from jointctl.ros.gains import attach_gain_servers
from jointctl.ros.industrial import IndustrialTopics
from jointctl.ros.robot_description import Viewers, attach_robot_description
from jointctl.ros.world_services import attach_world_services
from jointctl.runtime.clock import StampClock, WallClockPacer
from jointctl.runtime.lateness import watch_lateness
from jointctl.scenario.session import Session
from jointctl.trajectory.executor import TrajectoryExecutor

MASTER_TIMEOUT_S = 10.0
MASTER_CHECK_S = 1.0  # how often the node checks that its master is still the one it registered with [s]
SWITCH_INTERVAL_S = 2e-4  # GIL hand-over interval while serving [s]


class LoopClock(StampClock):
    """Maps loop time to ROS time (:class:`~jointctl.runtime.clock.StampClock`, as rospy.Time)."""

    def ros_time(self, loop_s: float) -> rospy.Time:
        return rospy.Time.from_sec(self.seconds(loop_s))


def ensure_master() -> subprocess.Popen | None:
    """Join the master at ROS_MASTER_URI, or start one there; returns the started process."""
    if rosgraph.Master("/jointctl").is_online():
        return None
    uri = urllib.parse.urlparse(rosgraph.get_master_uri())
    process = subprocess.Popen(["rosmaster", "--core", "-p", str(uri.port or 11311)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + MASTER_TIMEOUT_S
    while not rosgraph.Master("/jointctl").is_online():
        if process.poll() is not None or time.monotonic() > deadline:
            process.terminate()
            raise JointCtlError("could not start a ROS master", field="ROS_MASTER_URI",
                                value=rosgraph.get_master_uri())
        time.sleep(0.05)
    return process


class RosNode:
    """The session's robot on the ROS graph."""

    def __init__(self, session: Session, *, sim_time: bool = False,
                 actions: Mapping[str, Mapping[str, str]] | None = None,
                 command_topics: Mapping[str, str] | None = None,
                 state_rate_hz: float = 50.0) -> None:
        self.session = session
        manager = session.manager
        self.namespace = manager.namespace or session.robot.name
        self.clock = LoopClock(session.loop, sim_time)
        self.speed = 1.0
        ns = f"/{self.namespace}"
        if sim_time:
            rospy.set_param("/use_sim_time", True)
            clock_pub = rospy.Publisher("/clock", Clock, queue_size=10)
            session.loop.add_observer(lambda t: clock_pub.publish(Clock(clock=rospy.Time.from_sec(t))))
        tree = read_yaml(session.scenario.controller_file)
        rospy.set_param(ns, tree.get(self.namespace, tree) if isinstance(tree, dict) else {})
        for controller in manager.active:
            if isinstance(controller, JointStateController):
                pub = rospy.Publisher(f"{ns}/joint_states", JointState, queue_size=10)
                controller.subscribe(lambda sample, pub=pub: pub.publish(
                    joint_state_to_ros(sample, self.clock.ros_time(sample.time_s))))
            elif isinstance(controller, _EffortJointController) and manager.command_owner(controller.name) is None:
                rospy.Subscriber(f"{ns}/{controller.name}/command", Float64, self._command_callback(controller),
                                 queue_size=1)
        for topic, name in (command_topics or {}).items():
            # Extra command topics from robot.yaml (Part 2's global ``pos_cmd``): the same door, offered
            # while no other controller (a trajectory executor) commands that controller.
            controller = manager.controller(name)
            if not isinstance(controller, _EffortJointController):
                raise ConfigError("a command topic needs a joint position or velocity controller",
                                  source=session.robot.source, field=f"ros.command_topics.{topic}", value=name)
            if manager.command_owner(name) is None:
                rospy.Subscriber(topic, Float64, self._command_callback(controller), queue_size=1)
        self._state_publishers(ns, state_rate_hz)
        self._sensor_publishers()
        self.servers = [TrajectoryActionServer(f"{ns}/{c.name}/follow_joint_trajectory",
                                               "follow_joint_trajectory", c, self.clock)
                        for c in manager.active if isinstance(c, TrajectoryExecutor)]
        for name, spec in (actions or {}).items():
            executor = manager.controller(spec["controller"])
            self.servers.append(action_server(name, spec["type"], executor, self.clock))
        #: dynamic_reconfigure servers at <ns>/<controller>/pid: PID gains changed while running.
        self.gain_servers = attach_gain_servers(self)
        self._lateness_publisher(ns)
        manager.add_failure_listener(
            lambda f: rospy.logerr("jointctl: controller %s %s", f.controller, f.error().message))
        #: Gazebo's /gazebo world services (spawn, delete, physics properties) and model_states.
        self.world_services = attach_world_services(self)
        #: ROS-Industrial's names, when the hardware is an industrial controller (serve --hardware industrial).
        self.industrial = None
        executors = [c for c in manager.active if isinstance(c, TrajectoryExecutor)]
        if isinstance(session.hardware, IndustrialHardware) and executors:
            self.industrial = IndustrialTopics(session.hardware, executors[0], self.clock)
        #: /robot_description (the expanded URDF) and the spawned objects' markers, for robot_state_publisher
        #: and rviz (see jointctl.ros.robot_description).
        self.description = attach_robot_description(self)

    def _command_callback(self, controller):
        def on_command(msg: Float64) -> None:
            try:
                controller.set_reference(msg.data)
            except InvalidCommand as exc:
                rospy.logwarn("jointctl: refused %s", exc)
        return on_command

    def _state_publishers(self, ns: str, rate_hz: float) -> None:
        manager, loop = self.session.manager, self.session.loop
        joint_controllers = [c for c in manager.active if isinstance(c, _EffortJointController)]
        if not joint_controllers:
            return
        pubs = [(c, rospy.Publisher(f"{ns}/{c.name}/state", JointControllerState, queue_size=10))
                for c in joint_controllers]
        every = max(1, round(1.0 / (rate_hz * loop.period_s)))
        hw = self.session.hardware
        count = [0]

        def publish(t: float) -> None:
            count[0] += 1
            if count[0] % every:
                return
            stamp = self.clock.ros_time(t)
            for c, pub in pubs:
                g = c.pid.gains
                i = c.index
                value = (hw.position if c.controlled == "position" else hw.velocity)[i]
                msg = JointControllerState(
                    set_point=c.reference, process_value=value, process_value_dot=hw.velocity[i],
                    error=c.reference - value,
                    time_step=loop.period_s, command=c.effort_command[i], p=g.p, i=g.i, d=g.d,
                    i_clamp=g.i_clamp_max, antiwindup=g.antiwindup)
                msg.header.stamp = stamp
                pub.publish(msg)

        loop.add_observer(publish)

    def _lateness_publisher(self, ns: str) -> None:
        """``<ns>/loop_lateness`` (std_msgs/Float64MultiArray, once a second): p50, p99 and max, in ms,
        of how late each cycle's end comes against its ideal wall-clock time: the loop's jitter."""
        pub = rospy.Publisher(f"{ns}/loop_lateness", Float64MultiArray, queue_size=1)
        watch_lateness(self.session.loop, lambda *ms: pub.publish(Float64MultiArray(data=list(ms))),
                       lambda: self.speed)

    def _sensor_publishers(self) -> None:
        session = self.session
        for spec in session.robot.sensors:
            if spec.name not in session.hardware.wrenches:
                continue  # the model describes it, this hardware does not report it (an industrial controller)
            topic = spec.topic or f"{spec.name}_topic"
            pub = rospy.Publisher(topic, WrenchStamped, queue_size=10)
            every = max(1, round(1.0 / ((spec.update_rate_hz or 1000.0) * session.loop.period_s)))
            wrench = session.hardware.wrenches[spec.name]
            count = [0]

            def publish(t: float, pub=pub, wrench=wrench, frame=spec.link, count=count, every=every) -> None:
                count[0] += 1
                if count[0] % every == 0:
                    pub.publish(wrench_to_ros(wrench, frame, self.clock.ros_time(t)))

            session.loop.add_observer(publish)

    def spin(self, speed: float = 1.0) -> None:
        """Run the loop paced to the wall clock until ROS shuts down or SIGINT/SIGTERM."""
        loop = self.session.loop
        self.speed = speed
        loop.clock = WallClockPacer(speed)
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: loop.request_stop())
        rospy.on_shutdown(loop.request_stop)
        self.clock.start()
        loop.run()


def _watch_master(loop, lost: list) -> None:
    """Stop the loop when the master stops answering or is replaced: rospy never re-registers,
    so the node would silently be off the graph."""
    master = rosgraph.Master(rospy.get_name())
    try:
        pid = master.getPid()
    except Exception:  # noqa: BLE001  (any failure to reach the master counts as a miss)
        pid = None
    misses = 0
    while not rospy.is_shutdown():
        time.sleep(MASTER_CHECK_S)
        try:
            now = master.getPid()
        except Exception:  # noqa: BLE001
            misses += 1
            if misses >= 2:
                lost.append("stopped answering")
                loop.request_stop()
                return
            continue
        misses = 0
        if pid is not None and now != pid:
            lost.append("was restarted")
            loop.request_stop()
            return


def serve(session: Session, *, sim_time: bool = False, speed: float = 1.0,
          actions: Mapping[str, Mapping[str, str]] | None = None,
          command_topics: Mapping[str, str] | None = None, node_name: str | None = None,
          rviz: bool = False) -> None:
    """Start (or join) a master, bring the session up as a node and run until stopped. With ``rviz``,
    robot_state_publisher and rviz run beside it while it serves (what cannot start is said in one
    line on stderr; the node serves on)."""
    master = ensure_master()
    viewers = Viewers()
    # The loop thread must get the GIL back quickly after each sleep, while rospy's threads work:
    # Python's default 5 ms switch interval would make cycles that late.
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    try:
        name = node_name or f"jointctl_{session.robot.name}"
        rospy.init_node(name, anonymous=False, disable_signals=True)
        node = RosNode(session, sim_time=sim_time, actions=actions, command_topics=command_topics)
        rospy.loginfo("jointctl: %s up under /%s", session.robot.name, node.namespace)
        if rviz:
            print(viewers.start(node.description), file=sys.stderr, flush=True)
        lost: list[str] = []
        threading.Thread(target=_watch_master, args=(session.loop, lost), daemon=True,
                         name="jointctl-master-watchdog").start()
        node.spin(speed)
        if lost:
            raise JointCtlError(f"the ROS master {lost[0]}; the node is no longer on the graph (rospy does "
                                "not re-register): restart jointctl serve", field="ROS_MASTER_URI",
                                value=rosgraph.get_master_uri())
    finally:
        viewers.stop()
        rospy.signal_shutdown("jointctl stopped")
        if master is not None:
            master.terminate()
            master.wait(5)


def check_actions(actions: object, source: str) -> dict:
    """The ``ros.actions`` mapping of a robot.yaml: name -> {type, controller}."""
    if actions is None:
        return {}
    if not isinstance(actions, dict):
        raise ConfigError("must map action names to {type, controller}", source=source, field="ros.actions",
                          value=actions)
    for name, spec in actions.items():
        if not isinstance(spec, dict) or spec.get("type") not in ("traj", "arm7dof_traj",
                                                                   "follow_joint_trajectory"):
            raise ConfigError("needs type traj, arm7dof_traj or follow_joint_trajectory, and a controller",
                              source=source, field=f"ros.actions.{name}", value=spec)
    return actions


def check_command_topics(topics: object, source: str) -> dict:
    """The ``ros.command_topics`` mapping of a robot.yaml: topic name -> joint controller name."""
    if topics is None:
        return {}
    if not isinstance(topics, dict):
        raise ConfigError("must map topic names to controller names", source=source,
                          field="ros.command_topics", value=topics)
    for topic, controller in topics.items():
        if not isinstance(topic, str) or not topic or not isinstance(controller, str) or not controller:
            raise ConfigError("needs a topic name and the name of the joint controller it commands",
                              source=source, field=f"ros.command_topics.{topic}", value=controller)
    return topics


__all__ = ["RosNode", "check_actions", "check_command_topics", "ensure_master", "serve"]

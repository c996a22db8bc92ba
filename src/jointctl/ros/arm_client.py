"""The chapter's arm clients over ROS 1: a :class:`~jointctl.clients.arm.GoalSender` that sends
to the ``arm7dof_traj_as/trajAction`` server (``jointctl prompt arm7dof --ros``, ``jointctl play --ros``)."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence

import actionlib
import rospy
from actionlib_msgs.msg import GoalStatus as RosStatus
from arm7dof_traj_as.msg import trajAction, trajGoal
from sensor_msgs.msg import JointState

from jointctl.clients.arm import EXECUTOR, GOAL_MARGIN_S, TIMINGS, GoalOutcome
from jointctl.control.manager import read_yaml
from jointctl.control.params import Params
from jointctl.errors import JointCtlError
from jointctl.model.loader import load_robot_model
from jointctl.ros.clients import init_client_node
from jointctl.ros.conversions import trajectory_to_ros
from jointctl.scenario.spec import builtin_robots, read_robot_manifest
from jointctl.trajectory.executor import TrajectoryExecutor
from jointctl.trajectory.messages import JointTrajectory
from jointctl.trajectory.timing import time_path
from jointctl.trajectory.validation import joint_specs_from_model

#: The arm's namespace, its trajectory executor's parameters and the chapter's action server.
ROS_NAMESPACE = "arm7dof"
ROS_SERVER = "trajActionServer"
#: How long a ROS sender waits for the first joint state and for the action server (s).
ROS_WAIT_S = 20.0


class RosGoalSender:
    """A :class:`GoalSender` over ROS 1 (``jointctl prompt arm7dof --ros``, ``jointctl play --ros``).

    Joins the graph as its own node (one per process): the current angles are the latest
    ``/<namespace>/joint_states``; the joint names and timing parameters are the trajectory
    executor's (from the parameter server as ``jointctl serve`` loads them, else the robot's
    controller file); the joint limits are the robot model's (loaded with :mod:`jointctl.model`,
    as the in-process sender does). Paths are timed with :mod:`jointctl.trajectory.timing`
    and sent to the ``arm7dof_traj_as/trajAction`` server with actionlib; :meth:`send` blocks
    until the result (canceling a goal still running ``GOAL_MARGIN_S`` after its end plus
    the executor's ``goal_time_s``).
    """

    def __init__(self, *, robot: str = "arm7dof", namespace: str = ROS_NAMESPACE, server: str = ROS_SERVER,
                 controller: str = EXECUTOR, wait_s: float = ROS_WAIT_S) -> None:
        robots = builtin_robots()
        if robot not in robots:
            raise JointCtlError(f"no built-in robot of that name (have: {', '.join(robots)})",
                                field="robot", value=robot)
        files = read_robot_manifest(robots[robot] / "robot.yaml")
        init_client_node(f"{robot}_trajectory_client")
        self._rospy = rospy
        params = rospy.get_param(f"/{namespace}/{controller}", None)
        if not isinstance(params, dict):  # not served by jointctl: the robot's own controller file
            tree = read_yaml(files.controller_files["trajectory"]) or {}
            params = (tree.get(namespace, tree) or {}).get(controller) or {}
        if not params.get("joints"):
            raise JointCtlError("no joints for the trajectory controller", field=f"{namespace}/{controller}",
                                value=params)
        # The executor's own reading of its parameters: the same defaults and checks as in the loop.
        config = TrajectoryExecutor(controller, Params(params, source=f"/{namespace}/{controller}", field=""))
        self.joint_names = config.joint_names
        self.model = load_robot_model(files.description)
        self.joint_specs = joint_specs_from_model(self.model, self.joint_names)
        self.path_velocity_fraction = config.path_velocity_fraction
        self.max_acceleration = config.max_acceleration
        self.max_jerk = config.max_jerk
        self.goal_time_s = config.goal_time_s
        self._latest: dict[str, float] = {}
        self._have_state = threading.Event()
        self._lock = threading.Lock()
        self._subscriber = rospy.Subscriber(f"/{namespace}/joint_states", JointState, self._on_state, queue_size=1)
        if not self._have_state.wait(wait_s):
            raise JointCtlError(f"no joint states within {wait_s:g} s (is 'jointctl serve {robot} "
                                "--controllers trajectory' running?)", field="topic",
                                value=f"/{namespace}/joint_states")
        self._client = actionlib.SimpleActionClient(server, trajAction)
        if not self._client.wait_for_server(rospy.Duration(wait_s)):
            raise JointCtlError(f"no action server within {wait_s:g} s", field="action",
                                value=rospy.resolve_name(server))
        self.server = rospy.resolve_name(server)

    def _on_state(self, msg) -> None:
        with self._lock:
            self._latest.update(zip(msg.name, msg.position))
            if all(j in self._latest for j in self.joint_names):
                self._have_state.set()

    def current_positions(self) -> tuple[float, ...]:
        with self._lock:
            return tuple(float(self._latest[j]) for j in self.joint_names)

    def plan(self, path: Sequence[Sequence[float]], *, timing: str = "chapter",
             joint_names: Sequence[str] | None = None) -> JointTrajectory:
        if timing not in TIMINGS:
            raise JointCtlError(f"must be one of {', '.join(TIMINGS)}", field="timing", value=timing)
        return time_path(self.joint_names, self.current_positions(), path,
                         [spec.max_velocity for spec in self.joint_specs], timing=timing, path_joints=joint_names,
                         velocity_fraction=self.path_velocity_fraction, max_acceleration=self.max_acceleration,
                         max_jerk=self.max_jerk)

    def send(self, trajectory: JointTrajectory) -> GoalOutcome:
        rospy = self._rospy
        statuses = {RosStatus.SUCCEEDED: "succeeded", RosStatus.ABORTED: "aborted",
                    RosStatus.PREEMPTED: "preempted", RosStatus.RECALLED: "preempted",
                    RosStatus.REJECTED: "rejected", RosStatus.LOST: "lost"}
        client = self._client
        start = time.monotonic()
        client.send_goal(trajGoal(trajectory=trajectory_to_ros(trajectory)))
        end_s = trajectory.points[-1].time_from_start_s if trajectory.points else 0.0
        if not client.wait_for_result(rospy.Duration(end_s + self.goal_time_s + GOAL_MARGIN_S + 5.0)):
            client.cancel_goal()
            client.wait_for_result(rospy.Duration(60.0))
        state = client.get_state()
        text = client.get_goal_status_text()
        duration = time.monotonic() - start
        if state == RosStatus.REJECTED:  # refused before anything moved, as the executor refuses in-process
            raise JointCtlError(f"the action server rejected the goal: {text or 'no reason given'}",
                                source=self.server)
        time.sleep(0.05)  # one more joint state after the end
        status = statuses.get(state, "unfinished")
        error = "" if status == "succeeded" else (text or f"goal ended {status}")
        return GoalOutcome(status, error, duration, self.current_positions())

    trace_path = None

    def close(self) -> None:
        self._subscriber.unregister()
        self._rospy.signal_shutdown("arm client done")

    def __enter__(self) -> RosGoalSender:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


__all__ = ["ROS_NAMESPACE", "ROS_SERVER", "RosGoalSender"]

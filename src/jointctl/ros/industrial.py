"""ROS-Industrial's topic contract, for ``jointctl serve ROBOT --hardware industrial``.

Applications written for ROS-Industrial's ``industrial_robot_client`` (a MoveIt configuration, a
script that publishes ``joint_path_command``) work unchanged against jointctl's node, because it
offers the same names, in the root namespace as ROS-I's launch files put them:

- ``joint_trajectory_action`` (control_msgs/FollowJointTrajectory) on the robot's trajectory
  executor (joint_trajectory_controller semantics: a new goal replaces the running one, spliced; ROS-I
  stops and starts again instead);
- ``joint_path_command``: the topic (trajectory_msgs/JointTrajectory: a trajectory to execute, an
  empty one stops) and the service (industrial_msgs/CmdJointTrajectory, the same, answering
  SUCCESS or FAILURE); ``stop_motion`` (industrial_msgs/StopMotion);
- ``joint_states`` (sensor_msgs/JointState, positions as the controller reports them) and
  ``feedback_states`` (control_msgs/FollowJointTrajectoryFeedback, ``actual.positions``) for each
  JOINT_POSITION the controller sends, and ``robot_status`` (industrial_msgs/RobotStatus) for each
  STATUS, as ROS-I's ``robot_state`` relays them: published as each is read, on the hardware's state
  reader thread, so reports read together (the reader or the loop descheduled a while) are each
  relayed, in order, not only the last; stamped with the ROS time when read;
- parameters ``robot_ip_address`` and ``controller_joint_names``.

A stop (an empty ``joint_path_command``, ``stop_motion``, or a canceled ``joint_trajectory_action``
goal) cancels the executor's goal and sends the controller STOP (-4): the controller decelerates at
its own limits and clears its queue; until it reports the robot at rest the hardware's ``fault``
says "stopping" and the executor's reference follows the measured position, so what is streamed
after the stop starts a new trajectory at the controller from where the robot came to rest.
"""

from __future__ import annotations

import rospy
from control_msgs.msg import FollowJointTrajectoryFeedback
from industrial_msgs.msg import RobotMode, RobotStatus, ServiceReturnCode, TriState
from industrial_msgs.srv import CmdJointTrajectory, CmdJointTrajectoryResponse, StopMotion, StopMotionResponse
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory as RosJointTrajectory

from jointctl.hardware.industrial import IndustrialHardware
from jointctl.ros.actions import TrajectoryActionServer
from jointctl.ros.conversions import trajectory_from_ros
from jointctl.trajectory.errors import InvalidTrajectory
from jointctl.trajectory.executor import TrajectoryExecutor

#: Messages each state topic's publisher holds for a subscriber's connection.
STATE_QUEUE = 100


class IndustrialTopics:
    """ROS-I's names for ``executor`` driving ``hardware`` (see the module docstring)."""

    def __init__(self, hardware: IndustrialHardware, executor: TrajectoryExecutor, clock) -> None:
        self.hardware, self.executor, self.clock = hardware, executor, clock
        rospy.set_param("/robot_ip_address", hardware.robot_ip)
        rospy.set_param("/controller_joint_names", list(hardware.joint_names))
        self.action = TrajectoryActionServer("/joint_trajectory_action", "follow_joint_trajectory", executor, clock)
        # Reports read together are published together: the queues hold a burst of them (a reader
        # descheduled 1 s at the controller's 100 Hz) for a subscriber's connection to take.
        self._joint_states = rospy.Publisher("/joint_states", JointState, queue_size=STATE_QUEUE)
        self._feedback = rospy.Publisher("/feedback_states", FollowJointTrajectoryFeedback, queue_size=STATE_QUEUE)
        self._status_topic = rospy.Publisher("/robot_status", RobotStatus, queue_size=STATE_QUEUE)
        rospy.Subscriber("/joint_path_command", RosJointTrajectory, self._on_path, queue_size=1)
        rospy.Service("/joint_path_command", CmdJointTrajectory, self._on_path_service)
        rospy.Service("/stop_motion", StopMotion, self._on_stop_service)
        self._goal = None
        self._names = list(hardware.joint_names)
        hardware.add_state_listener(self._relay_positions, self._relay_status)

    # -- commands (rospy's threads) ---------------------------------------------------------------
    def _execute(self, msg: RosJointTrajectory) -> bool:
        """Execute ``msg`` (an empty one stops); False when the executor refuses it (logged)."""
        if not msg.points:
            self.stop()
            return True
        trajectory = trajectory_from_ros(msg, self.clock.ros_time_at_loop_zero())
        try:
            self._goal = self.executor.submit(trajectory, now_s=self.clock.loop_now())
        except InvalidTrajectory as exc:
            rospy.logwarn("jointctl: joint_path_command refused: %s", exc)
            return False
        return True

    def stop(self) -> None:
        """Cancel the running goal and stop the controller (STOP, -4)."""
        goal = self.executor.active_goal
        if goal is not None:
            goal.cancel()
        self.hardware.stop_motion()

    def _on_path(self, msg: RosJointTrajectory) -> None:
        self._execute(msg)

    def _on_path_service(self, request) -> CmdJointTrajectoryResponse:
        ok = self._execute(request.trajectory)
        return CmdJointTrajectoryResponse(code=ServiceReturnCode(
            val=ServiceReturnCode.SUCCESS if ok else ServiceReturnCode.FAILURE))

    def _on_stop_service(self, request) -> StopMotionResponse:
        self.stop()
        return StopMotionResponse(code=ServiceReturnCode(val=ServiceReturnCode.SUCCESS))

    # -- state (the hardware's state reader thread: publishing only queues) ----------------------
    def _relay_positions(self, positions: tuple[float, ...]) -> None:
        stamp = rospy.Time.now()
        joint_state = JointState(name=self._names, position=list(positions))
        joint_state.header.stamp = stamp
        feedback = FollowJointTrajectoryFeedback(joint_names=self._names)
        feedback.header.stamp = stamp
        feedback.actual.positions = list(positions)
        try:
            self._joint_states.publish(joint_state)
            self._feedback.publish(feedback)
        except rospy.ROSException:  # the node is shutting down
            pass

    def _relay_status(self, status) -> None:
        message = RobotStatus(
            mode=RobotMode(val=status.mode), e_stopped=TriState(val=status.e_stopped),
            drives_powered=TriState(val=status.drives_powered),
            motion_possible=TriState(val=status.motion_possible), in_motion=TriState(val=status.in_motion),
            in_error=TriState(val=status.in_error), error_code=status.error_code)
        message.header.stamp = rospy.Time.now()
        try:
            self._status_topic.publish(message)
        except rospy.ROSException:  # the node is shutting down
            pass


__all__ = ["IndustrialTopics"]

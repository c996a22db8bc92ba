"""Trajectory action servers on a :class:`~jointctl.trajectory.executor.TrajectoryExecutor`.

Three action types: ``control_msgs/FollowJointTrajectory`` (result error_code + error_string),
the chapter's ``example_trajectory/TrajAction`` (result ``rtn_status``: the error code, 0 on
success) and the arm streamer's ``arm7dof_traj_as/trajAction`` (result ``return_val``: goals
served so far). Two goal semantics, side by side (docs/ros.md):

- :class:`TrajectoryActionServer`, for ``follow_joint_trajectory``: ROS's
  joint_trajectory_controller. A goal is validated on arrival against the current desired state
  and REJECTED with the validation text if it is bad (nothing moves); a new goal replaces the
  running one with a splice (the old one ends PREEMPTED); ``header.stamp`` is honoured (a zero
  stamp means "now"); the goal's own position tolerances and goal time are honoured where it gives
  them (control_msgs: 0 keeps the controller's, -1 takes the check away).
- :class:`QueuedTrajectoryActionServer`, for the chapter's servers (``traj``, ``arm7dof_traj``):
  actionlib's SimpleActionServer with an execute callback, as the book's
  ``example_trajectory_action_server`` and ``arm7dof_traj_as`` are. Goals run one after another in
  order of arrival: a goal that arrives while one executes waits (PENDING); a still newer one
  replaces the waiting one, which SimpleActionServer cancels (a pending goal canceled ends
  RECALLED). ``header.stamp`` is ignored: time starts when the goal starts, and a first point at
  time 0 is checked against where the goal starts (the previous goal's end). A goal that can
  never run (bad joints, values, times or limits) is REJECTED on arrival; one whose start does
  not match where the robot is when its turn comes is ABORTED, and nothing moves. Unlike the
  book's servers, a client's cancel of the running goal is honoured: the joints decelerate to
  rest and the goal ends PREEMPTED.

Each goal ends exactly once: succeeded, aborted, canceled (preempted or recalled) or rejected.
"""

from __future__ import annotations

import dataclasses
import threading

import actionlib
import rospy
from actionlib_msgs.msg import GoalStatus as RosGoalStatus
from trajectory_msgs.msg import JointTrajectoryPoint as RosPoint

from jointctl.ros.conversions import tolerances_from_ros, trajectory_from_ros
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.executor import GoalResult, GoalStatus, TrajectoryExecutor, TrajectoryFeedback

KINDS = ("follow_joint_trajectory", "traj", "arm7dof_traj")
#: The kinds the book serves with a SimpleActionServer (queued goals, stamps ignored).
QUEUED_KINDS = ("traj", "arm7dof_traj")
WAIT_POLL_S = 0.02  # how often a queued goal's execute thread looks for a cancel [s]


def _action_types(kind: str):
    if kind == "follow_joint_trajectory":
        from control_msgs.msg import (FollowJointTrajectoryAction, FollowJointTrajectoryFeedback,
                                      FollowJointTrajectoryResult)
        return FollowJointTrajectoryAction, FollowJointTrajectoryResult, FollowJointTrajectoryFeedback
    if kind == "traj":
        from example_trajectory.msg import TrajAction, TrajFeedback, TrajResult
        return TrajAction, TrajResult, TrajFeedback
    from arm7dof_traj_as.msg import trajAction, trajFeedback, trajResult
    return trajAction, trajResult, trajFeedback


class _Messages:
    """Result and feedback messages of one action kind."""

    def __init__(self, kind: str, executor: TrajectoryExecutor, clock) -> None:
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
        self.kind, self.executor, self.clock = kind, executor, clock
        self.action, self._result_type, self._feedback_type = _action_types(kind)

    def feedback(self, feedback: TrajectoryFeedback):
        msg = self._feedback_type()
        if self.kind == "follow_joint_trajectory":
            msg.header.stamp = self.clock.ros_time(feedback.time_s)
            msg.joint_names = list(feedback.joint_names)
            msg.desired = RosPoint(positions=list(feedback.desired_positions),
                                   velocities=list(feedback.desired_velocities))
            msg.actual = RosPoint(positions=list(feedback.actual_positions),
                                  velocities=list(feedback.actual_velocities))
            msg.error = RosPoint(positions=list(feedback.errors))
        else:
            msg.fdbk = int(round(feedback.time_s * 1000))  # loop time in ms: progress made visible
        return msg

    def result(self, code: TrajectoryErrorCode, text: str):
        msg = self._result_type()
        if self.kind == "follow_joint_trajectory":
            msg.error_code, msg.error_string = int(code), text
        elif self.kind == "traj":
            msg.rtn_status = int(code)
        else:
            msg.return_val = self.executor.goals_served
        return msg


class TrajectoryActionServer:
    """Serves ``kind`` goals under ``name`` on ``executor`` with joint_trajectory_controller
    semantics (replace and splice, stamps honoured).

    ``clock`` maps ROS time onto loop time (``ros_time_at_loop_zero``, ``loop_now``) and back
    (``ros_time``).
    """

    def __init__(self, name: str, kind: str, executor: TrajectoryExecutor, clock) -> None:
        self.messages = _Messages(kind, executor, clock)
        self.name, self.kind, self.executor, self.clock = name, kind, executor, clock
        self._lock = threading.Lock()
        self.server = actionlib.ActionServer(name, self.messages.action, goal_cb=self._on_goal,
                                             cancel_cb=self._on_cancel, auto_start=False)
        self._handles: dict[str, object] = {}
        self.server.start()

    # -- actionlib callbacks (actionlib's threads) --------------------------------------------
    def _on_goal(self, gh) -> None:
        goal = gh.get_goal()
        accepted = threading.Event()
        trajectory = trajectory_from_ros(goal.trajectory, self.clock.ros_time_at_loop_zero())
        tolerances = tolerances_from_ros(goal) if self.kind == "follow_joint_trajectory" else None
        try:
            handle = self.executor.submit(
                trajectory, now_s=self.clock.loop_now(),
                on_feedback=lambda fb: gh.publish_feedback(self.messages.feedback(fb)),
                on_done=lambda result: self._on_done(gh, result, accepted), tolerances=tolerances)
        except InvalidTrajectory as exc:
            gh.set_rejected(self.messages.result(exc.error_code, str(exc)), str(exc))
            return
        with self._lock:
            self._handles[gh.get_goal_id().id] = handle
        gh.set_accepted()
        accepted.set()

    def _on_cancel(self, gh) -> None:
        with self._lock:
            handle = self._handles.get(gh.get_goal_id().id)
        if handle is not None:
            handle.cancel()

    # -- executor callback (the loop thread: must only queue) ---------------------------------
    def _on_done(self, gh, result: GoalResult, accepted: threading.Event) -> None:
        if result.status is GoalStatus.REJECTED:
            return  # refused in submit: _on_goal rejects it (an abort before the rejection would be an error)
        accepted.wait(1.0)  # a goal can end before actionlib's thread has marked it accepted
        with self._lock:
            self._handles.pop(gh.get_goal_id().id, None)
        msg = self.messages.result(result.error_code, result.error_string)
        if result.status is GoalStatus.SUCCEEDED:
            gh.set_succeeded(msg, result.error_string)
        elif result.status is GoalStatus.PREEMPTED:
            gh.set_canceled(msg, result.error_string)
        else:
            gh.set_aborted(msg, result.error_string)


class _RejectingSimpleActionServer(actionlib.SimpleActionServer):
    """actionlib's SimpleActionServer, refusing on arrival a goal that can never run."""

    def __init__(self, name, action, execute_cb, check) -> None:
        self._check = check
        super().__init__(name, action, execute_cb=execute_cb, auto_start=False)

    def internal_goal_callback(self, goal) -> None:
        refusal = self._check(goal.get_goal())
        if refusal is not None:
            result, text = refusal
            goal.set_rejected(result, text)
            return
        super().internal_goal_callback(goal)


class QueuedTrajectoryActionServer:
    """Serves ``kind`` goals under ``name`` on ``executor`` as the book's SimpleActionServers do:
    queued in order of arrival, stamps ignored (see the module's docstring)."""

    def __init__(self, name: str, kind: str, executor: TrajectoryExecutor, clock) -> None:
        self.messages = _Messages(kind, executor, clock)
        self.name, self.kind, self.executor, self.clock = name, kind, executor, clock
        self.server = _RejectingSimpleActionServer(name, self.messages.action, self._execute, self._refusal)
        self.server.start()

    @staticmethod
    def _trajectory(goal):
        """The goal's trajectory with its stamp dropped: time starts when the goal starts."""
        return dataclasses.replace(trajectory_from_ros(goal.trajectory), stamp_s=0.0)

    def _refusal(self, goal):
        """(result, text) for a goal that can never run; None for one that may."""
        try:
            self.executor.check_goal_shape(self._trajectory(goal))
        except InvalidTrajectory as exc:
            return self.messages.result(exc.error_code, str(exc)), str(exc)
        return None

    def _execute(self, goal) -> None:
        """SimpleActionServer's execute callback (its own thread): run the goal to its end."""
        server = self.server
        try:
            handle = self.executor.submit(
                self._trajectory(goal), now_s=self.clock.loop_now(),
                on_feedback=lambda fb: server.publish_feedback(self.messages.feedback(fb)))
        except InvalidTrajectory as exc:
            server.set_aborted(self.messages.result(exc.error_code, str(exc)), str(exc))
            return
        while handle.wait(WAIT_POLL_S) is None:
            # A newer goal also raises SimpleActionServer's preempt flag: that one waits its turn.
            # Only a cancel of this goal (status PREEMPTING) stops it.
            canceled = server.current_goal.get_goal_status().status == RosGoalStatus.PREEMPTING
            if (canceled or rospy.is_shutdown()) and not handle.cancel_requested:
                handle.cancel()
        result = handle.result
        msg = self.messages.result(result.error_code, result.error_string)
        if result.status is GoalStatus.SUCCEEDED:
            server.set_succeeded(msg, result.error_string)
        elif result.status is GoalStatus.PREEMPTED:
            server.set_preempted(msg, result.error_string)
        else:
            server.set_aborted(msg, result.error_string)


def action_server(name: str, kind: str, executor: TrajectoryExecutor, clock):
    """The server the kind calls for: queued for the book's action types, replacing otherwise."""
    server = QueuedTrajectoryActionServer if kind in QUEUED_KINDS else TrajectoryActionServer
    return server(name, kind, executor, clock)

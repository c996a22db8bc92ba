"""Trajectory action servers on a :class:`~jointctl.trajectory.executor.TrajectoryExecutor`.

One class serves the three action types the chapter and ROS users expect:
``control_msgs/FollowJointTrajectory`` (result error_code + error_string), the chapter's
``example_trajectory/TrajAction`` (result ``rtn_status``: the error code, 0 on success) and the
arm streamer's ``arm7dof_traj_as/trajAction`` (result ``return_val``: goals served so far).
Goals are validated before they are accepted: a refused goal is REJECTED with the validation
text and nothing moves. Each goal ends exactly once: succeeded, aborted or canceled (preempted).
"""

from __future__ import annotations

import threading

import actionlib
from trajectory_msgs.msg import JointTrajectoryPoint as RosPoint

from jointctl.ros.conversions import trajectory_from_ros
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.executor import GoalResult, GoalStatus, TrajectoryExecutor, TrajectoryFeedback

KINDS = ("follow_joint_trajectory", "traj", "arm7dof_traj")


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


class TrajectoryActionServer:
    """Serves ``kind`` goals under ``name`` on ``executor``.

    ``loop_time`` maps a ROS time in seconds to loop time (for stamped goals) and back.
    """

    def __init__(self, name: str, kind: str, executor: TrajectoryExecutor, clock) -> None:
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
        self.name, self.kind, self.executor, self.clock = name, kind, executor, clock
        action, self._result_type, self._feedback_type = _action_types(kind)
        self._lock = threading.Lock()
        self.server = actionlib.ActionServer(name, action, goal_cb=self._on_goal, cancel_cb=self._on_cancel,
                                             auto_start=False)
        self._handles: dict[str, object] = {}
        self.server.start()

    # -- actionlib callbacks (actionlib's threads) --------------------------------------------
    def _on_goal(self, gh) -> None:
        goal = gh.get_goal()
        accepted = threading.Event()
        trajectory = trajectory_from_ros(goal.trajectory, self.clock.ros_time_at_loop_zero())
        try:
            handle = self.executor.submit(
                trajectory, now_s=self.clock.loop_now(),
                on_feedback=lambda fb: self._on_feedback(gh, fb),
                on_done=lambda result: self._on_done(gh, result, accepted))
        except InvalidTrajectory as exc:
            gh.set_rejected(self._result(exc.error_code, str(exc)), str(exc))
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

    # -- executor callbacks (the loop thread: must only queue) --------------------------------
    def _on_feedback(self, gh, feedback: TrajectoryFeedback) -> None:
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
        gh.publish_feedback(msg)

    def _on_done(self, gh, result: GoalResult, accepted: threading.Event) -> None:
        accepted.wait(1.0)  # a goal can end before actionlib's thread has marked it accepted
        with self._lock:
            self._handles.pop(gh.get_goal_id().id, None)
        msg = self._result(result.error_code, result.error_string)
        if result.status is GoalStatus.SUCCEEDED:
            gh.set_succeeded(msg, result.error_string)
        elif result.status is GoalStatus.PREEMPTED:
            gh.set_canceled(msg, result.error_string)
        else:
            gh.set_aborted(msg, result.error_string)

    def _result(self, code: TrajectoryErrorCode, text: str):
        msg = self._result_type()
        if self.kind == "follow_joint_trajectory":
            msg.error_code, msg.error_string = int(code), text
        elif self.kind == "traj":
            msg.rtn_status = int(code)
        else:
            msg.return_val = self.executor.goals_served
        return msg

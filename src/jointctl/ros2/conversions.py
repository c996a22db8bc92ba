"""jointctl values <-> ROS 2 messages, field by field (times in seconds <-> builtin_interfaces)."""

from __future__ import annotations

import math

from builtin_interfaces.msg import Duration, Time
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory as Ros2JointTrajectory

from jointctl.control.joint_state_controller import JointStateSample
from jointctl.trajectory.goals import GoalTolerances
from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint


def time_msg(seconds: float) -> Time:
    """builtin_interfaces/Time of ``seconds`` (>= 0) since the clock's epoch."""
    sec = math.floor(seconds)
    return Time(sec=int(sec), nanosec=min(int(round((seconds - sec) * 1e9)), 999_999_999))


def seconds_of(stamp: Time | Duration) -> float:
    """Seconds of a builtin_interfaces Time or Duration."""
    return stamp.sec + stamp.nanosec * 1e-9


def joint_state_to_ros2(sample: JointStateSample, stamp: Time) -> JointState:
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(sample.name)
    msg.position = [float(v) for v in sample.position]
    msg.velocity = [float(v) for v in sample.velocity]
    msg.effort = [float(v) for v in sample.effort]
    return msg


def trajectory_from_ros2(msg: Ros2JointTrajectory, stamp_offset_s: float = 0.0) -> JointTrajectory:
    """A ROS 2 trajectory as jointctl's; ``stamp_offset_s`` maps the ROS clock onto loop time (a zero stamp
    stays zero: "start now")."""
    stamp = seconds_of(msg.header.stamp)
    return JointTrajectory(
        joint_names=tuple(msg.joint_names),
        points=tuple(
            JointTrajectoryPoint(tuple(p.positions), tuple(p.velocities), tuple(p.accelerations),
                                 tuple(p.effort), seconds_of(p.time_from_start))
            for p in msg.points),
        stamp_s=stamp - stamp_offset_s if stamp > 0 else 0.0,
        frame_id=msg.header.frame_id)


def tolerances_from_ros2(goal) -> GoalTolerances:
    """A FollowJointTrajectory goal's own position tolerances and goal time (control_msgs: 0 keeps the controller's,
    -1 takes the check away). Velocity and acceleration tolerances are not checked by jointctl's executor."""
    return GoalTolerances(path={t.name: t.position for t in goal.path_tolerance},
                          goal={t.name: t.position for t in goal.goal_tolerance},
                          goal_time_s=seconds_of(goal.goal_time_tolerance))


__all__ = ["joint_state_to_ros2", "seconds_of", "time_msg", "tolerances_from_ros2", "trajectory_from_ros2"]

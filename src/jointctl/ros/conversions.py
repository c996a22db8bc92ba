"""jointctl values <-> ROS messages, field by field."""

from __future__ import annotations

import rospy
from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory as RosJointTrajectory
from trajectory_msgs.msg import JointTrajectoryPoint as RosJointTrajectoryPoint

from jointctl.control.joint_state_controller import JointStateSample
from jointctl.trajectory.goals import GoalTolerances
from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint


def trajectory_from_ros(msg: RosJointTrajectory, stamp_offset_s: float = 0.0) -> JointTrajectory:
    """A ROS trajectory as jointctl's; ``stamp_offset_s`` maps the ROS clock onto loop time
    (a zero stamp stays zero: "start now")."""
    stamp = msg.header.stamp.to_sec()
    return JointTrajectory(
        joint_names=tuple(msg.joint_names),
        points=tuple(
            JointTrajectoryPoint(tuple(p.positions), tuple(p.velocities), tuple(p.accelerations),
                                 tuple(p.effort), p.time_from_start.to_sec())
            for p in msg.points
        ),
        stamp_s=stamp - stamp_offset_s if stamp > 0 else 0.0,
        frame_id=msg.header.frame_id,
    )


def tolerances_from_ros(goal) -> GoalTolerances:
    """A FollowJointTrajectory goal's own position tolerances and goal time (control_msgs: 0 keeps the controller's,
    -1 takes the check away). Velocity and acceleration tolerances are not checked by jointctl's executor."""
    return GoalTolerances(path={t.name: t.position for t in goal.path_tolerance},
                          goal={t.name: t.position for t in goal.goal_tolerance},
                          goal_time_s=goal.goal_time_tolerance.to_sec())


def trajectory_to_ros(trajectory: JointTrajectory) -> RosJointTrajectory:
    msg = RosJointTrajectory()
    msg.header.stamp = rospy.Time.from_sec(trajectory.stamp_s)
    msg.header.frame_id = trajectory.frame_id
    msg.joint_names = list(trajectory.joint_names)
    for p in trajectory.points:
        msg.points.append(RosJointTrajectoryPoint(
            positions=list(p.positions), velocities=list(p.velocities),
            accelerations=list(p.accelerations), effort=list(p.effort),
            time_from_start=rospy.Duration.from_sec(p.time_from_start_s)))
    return msg


def joint_state_to_ros(sample: JointStateSample, stamp: rospy.Time) -> JointState:
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(sample.name)
    msg.position = list(sample.position)
    msg.velocity = list(sample.velocity)
    msg.effort = list(sample.effort)
    return msg


def wrench_to_ros(wrench, frame_id: str, stamp: rospy.Time) -> WrenchStamped:
    msg = WrenchStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    f, t = msg.wrench.force, msg.wrench.torque
    f.x, f.y, f.z, t.x, t.y, t.z = wrench
    return msg

"""An actionlib client in its own process (rospy allows one node per process).

    python action_client.py KIND SERVER JSON_GOAL [--cancel-after S]

KIND is follow (control_msgs/FollowJointTrajectory), traj (example_trajectory/TrajAction) or
arm (arm7dof_traj_as/trajAction). JSON_GOAL: {"joint_names": [...], "points": [[t, [q...]], ...]}.
Prints one JSON line: the final state name, the result fields and the text.
"""

import json
import sys
import time

import actionlib
import rospy
from actionlib_msgs.msg import GoalStatus
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

STATES = {getattr(GoalStatus, n): n for n in ("PENDING", "ACTIVE", "PREEMPTED", "SUCCEEDED", "ABORTED",
                                             "REJECTED", "PREEMPTING", "RECALLING", "RECALLED", "LOST")}


def result_connected(client, timeout_s: float) -> bool:
    """Whether the server connects to ``client``'s result subscription within ``timeout_s``: actionlib's
    wait_for_server does not wait for it, and a goal rejected at once would have its result published before it,
    lost, and the client wait for it in vain."""
    deadline = time.monotonic() + timeout_s
    while client.action_client.result_sub.get_num_connections() == 0:
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)  # (rospy has no event for a new connection)
    return True


def main() -> None:
    kind, server, spec = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
    cancel_after = float(sys.argv[5]) if len(sys.argv) > 5 and sys.argv[4] == "--cancel-after" else None
    if kind == "follow":
        from control_msgs.msg import FollowJointTrajectoryAction as Action, FollowJointTrajectoryGoal as Goal
    elif kind == "traj":
        from example_trajectory.msg import TrajAction as Action, TrajGoal as Goal
    else:
        from arm7dof_traj_as.msg import trajAction as Action, trajGoal as Goal
    rospy.init_node("jointctl_test_client", anonymous=True)
    client = actionlib.SimpleActionClient(server, Action)
    if not client.wait_for_server(rospy.Duration(20)):
        print(json.dumps({"state": "NO_SERVER"}))
        return
    if not result_connected(client, 20.0):
        print(json.dumps({"state": "NO_RESULT_CONNECTION"}))
        return
    goal = Goal()
    goal.trajectory = JointTrajectory(joint_names=spec["joint_names"])
    for t, q in spec["points"]:
        goal.trajectory.points.append(JointTrajectoryPoint(positions=q, time_from_start=rospy.Duration(t)))
    feedback = []
    client.send_goal(goal, feedback_cb=lambda fb: feedback.append(1))
    if cancel_after is not None:
        rospy.sleep(cancel_after)
        client.cancel_goal()
    client.wait_for_result(rospy.Duration(60))
    result = client.get_result()
    fields = {f: getattr(result, f) for f in result.__slots__} if result is not None else {}
    print(json.dumps({"state": STATES.get(client.get_state(), "?"), "result": fields,
                      "text": client.get_goal_status_text(), "feedback": len(feedback)}))


if __name__ == "__main__":
    main()

"""Send several goals to one action server at given times, as the book's clients do, and report each.

    python goal_sequence_client.py KIND SERVER JSON_GOALS

KIND is follow, traj or arm (as in action_client.py). JSON_GOALS is a list of
``{"send_at_s": t, "after_previous": b, "stamp_age_s": a, "cancel_at_s": c, "joint_names": [...],
"points": [[t, [q...]], ...]}``: each goal is sent ``send_at_s`` after the first, by its own
SimpleActionClient (the book's prompter sends its next goal while the first runs), or, with
``after_previous``, once the goal before it has ended (one process for goals sent one after another); ``stamp_age_s`` stamps the trajectory header that many
seconds before sending (the book's playfile client stamps before waiting for the server; 0 leaves
the stamp zero); ``cancel_at_s`` cancels the goal then. Prints one JSON line: per goal, its final
state name, status text, result fields, the number of feedback messages and the time (s after the
first send) it ended.
"""

import json
import sys
import time

import actionlib
import rospy
from actionlib_msgs.msg import GoalStatus
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from action_client import result_connected  # (beside this script)

STATES = {getattr(GoalStatus, n): n for n in ("PENDING", "ACTIVE", "PREEMPTED", "SUCCEEDED", "ABORTED",
                                             "REJECTED", "PREEMPTING", "RECALLING", "RECALLED", "LOST")}


def action_types(kind):
    if kind == "follow":
        from control_msgs.msg import FollowJointTrajectoryAction as Action, FollowJointTrajectoryGoal as Goal
    elif kind == "traj":
        from example_trajectory.msg import TrajAction as Action, TrajGoal as Goal
    else:
        from arm7dof_traj_as.msg import trajAction as Action, trajGoal as Goal
    return Action, Goal


def main() -> None:
    kind, server, specs = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
    Action, Goal = action_types(kind)
    rospy.init_node("jointctl_test_sequence", anonymous=True)
    clients = [actionlib.SimpleActionClient(server, Action) for _ in specs]
    for client in clients:
        if not client.wait_for_server(rospy.Duration(30)):
            print(json.dumps({"error": "NO_SERVER"}))
            return
        if not result_connected(client, 30.0):
            print(json.dumps({"error": "NO_RESULT_CONNECTION"}))
            return
    ended = [None] * len(specs)
    feedback = [0] * len(specs)
    start = time.monotonic()

    def done_callback(k):
        return lambda state, result: ended.__setitem__(k, time.monotonic() - start)

    def feedback_callback(k):
        return lambda fb: feedback.__setitem__(k, feedback[k] + 1)

    for k, (spec, client) in enumerate(zip(specs, clients)):
        while time.monotonic() - start < spec.get("send_at_s", 0.0):
            time.sleep(0.005)
        if spec.get("after_previous") and k > 0:
            clients[k - 1].wait_for_result(rospy.Duration(120))
        goal = Goal()
        goal.trajectory = JointTrajectory(joint_names=spec["joint_names"])
        for t, q in spec["points"]:
            goal.trajectory.points.append(JointTrajectoryPoint(positions=q, time_from_start=rospy.Duration(t)))
        for name, position in spec.get("path_tolerance", {}).items():  # FollowJointTrajectory only
            from control_msgs.msg import JointTolerance
            goal.path_tolerance.append(JointTolerance(name=name, position=position))
        if spec.get("stamp_age_s"):
            goal.trajectory.header.stamp = rospy.Time.now() - rospy.Duration(spec["stamp_age_s"])
        client.send_goal(goal, done_cb=done_callback(k), feedback_cb=feedback_callback(k))
    cancels = sorted((spec["cancel_at_s"], k) for k, spec in enumerate(specs) if "cancel_at_s" in spec)
    for at_s, k in cancels:
        while time.monotonic() - start < at_s:
            time.sleep(0.005)
        clients[k].cancel_goal()
    report = []
    for k, client in enumerate(clients):
        client.wait_for_result(rospy.Duration(120))
        result = client.get_result()
        report.append({"state": STATES.get(client.get_state(), "?"), "text": client.get_goal_status_text(),
                       "result": {f: getattr(result, f) for f in result.__slots__} if result is not None else {},
                       "feedback": feedback[k], "ended_s": ended[k]})
    print(json.dumps(report))


if __name__ == "__main__":
    main()

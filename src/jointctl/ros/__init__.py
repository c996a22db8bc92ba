"""ROS 1 on the wire: the only package of jointctl that imports rospy and actionlib.

It runs a scenario's loop as a ROS node: joint states, sensor wrenches and controller states
published, controller commands subscribed, trajectory goals served as actions, all through the
same doors (``set_reference``, ``TrajectoryExecutor.submit``) every other edge uses.
"""

"""``joint_trajectory_controller/JointTrajectoryController``: ros2_controllers 4.18's trajectory controller, on
jointctl's trajectory executor (:class:`~jointctl.trajectory.executor.TrajectoryExecutor`: its goals, doors,
validation and plans), with ROS 2's parameters and what the ROS 2 controller computes differently.

Parameters (``ros__parameters``, ros2_controllers' names and defaults)::

    joint_trajectory_controller:
      ros__parameters:
        joints: [joint1, joint2]
        command_interfaces: [effort]          # [effort] (a PID per joint) or [position]
        state_interfaces: [position, velocity]
        gains:                                # effort: per joint p, i, d, i_clamp, ff_velocity_scale (all 0.0)
          joint1: {p: 400.0, i: 0.0, d: 20.0, i_clamp: 0.0, ff_velocity_scale: 0.0}
        constraints:
          stopped_velocity_tolerance: 0.01    # m/s or rad/s, checked at the goal (0: not)
          goal_time: 0.0                      # s after the last point to reach the goal (0: wait for ever)
          joint1: {trajectory: 0.0, goal: 0.0}   # path and goal position tolerances (0: not checked)
        interpolation_method: splines         # by the points' fields: linear, cubic or quintic
        allow_partial_joints_goal: false
        allow_nonzero_velocity_at_trajectory_end: false
        open_loop_control: false
        action_monitor_rate: 20.0             # Hz of the goal's feedback

What it computes as the ROS 2 controller does:

- a new trajectory starts from the **measured** state (position and velocity) at the cycle it is taken up,
  which is that cycle's desired state (``open_loop_control: true``: from the last desired state);
- with ``command_interfaces: [effort]`` (the PIDs made once, at configure: not reset when it starts again) each
  joint's effort is ``ff_velocity_scale · v_next +
  Pid(e, ė)``: control_toolbox's PID (:class:`~jointctl.control.toolbox_pid.ToolboxPid`, the integral term
  clamped to ±``i_clamp``, no antiwindup) on the position error (the shortest angle on a continuous joint) and
  the velocity error, both against the desired state of this cycle, ``v_next`` the desired velocity one
  period on; with ``[position]`` the position command is the desired position one period on;
- tolerances: the path tolerance aborts a goal (PATH_TOLERANCE_VIOLATED); after the last point a goal
  succeeds once every joint is within its goal tolerance (where set) and moves slower than
  ``stopped_velocity_tolerance`` (where positive), whether or not a goal tolerance is set; it is aborted
  (GOAL_TOLERANCE_VIOLATED) ``goal_time`` after the last point, never when ``goal_time`` is 0;
- a goal naming fewer joints than ``joints`` without ``allow_partial_joints_goal`` is refused (INVALID_JOINTS),
  and one whose last point has a velocity without ``allow_nonzero_velocity_at_trajectory_end`` (INVALID_GOAL).

What stays the executor's (docs/ros2_control_files.md): goals are also refused outside the URDF's range and speed
limits; a cancel or an abort brings the joints to rest along a deceleration (``stop_deceleration``, 5 per s²)
where the ROS 2 controller holds the measured position at once.

The doors are the executor's: :meth:`~jointctl.trajectory.executor.TrajectoryExecutor.submit` (a goal, from the
action server or the ``~/joint_trajectory`` topic; raises InvalidTrajectory with the FollowJointTrajectory error
code), ``GoalHandle.cancel``, :attr:`~jointctl.trajectory.executor.TrajectoryExecutor.latest_feedback`.
"""

from __future__ import annotations

import math

from jointctl.control.params import Params
from jointctl.control.pid_controller import string_list
from jointctl.control.toolbox_pid import ToolboxGains, ToolboxPid, period_ns, shortest_angular_distance
from jointctl.errors import ConfigError
from jointctl.hardware.interface import EFFORT, POSITION, HardwareInterface
from jointctl.model.robot_model import RobotModel
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.executor import TrajectoryExecutor
from jointctl.trajectory.messages import JointTrajectory
from jointctl.trajectory.plan import interleave

#: ros2_controllers' interpolation methods and the executor's interpolation for each.
INTERPOLATION_METHODS = {"splines": "auto"}
GAIN_FIELDS = ("p", "i", "d", "i_clamp", "ff_velocity_scale")
#: ``std::numeric_limits<float>::epsilon()``: a last point's velocity above it is not zero to the ROS 2 controller.
FLOAT_EPSILON = 1.1920928955078125e-07


class JointTrajectoryController(TrajectoryExecutor):
    """ros2_controllers' ``joint_trajectory_controller/JointTrajectoryController`` (see the module docstring)."""

    stopped_velocity_always = True

    def __init__(self, name: str, params: Params) -> None:
        joints = string_list(params, "joints", required=True)
        command_joints = string_list(params, "command_joints")
        if command_joints and command_joints != joints:
            raise params.error("jointctl commands the joints it reads (command_joints empty or equal to joints)",
                               "command_joints", list(command_joints))
        commands = string_list(params, "command_interfaces", required=True)
        if list(commands) not in (["effort"], ["position"]):
            raise params.error("jointctl's JointTrajectoryController commands [effort] or [position]",
                               "command_interfaces", list(commands))
        self.effort = commands == ("effort",)
        states = string_list(params, "state_interfaces", required=True)
        needed = ("position", "velocity") if self.effort else ("position",)
        if any(s not in ("position", "velocity") for s in states) or any(s not in states for s in needed):
            raise params.error(f"must be [{', '.join(needed)}]" + ("" if self.effort else " or [position, velocity]")
                               + f" for {commands[0]} commands", "state_interfaces", list(states))
        self.allow_partial_joints_goal = params.boolean("allow_partial_joints_goal", False)
        self.allow_nonzero_velocity_at_trajectory_end = params.boolean("allow_nonzero_velocity_at_trajectory_end",
                                                                       False)
        self.open_loop_control = params.boolean("open_loop_control", False)
        params.boolean("set_last_command_interface_value_as_state_on_activation", True)
        if params.boolean("allow_integration_in_goal_trajectories", False):
            raise params.error("jointctl's goals give positions", "allow_integration_in_goal_trajectories", True)
        method = params.string("interpolation_method", "splines")
        if method not in INTERPOLATION_METHODS:
            raise params.error("jointctl interpolates with splines (a trajectory without interpolation is not "
                               "followed)", "interpolation_method", method)
        monitor_rate = params.number("action_monitor_rate", 20.0, minimum=0.1)
        if params.number("cmd_timeout", 0.0, minimum=0) != 0.0:
            raise params.error("jointctl holds the last point without a timeout (0.0)", "cmd_timeout",
                               params.values["cmd_timeout"])
        gains = params.child("gains") if params.has("gains") else Params({}, source=params.source,
                                                                           field=params.path("gains"))
        self.joint_gains = []
        for joint in joints:
            g = gains.child(joint) if gains.has(joint) else Params({}, source=params.source,
                                                                    field=gains.path(joint))
            values = {k: g.number(k, 0.0) for k in GAIN_FIELDS}
            g.reject_unknown()
            if values["i_clamp"] < 0:
                raise g.error("must not be negative (the integral term is clamped to ±i_clamp)", "i_clamp",
                              values["i_clamp"])
            self.joint_gains.append(values)
        gains.reject_unknown()
        constraints = params.child("constraints") if params.has("constraints") else Params(
            {}, source=params.source, field=params.path("constraints"))
        stopped = constraints.number("stopped_velocity_tolerance", 0.01)
        goal_time = constraints.number("goal_time", 0.0, minimum=0)
        path_tolerance, goal_tolerance = {}, {}
        for joint in joints:
            c = constraints.child(joint) if constraints.has(joint) else Params({}, source=params.source,
                                                                              field=constraints.path(joint))
            path_tolerance[joint] = c.number("trajectory", 0.0)
            goal_tolerance[joint] = c.number("goal", 0.0)
            c.reject_unknown()
        constraints.reject_unknown()
        params.reject_unknown({"type"})
        executor = {"joints": list(joints), "interpolation": INTERPOLATION_METHODS[method],
                    "feedback_rate_hz": monitor_rate, "goal_time_s": goal_time,
                    "stopped_velocity_tolerance": max(stopped, 0.0), "goal_tolerance": goal_tolerance,
                    "path_tolerance": path_tolerance}
        if self.effort:
            executor["velocity_feedforward"] = True
        super().__init__(name, Params(executor, source=params.source, field=params.field))
        self.stopped_velocity_tolerance = stopped  # 0 or below: not checked
        self.goal_time_limited = goal_time > 0.0
        if goal_time == 0.0:  # the ROS 2 controller waits for the goal without end
            self.goal_time_s = math.inf
        self._scales = tuple(g["ff_velocity_scale"] for g in self.joint_gains)

    # -- controller contract -----------------------------------------------------------------
    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        interface = EFFORT if self.effort else POSITION
        return tuple((joint, interface) for joint in self.joint_names)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        interface = EFFORT if self.effort else POSITION
        for joint in self.joint_names:
            offered = hardware.command_interfaces(joint)
            if interface not in offered:
                raise ConfigError(f"joint {joint!r} has no {interface} command interface on this hardware (it has: "
                                  f"{', '.join(sorted(offered)) or 'none'})", source=self.source,
                                  field=f"{self.field}.command_interfaces", value=[interface])
        if not self.effort:
            super().configure(hardware, robot)
            return
        self._resolve(hardware, robot)
        n = len(hardware.joint_names)
        # The desired state, kept (the executor writes it here); the hardware gets efforts.
        self._positions, self._velocities, self._accelerations = [0.0] * n, [0.0] * n, [0.0] * n
        self._in_use = self.context.references if self.context is not None else None
        self._effort = hardware.command_buffer(EFFORT)
        self.pids = [ToolboxPid(ToolboxGains(g["p"], g["i"], g["d"], g["i_clamp"], -g["i_clamp"]))
                     for g in self.joint_gains]
        self._wrap = tuple(robot.joint(j).type == "continuous" for j in self.joint_names)

    # -- ROS 2's goal checks ----------------------------------------------------------------
    def _check_running_and_points(self, trajectory: JointTrajectory) -> None:
        super()._check_running_and_points(trajectory)
        if not isinstance(trajectory, JointTrajectory):
            return
        names = trajectory.joint_names
        if not self.allow_partial_joints_goal and isinstance(names, tuple) and len(names) != len(self.joint_names):
            raise InvalidTrajectory(TrajectoryErrorCode.INVALID_JOINTS,
                                    f"the goal must name the controller's {len(self.joint_names)} joints "
                                    f"(allow_partial_joints_goal is false)", field="joint_names", value=list(names))
        points = trajectory.points
        if not self.allow_nonzero_velocity_at_trajectory_end and isinstance(points, tuple) and points:
            velocities = points[-1].velocities
            for k, v in enumerate(velocities if isinstance(velocities, tuple) else ()):
                if isinstance(v, (int, float)) and abs(v) > FLOAT_EPSILON:
                    raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL,
                                            "the last point's velocity is not zero "
                                            "(allow_nonzero_velocity_at_trajectory_end is false)",
                                            point=len(points) - 1, joint=names[k] if k < len(names) else None,
                                            value=v)

    # -- the cycle ---------------------------------------------------------------------------
    def _activate(self, handle, time_s: float, period_s: float) -> None:
        """ROS 2's ``set_point_before_trajectory_msg(time, state)``: the trajectory starts at this cycle's time from
        the measured state (open loop: from the last desired state), which is this cycle's desired state."""
        if not self.open_loop_control:
            hw = self.hardware
            self._ref = interleave(self._of_joints(hw.position), self._of_joints(hw.velocity), self._zeros)
        super()._activate(handle, time_s, period_s if self._hands_over() else 0.0)
        # A goal of positions only: from its last point on ROS 2 samples that point, with velocity 0 (where the
        # linear segment's slope would still be the velocity at the last knot).
        self._positions_only = handle.validated.velocities is None

    _positions_only = False

    def update(self, time_s: float, period_s: float) -> None:
        super().update(time_s, period_s)
        plan = self._plan
        if (self._positions_only and plan is not None and not plan.stopping and time_s + 1e-9 >= plan.end_s
                and any(self._ref[1::3])):
            self._ref = interleave(self._ref[0::3], self._zeros, self._zeros)
        ahead = plan.at(time_s + period_s, period_s) if plan is not None else None  # the desired state a period on
        if not self.effort:
            if ahead is not None:
                for k, i in enumerate(self.hw_index):
                    self._positions[i] = ahead[3 * k]
            return
        ref, hw, effort = self._ref, self.hardware, self._effort
        dt_ns = period_ns(period_s)
        for k, i in enumerate(self.hw_index):
            desired, measured = ref[3 * k], hw.position[i]
            error = shortest_angular_distance(measured, desired) if self._wrap[k] else desired - measured
            command = self.pids[k].compute_with_rate(error, ref[3 * k + 1] - hw.velocity[i], dt_ns)
            scale = self._scales[k]
            if scale:
                command += scale * (ahead[3 * k + 1] if ahead is not None else ref[3 * k + 1])
            effort[i] = command


__all__ = ["JointTrajectoryController"]

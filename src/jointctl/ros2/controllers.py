"""Each running controller's face on ROS 2, under the names and interfaces of ros2_controllers.

ros2_control makes every controller a node named after it (``/<controller>``) with its parameters, topics
relative to it (``~/reference`` is ``/<controller>/reference``) and the joint states on the global
``/joint_states``. jointctl's controllers get the same faces:

- a joint state controller (``joint_state_broadcaster/JointStateBroadcaster``, or the chapter's
  ``joint_state_controller``): ``/joint_states`` (sensor_msgs/msg/JointState) at its ``publish_rate``;
- a PID joint controller (the chapter's effort position and velocity controllers): pid_controller's face.
  ``~/reference`` (control_msgs/msg/MultiDOFCommand: ``dof_names`` [the joint, or empty], ``values`` [m, rad,
  m/s or rad/s]; best effort, depth 1, as pid_controller subscribes), ``~/controller_state``
  (control_msgs/msg/MultiDOFStateStamped) at ``state_rate_hz``, and parameters ``dof_names``,
  ``command_interface`` (``effort``), ``reference_and_state_interfaces`` (``[position]`` or ``[velocity]``),
  read-only, and ``gains.<joint>.{p, i, d, i_clamp_max, i_clamp_min, antiwindup}``, which ``ros2 param set``
  changes while running: validated whole (finite, p, i, d not negative, i_clamp_min not above i_clamp_max) and
  applied from the next cycle; a refused change is answered unsuccessful with the reason, and the gains stay;
- ros2_controllers' own types (:mod:`jointctl.control.pid_controller`, ``forward_command_controller``) keep their
  topics and parameters: pid_controller's ``~/reference``, ``~/controller_state`` (every cycle it runs, as
  pid_controller publishes), ``~/set_feedforward_control`` (std_srvs/srv/SetBool) and every parameter of its file
  (``gains.<dof>.*`` changed live through the controller's ``set_parameter``, which refuses what ros2_controllers
  refuses); forward_command_controller's ``~/commands`` (std_msgs/msg/Float64MultiArray, one value per joint) and its
  ``joints`` and ``interface_name`` parameters (read-only); joint_state_broadcaster's ``use_local_topics``;
- a trajectory executor (and ``joint_trajectory_controller/JointTrajectoryController``): joint_trajectory_controller's
  ``~/follow_joint_trajectory`` action (control_msgs/action/FollowJointTrajectory), ``~/joint_trajectory`` topic and ``~/controller_state``
  (control_msgs/msg/JointTrajectoryControllerState: the last cycle's reference against the joints' state, positions
  and velocities, at ``state_rate_hz``). As JTC does, a goal that is
  not valid is rejected when it arrives (its reason, with the error code JTC's result would carry, logged on
  /rosout); one that strays beyond its tolerances ends aborted with PATH_TOLERANCE_VIOLATED (-4) or
  GOAL_TOLERANCE_VIOLATED (-5) (the controller's tolerances, or the goal's own position tolerances and goal time
  where it gives them: 0 keeps the controller's, -1 takes the check away), a cancel decelerates the joints to rest
  and ends canceled.

Callbacks run on the executor's threads; they hand values to the controllers' doors (single-slot, read by the
loop at the start of its next cycle) and never touch the loop's state otherwise.
"""

from __future__ import annotations

import math

from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTrajectoryControllerState, MultiDOFCommand, MultiDOFStateStamped, SingleDOFState
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool
from trajectory_msgs.msg import JointTrajectory as Ros2JointTrajectory
from trajectory_msgs.msg import JointTrajectoryPoint

from jointctl.control.forward_command_controller import ForwardCommandController
from jointctl.control.joint_controllers import JointPositionController, _EffortJointController
from jointctl.control.pid_controller import GAIN_NUMBERS, GAIN_SWITCHES, PidController, PidControllerState
from jointctl.control.joint_state_controller import JointStateController
from jointctl.control.pid import PidGains
from jointctl.errors import InvalidCommand, JointCtlError
from jointctl.ros2.conversions import joint_state_to_ros2, tolerances_from_ros2, trajectory_from_ros2
from jointctl.trajectory.errors import InvalidTrajectory
from jointctl.trajectory.executor import GoalResult, GoalStatus, TrajectoryExecutor, TrajectoryFeedback

#: pid_controller's ``~/reference`` subscription: best effort, depth 1 (ros2-facts).
REFERENCE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
GAIN_FIELDS = ("p", "i", "d", "i_clamp_max", "i_clamp_min")
RESULT_WAIT_S = 0.05  # how often a goal's execute callback looks for a cancel [s]


class _Face:
    """What the faces share: whether their controller runs (an inactive one's doors refuse, logged, as a
    deactivated ros2_control controller takes no reference: nothing it is sent moves the robot later)."""

    node: Node
    controller: object
    manager = None  # set by faces()

    def _refused_while_inactive(self, what: str) -> bool:
        if self.manager is None or self.controller in self.manager.active:
            return False
        self.node.get_logger().warn(f"refused {what}: the controller is inactive (ros2 control switch_controllers "
                                    f"--activate {self.controller.name})")
        return True


def pid_faced(controller) -> bool:
    """Whether ``controller`` gets pid_controller's face (a PID on one joint, through its gains)."""
    return isinstance(controller, _EffortJointController)


class JointStateFace:
    """``/joint_states`` of a joint state controller (``~/joint_states`` with ``use_local_topics``)."""

    def __init__(self, node: Node, controller: JointStateController, clock) -> None:
        topic = "~/joint_states" if getattr(controller, "use_local_topics", False) else "/joint_states"
        self.publisher = node.create_publisher(JointState, topic, 10)
        controller.subscribe(lambda sample: self.publisher.publish(
            joint_state_to_ros2(sample, clock.stamp(sample.time_s))))


class PidFace(_Face):
    """pid_controller's topics and parameters on a jointctl PID joint controller (see the module's doc)."""

    def __init__(self, node: Node, controller: _EffortJointController, session, clock,
                 state_rate_hz: float) -> None:
        self.node, self.controller, self.session, self.clock = node, controller, session, clock
        joint = controller.joint
        self.prefix = f"gains.{joint}."
        interface = "position" if isinstance(controller, JointPositionController) else "velocity"
        read_only = ParameterDescriptor(read_only=True)
        node.declare_parameter("dof_names", [joint], read_only)
        node.declare_parameter("command_interface", "effort", read_only)
        node.declare_parameter("reference_and_state_interfaces", [interface], read_only)
        gains = controller.pid.gains
        for name in GAIN_FIELDS:
            node.declare_parameter(self.prefix + name, float(getattr(gains, name)))
        node.declare_parameter(self.prefix + "antiwindup", bool(gains.antiwindup))
        node.add_on_set_parameters_callback(self._on_parameters)
        self.subscription = node.create_subscription(MultiDOFCommand, "~/reference", self._on_reference,
                                                     REFERENCE_QOS)
        self.state_publisher = node.create_publisher(MultiDOFStateStamped, "~/controller_state", 1)
        loop = session.loop
        self._every = max(1, round(1.0 / (state_rate_hz * loop.period_s)))
        self._count = 0
        self._interface = interface
        loop.add_observer(self._publish_state)

    # -- parameters (executor thread) ------------------------------------------------------------
    def _on_parameters(self, parameters) -> SetParametersResult:
        changes = {p.name[len(self.prefix):]: p.value for p in parameters if p.name.startswith(self.prefix)}
        if not changes:
            return SetParametersResult(successful=True)
        current = self.controller.pid.gains
        values = {name: getattr(current, name) for name in (*GAIN_FIELDS, "antiwindup")}
        for name, value in changes.items():
            if name not in values:
                return SetParametersResult(successful=False, reason=f"no gain {self.prefix}{name}")
            if name == "antiwindup":
                if not isinstance(value, bool):
                    return SetParametersResult(successful=False, reason=f"{self.prefix}antiwindup must be a bool")
            elif isinstance(value, bool) or not isinstance(value, (int, float)):
                return SetParametersResult(successful=False, reason=f"{self.prefix}{name} must be a number")
            values[name] = value if name == "antiwindup" else float(value)
        try:
            gains = PidGains(**values)
        except JointCtlError as exc:
            return SetParametersResult(successful=False, reason=f"{self.prefix}{exc.field.split('.')[-1]}: "
                                                                f"{exc.message} (value {exc.value!r})")
        self.controller.set_gains(gains)
        self.node.get_logger().info(f"gains now p={gains.p:g} i={gains.i:g} d={gains.d:g} "
                                    f"i_clamp=[{gains.i_clamp_min:g}, {gains.i_clamp_max:g}] "
                                    f"antiwindup={gains.antiwindup}")
        return SetParametersResult(successful=True)

    # -- reference (executor thread) -------------------------------------------------------------
    def _on_reference(self, msg: MultiDOFCommand) -> None:
        if self._refused_while_inactive("a reference"):
            return
        joint = self.controller.joint
        names = list(msg.dof_names)
        if names and names != [joint]:
            self.node.get_logger().warn(f"refused a reference for dof_names {names}: this controller has [{joint}]")
            return
        if len(msg.values) != 1:
            self.node.get_logger().warn(f"refused a reference with {len(msg.values)} values for 1 dof ({joint})")
            return
        try:
            self.controller.set_reference(float(msg.values[0]))
        except InvalidCommand as exc:
            self.node.get_logger().warn(f"refused {exc}")

    # -- state (loop thread: publish only) -------------------------------------------------------
    def _publish_state(self, time_s: float) -> None:
        self._count += 1
        if self._count % self._every:
            return
        c, hw = self.controller, self.session.hardware
        i = c.index
        position = self._interface == "position"
        feedback = hw.position[i] if position else hw.velocity[i]
        reference = c.reference
        msg = MultiDOFStateStamped()
        msg.header.stamp = self.clock.stamp(time_s)
        state = SingleDOFState(name=c.joint, reference=float(reference), feedback=float(feedback),
                               feedback_dot=float(hw.velocity[i]) if position else math.nan,
                               error=float(reference - feedback), error_dot=math.nan,
                               time_step=float(self.session.loop.period_s), output=float(c.effort_command[i]))
        msg.dof_states = [state]
        self.state_publisher.publish(msg)


class PidControllerFace(_Face):
    """ros2_controllers' pid_controller on jointctl's :class:`PidController` (see the module's docstring)."""

    def __init__(self, node: Node, controller: PidController, clock) -> None:
        self.node, self.controller, self.clock = node, controller, clock
        read_only = ParameterDescriptor(read_only=True)
        node.declare_parameter("dof_names", list(controller.dof_names), read_only)
        node.declare_parameter("reference_and_state_dof_names", list(controller.state_dof_names), read_only)
        node.declare_parameter("command_interface", controller.command_interface, read_only)
        node.declare_parameter("reference_and_state_interfaces", list(controller.interfaces), read_only)
        node.declare_parameter("use_external_measured_states", controller.use_external_measured_states, read_only)
        for dof, gains in zip(controller.dof_names, controller.gains):
            for name in (*GAIN_NUMBERS, *GAIN_SWITCHES):
                node.declare_parameter(f"gains.{dof}.{name}", getattr(gains, name))
        node.add_on_set_parameters_callback(self._on_parameters)
        self.subscription = node.create_subscription(MultiDOFCommand, "~/reference", self._on_reference,
                                                     REFERENCE_QOS)
        self.state_publisher = node.create_publisher(MultiDOFStateStamped, "~/controller_state", 1)
        node.create_service(SetBool, "~/set_feedforward_control", self._on_feedforward)
        controller.subscribe(self._publish_state)

    def _on_parameters(self, parameters) -> SetParametersResult:
        for parameter in parameters:
            try:
                self.controller.set_parameter(parameter.name, parameter.value)
            except JointCtlError as exc:
                return SetParametersResult(successful=False, reason=f"{parameter.name}: {exc.message} "
                                                                    f"(value {parameter.value!r})")
        return SetParametersResult(successful=True)

    def _on_reference(self, msg: MultiDOFCommand) -> None:
        if self._refused_while_inactive("a reference"):
            return
        try:
            self.controller.set_reference(list(msg.values), list(msg.values_dot) or None, list(msg.dof_names) or None)
        except InvalidCommand as exc:
            self.node.get_logger().warn(f"refused a reference: {exc}")

    def _on_feedforward(self, request, response):
        try:
            self.controller.set_feedforward(bool(request.data))
            response.success, response.message = True, ""
        except JointCtlError as exc:
            response.success, response.message = False, str(exc)
        return response

    def _publish_state(self, state: PidControllerState) -> None:
        msg = MultiDOFStateStamped()
        msg.header.stamp = self.clock.stamp(state.time_s)
        msg.dof_states = [SingleDOFState(name=d.name, reference=d.reference, feedback=d.feedback,
                                         feedback_dot=d.feedback_dot, error=d.error, error_dot=d.error_dot,
                                         time_step=d.time_step, output=d.output) for d in state.dof_states]
        self.state_publisher.publish(msg)


class ForwardCommandFace(_Face):
    """forward_command_controller's ``~/commands`` on jointctl's :class:`ForwardCommandController`."""

    def __init__(self, node: Node, controller: ForwardCommandController) -> None:
        self.node, self.controller = node, controller
        read_only = ParameterDescriptor(read_only=True)
        node.declare_parameter("joints", list(controller.joints), read_only)
        node.declare_parameter("interface_name", controller.interface_name, read_only)
        self.subscription = node.create_subscription(Float64MultiArray, "~/commands", self._on_commands, 1)

    def _on_commands(self, msg: Float64MultiArray) -> None:
        if self._refused_while_inactive("commands"):
            return
        try:
            self.controller.set_commands(list(msg.data))
        except InvalidCommand as exc:
            self.node.get_logger().warn(f"refused commands: {exc}")


class TrajectoryFace(_Face):
    """joint_trajectory_controller's action and topic on a trajectory executor (see the module's doc)."""

    def __init__(self, node: Node, executor: TrajectoryExecutor, clock, loop, hardware, state_rate_hz: float) -> None:
        self.node, self.executor, self.controller, self.clock = node, executor, executor, clock
        group = ReentrantCallbackGroup()
        self.server = ActionServer(node, FollowJointTrajectory, "~/follow_joint_trajectory",
                                   execute_callback=self._execute, goal_callback=self._on_goal,
                                   cancel_callback=lambda _goal: CancelResponse.ACCEPT, callback_group=group)
        self.subscription = node.create_subscription(Ros2JointTrajectory, "~/joint_trajectory", self._on_topic, 1,
                                                     callback_group=group)
        self.state_publisher = node.create_publisher(JointTrajectoryControllerState, "~/controller_state", 1)
        self._every = max(1, round(1.0 / (state_rate_hz * loop.period_s)))
        self._count = 0
        self._hardware = hardware
        self._index = [hardware.joint_index(j) for j in executor.joint_names]
        loop.add_observer(self._publish_state)

    def _publish_state(self, time_s: float) -> None:
        """The reference of the last cycle against the joints' state, at ``state_rate_hz`` (the loop thread:
        publish only)."""
        self._count += 1
        if self._count % self._every:
            return
        hw, executor = self._hardware, self.executor
        actual = [hw.position[i] for i in self._index]
        speed = [hw.velocity[i] for i in self._index]
        desired, desired_speed = executor.desired, executor.desired_velocity
        msg = JointTrajectoryControllerState()
        msg.header.stamp = self.clock.stamp(time_s)
        msg.joint_names = list(executor.joint_names)
        msg.reference = JointTrajectoryPoint(positions=desired, velocities=desired_speed)
        msg.feedback = JointTrajectoryPoint(positions=actual, velocities=speed)
        msg.error = JointTrajectoryPoint(positions=[d - a for d, a in zip(desired, actual)],
                                         velocities=[d - a for d, a in zip(desired_speed, speed)])
        msg.speed_scaling_factor = 1.0
        self.state_publisher.publish(msg)

    def _trajectory(self, msg: Ros2JointTrajectory):
        return trajectory_from_ros2(msg, self.clock.ros_time_at_loop_zero())

    def _on_goal(self, goal) -> GoalResponse:
        if self._refused_while_inactive("a goal"):
            return GoalResponse.REJECT
        try:
            self.executor.check_goal_shape(self._trajectory(goal.trajectory))
            self.executor.tolerances_held_to(tolerances_from_ros2(goal))
        except InvalidTrajectory as exc:
            self.node.get_logger().error(f"rejected a goal ({exc.error_code.name} {int(exc.error_code)}): {exc}")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _on_topic(self, msg: Ros2JointTrajectory) -> None:
        if self._refused_while_inactive("a trajectory"):
            return
        try:
            self.executor.submit(self._trajectory(msg), now_s=self.clock.loop_now())
        except InvalidTrajectory as exc:
            self.node.get_logger().error(f"refused a trajectory ({exc.error_code.name}): {exc}")

    def _execute(self, goal_handle):
        """The goal's life (an executor thread): submitted to the loop, fed back, ended once."""
        result = FollowJointTrajectory.Result()
        try:
            handle = self.executor.submit(self._trajectory(goal_handle.request.trajectory),
                                          now_s=self.clock.loop_now(),
                                          on_feedback=lambda fb: goal_handle.publish_feedback(self._feedback(fb)),
                                          tolerances=tolerances_from_ros2(goal_handle.request))
        except InvalidTrajectory as exc:  # valid on arrival, not from where the robot is when it starts
            result.error_code, result.error_string = int(exc.error_code), str(exc)
            goal_handle.abort()
            return result
        done: GoalResult | None = None
        while done is None:
            done = handle.wait(RESULT_WAIT_S)
            if goal_handle.is_cancel_requested and not handle.cancel_requested:
                handle.cancel()
        result.error_code, result.error_string = int(done.error_code), done.error_string
        if done.status is GoalStatus.SUCCEEDED:
            goal_handle.succeed()
        elif done.status is GoalStatus.PREEMPTED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:
            goal_handle.abort()
        return result

    def _feedback(self, feedback: TrajectoryFeedback) -> FollowJointTrajectory.Feedback:
        msg = FollowJointTrajectory.Feedback()
        msg.header.stamp = self.clock.stamp(feedback.time_s)
        msg.joint_names = list(feedback.joint_names)
        msg.desired = JointTrajectoryPoint(positions=list(feedback.desired_positions),
                                           velocities=list(feedback.desired_velocities))
        msg.actual = JointTrajectoryPoint(positions=list(feedback.actual_positions),
                                          velocities=list(feedback.actual_velocities))
        msg.error = JointTrajectoryPoint(positions=list(feedback.errors))
        return msg


__all__ = ["ForwardCommandFace", "JointStateFace", "PidControllerFace", "PidFace", "TrajectoryFace", "faces",
           "pid_faced"]


def faces(node_for, session, clock, state_rate_hz: float) -> list:
    """The ROS 2 face of each of ``session``'s running controllers that has one; ``node_for(name)`` makes the node
    of a controller."""
    manager = session.manager
    made = []
    for controller in manager.active:
        if isinstance(controller, JointStateController):
            face = JointStateFace(node_for(controller.name), controller, clock)
        elif isinstance(controller, PidController):
            face = PidControllerFace(node_for(controller.name), controller, clock)
        elif isinstance(controller, ForwardCommandController):
            face = ForwardCommandFace(node_for(controller.name), controller)
        elif pid_faced(controller) and manager.command_owner(controller.name) is None:
            face = PidFace(node_for(controller.name), controller, session, clock, state_rate_hz)
        elif isinstance(controller, TrajectoryExecutor):
            face = TrajectoryFace(node_for(controller.name), controller, clock, session.loop, session.hardware,
                                  state_rate_hz)
        else:
            continue
        face.manager = manager
        made.append(face)
    return made

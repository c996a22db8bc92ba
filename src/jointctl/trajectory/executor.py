"""Execute joint trajectories inside the control loop, like ros_control's joint_trajectory_controller.

``trajectory_controllers/JointTrajectoryExecutor`` is a chained controller: it
feeds position, velocity and acceleration references to one position
controller per joint, every cycle (or at ``stream_rate_hz``, holding in
between, as the chapter's action servers stream to their position
controllers). Without ``position_controllers`` it commands the joints'
``position`` command interfaces itself, as ros_control's
``position_controllers/JointTrajectoryController`` does: for hardware that
servos its joints itself (an industrial controller), with no PID in front.
Goals arrive through :meth:`TrajectoryExecutor.submit` from any
thread and are validated at once (accepted or rejected, nothing moves on a
rejection); the loop picks an accepted goal up at the start of its next cycle.

Behaviour users of ROS's trajectory controller keep asking for:

- a goal starts from the current *desired* state, position and velocity, so
  there is no jump; a new goal during execution replaces the old one (which
  ends PREEMPTED) with a splice continuous in position and velocity;
- a partial goal moves only the joints it names; the others hold;
- cancel decelerates every joint to rest within ``stop_deceleration`` (all
  joints stop together) instead of freezing; so does an abort;
- path tolerances abort a goal that strays; goal tolerances with ``goal_time_s``
  decide success at the end; every goal gets exactly one terminal result;
- streamed references (:meth:`stream_reference`) are held, velocity zeroed,
  when none arrives within ``watchdog_timeout_s``.

This module is the controller: its parameters, its doors and its cycle. The
goals' life is :mod:`~jointctl.trajectory.goals`, what the joints follow
(splices, stops, block sampling) :mod:`~jointctl.trajectory.plan`, the
tolerance checks :mod:`~jointctl.trajectory.tolerances` and path timing
:func:`~jointctl.trajectory.timing.time_path`.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Mapping, Sequence
from operator import itemgetter

import numpy as np

from jointctl.control.controller import Controller
from jointctl.control.joint_controllers import JointPositionController
from jointctl.control.params import Params
from jointctl.errors import ConfigError, InvalidCommand
from jointctl.hardware.interface import POSITION, HardwareInterface
from jointctl.model.robot_model import RobotModel
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.goals import (GoalHandle, GoalQueue, GoalResult, GoalStatus, GoalTolerances,
                                       TrajectoryFeedback)
from jointctl.trajectory.messages import JointSpec, JointTrajectory
from jointctl.trajectory.plan import BLOCK_CYCLES, INTERPOLATIONS, Plan, Row, interleave
from jointctl.trajectory.timing import (PATH_MAX_ACCELERATION, PATH_MAX_JERK, PATH_START_S,
                                        PATH_VELOCITY_FRACTION, time_path)
from jointctl.trajectory.tolerances import goal_reached, path_violation, worst_joint
from jointctl.trajectory.validation import ValidatedTrajectory, joint_specs_from_model, validate_trajectory

__all__ = ["BLOCK_CYCLES", "INTERPOLATIONS", "GoalHandle", "GoalResult", "GoalStatus", "GoalTolerances",
           "TrajectoryExecutor", "TrajectoryFeedback"]


#: A goal handed whole to the hardware keeps its own times when it starts less than this late [s]
#: (its stamp a few cycles past: the controller absorbs it); later, what is left of it is timed from now.
LATE_START_S = 0.1


class TrajectoryExecutor(Controller):
    """Interpolates goals into references for one position controller per joint."""

    #: Whether a goal's end checks the joints' speeds against ``stopped_velocity_tolerance`` even without a goal
    #: tolerance (ros2_controllers' JointTrajectoryController does; ros_controllers' only with one).
    stopped_velocity_always = False

    def __init__(self, name: str, params: Params) -> None:
        super().__init__(name, params)
        joints = params.raw("joints")
        if not isinstance(joints, list) or not joints or not all(isinstance(j, str) for j in joints):
            raise params.error("must be a non-empty list of joint names", "joints", joints)
        self.joint_names = tuple(joints)
        controllers = params.raw("position_controllers", None)
        if controllers is None:  # it commands the joints' position interfaces itself
            self.joints = self.joint_names
        elif (not isinstance(controllers, list) or len(controllers) != len(joints)
                or not all(isinstance(c, str) for c in controllers)):
            raise params.error("must list one position controller per joint, in the order of joints",
                               "position_controllers", controllers)
        else:
            self.downstream = tuple(controllers)
        self.interpolation = params.string("interpolation", "cubic")
        if self.interpolation not in INTERPOLATIONS:
            raise params.error(f"must be one of {', '.join(INTERPOLATIONS)}", "interpolation",
                               self.interpolation)
        self.stream_rate_hz = params.number("stream_rate_hz", None, positive=True)
        self.velocity_feedforward = params.boolean("velocity_feedforward", True)
        self.feedback_rate_hz = params.number("feedback_rate_hz", 20.0, positive=True)
        #: Set by the user, ``goal_time_s`` also bounds how long hardware that executes goals itself may
        #: take beyond the goal's end; unset, such hardware takes as long as its own timing needs.
        self.goal_time_limited = params.has("goal_time_s")
        self.goal_time_s = params.number("goal_time_s", 0.5, minimum=0)
        self.stopped_velocity_tolerance = params.number("stopped_velocity_tolerance", 0.01, minimum=0)
        self.goal_tolerance = self._per_joint(params, "goal_tolerance", 0.0)
        self.path_tolerance = self._per_joint(params, "path_tolerance", 0.0)
        self.stop_deceleration = self._per_joint(params, "stop_deceleration", 5.0, positive=True)
        self.watchdog_timeout_s = params.number("watchdog_timeout_s", 0.5, positive=True)
        self.max_acceleration = self._per_joint(params, "max_acceleration", PATH_MAX_ACCELERATION, positive=True)
        self.max_jerk = self._per_joint(params, "max_jerk", PATH_MAX_JERK, positive=True)
        self.path_velocity_fraction = params.number("path_velocity_fraction", PATH_VELOCITY_FRACTION, positive=True)
        self.start_tolerance = params.number("start_tolerance", 1e-3, minimum=0)
        self.check_velocity_limits = params.boolean("check_velocity_limits", True)
        self.min_points = int(params.number("min_points", 1, positive=True))
        params.reject_unknown({"type"})
        self.goals = GoalQueue()
        self.latest_feedback: TrajectoryFeedback | None = None
        self._streamed: tuple | None = None
        self._lock = threading.Lock()
        self._running = False
        self._stream_period_s = None if self.stream_rate_hz is None else 1.0 / self.stream_rate_hz
        self._feedback_period_s = 1.0 / self.feedback_rate_hz
        self._zeros = [0.0] * len(self.joint_names)  # shared, never changed

    def _per_joint(self, params: Params, key: str, default: float, *, positive: bool = False) -> tuple:
        """A scalar for every joint, or a mapping joint -> value (missing joints get ``default``)."""
        value = params.raw(key, default)
        if isinstance(value, Mapping):
            child = Params(value, source=params.source, field=params.path(key))
            values = tuple(child.number(j, default, minimum=0, positive=positive) for j in self.joint_names)
            child.reject_unknown()
            return values
        scalar = params.number(key, default, minimum=0, positive=positive)
        return (scalar,) * len(self.joint_names)

    # The references in hand (those of the last cycle) are one row, joint by joint: (q0, v0, a0, q1, ...).
    @property
    def desired(self) -> list[float]:
        """Desired positions (the position references of the last cycle)."""
        return list(self._ref[0::3])

    @property
    def desired_velocity(self) -> list[float]:
        return list(self._ref[1::3])

    @property
    def desired_acceleration(self) -> list[float]:
        return list(self._ref[2::3])

    @property
    def active_goal(self) -> GoalHandle | None:
        """The goal being executed, if any."""
        return self.goals.active

    @property
    def goals_served(self) -> int:
        """How many goals became active."""
        return self.goals.served

    # -- controller contract -----------------------------------------------------------------
    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        if self.downstream:
            return tuple((c, "reference") for c in self.downstream)
        return tuple((j, POSITION) for j in self.joint_names)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        self._resolve(hardware, robot)
        if not self.downstream:  # the hardware's position command interfaces, written directly
            for k, joint in enumerate(self.joint_names):
                if POSITION not in hardware.command_interfaces(joint):
                    raise ConfigError("the joint has no position command interface (list position_controllers "
                                      "to command it through position controllers)", source=self.source,
                                      field=f"{self.field}.joints[{k}]", value=joint)
            n = len(hardware.joint_names)
            self._positions = hardware.command_buffer(POSITION)
            self._velocities, self._accelerations = [0.0] * n, [0.0] * n  # not sent: the hardware interpolates
            self._in_use = self.context.references if self.context is not None else None

    def _resolve(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        """The joints' hardware indices and their limits from the model."""
        self.hardware = hardware
        self.hw_index = [hardware.joint_index(j, source=self.source, field=f"{self.field}.joints")
                         for j in self.joint_names]
        # The executor's joints out of a hardware state list, as a tuple (one C call).
        if len(self.hw_index) > 1:
            self._of_joints: Callable[[Sequence[float]], tuple] = itemgetter(*self.hw_index)
        else:
            index = self.hw_index[0]
            self._of_joints = lambda values: (values[index],)
        self.specs: tuple[JointSpec, ...] = joint_specs_from_model(robot, self.joint_names)
        first = self.hw_index[0]
        consecutive = self.hw_index == list(range(first, first + len(self.hw_index)))
        self._span = slice(first, first + len(self.hw_index)) if consecutive else None

    def bind_downstream(self, controllers: dict[str, Controller]) -> None:
        if not self.downstream:  # commanding position interfaces: nothing to bind
            self.targets = ()
            return
        targets = []
        for joint, name in zip(self.joint_names, self.downstream):
            c = controllers[name]
            if not isinstance(c, JointPositionController) or c.joint != joint:
                raise ConfigError(f"must be a position controller of joint {joint!r}", source=self.source,
                                  field=f"{self.field}.position_controllers", value=name)
            targets.append(c)
        self.targets = tuple(targets)
        # The targets' reference interfaces (chained mode): the context's per-joint lists, written
        # in place; by slice when the executor's joints are consecutive hardware joints, in order.
        context = self.targets[0].context
        self._positions = context.reference_positions
        self._velocities = context.reference_velocities
        self._accelerations = context.reference_accelerations
        self._in_use = None  # the position controllers record what they use

    def start(self, time_s: float) -> None:
        self.hardware.read()
        self._ref: Row = interleave(self._of_joints(self.hardware.position), self._zeros, self._zeros)
        self._plan: Plan | None = None
        self._next_stream_s = time_s
        self._next_feedback_s = time_s
        self._supervise_at = time_s
        self._stream_deadline_s = math.inf
        self._write()
        self._running = True

    def stop(self, time_s: float) -> None:
        self._stop(time_s, "the trajectory controller stopped")

    def fail(self, time_s: float, reason: str) -> None:
        """Its chain failed: goals end ABORTED saying why; nothing is commanded downstream."""
        self._stop(time_s, f"the trajectory controller's chain failed: {reason}")

    def _stop(self, time_s: float, why: str) -> None:
        self._running = False
        self.goals.abort_all(why, time_s)
        self._plan = None
        self._ref = interleave(self._ref[0::3], self._zeros, self._zeros)
        self._write()  # the position controllers hold, without feed-forward

    # -- doors (any thread) ------------------------------------------------------------------
    def submit(self, trajectory: JointTrajectory, *, now_s: float | None = None,
               on_feedback: Callable[[TrajectoryFeedback], None] | None = None,
               on_done: Callable[[GoalResult], None] | None = None,
               tolerances: GoalTolerances | None = None) -> GoalHandle:
        """Validate ``trajectory`` against the current desired state and queue it.

        Raises :class:`InvalidTrajectory` (nothing moves) when it is refused; the
        handle then never becomes active. ``now_s`` is the loop time (default: the
        time of the last cycle). ``tolerances``: the goal's own (control_msgs'
        semantics, :class:`GoalTolerances`), else the controller's.
        """
        handle = self.goals.new(trajectory, on_feedback, on_done)
        now = self._last_time_s if now_s is None else now_s
        try:
            handle.path_tolerance, handle.goal_tolerance, handle.goal_time_s = self.tolerances_held_to(tolerances)
            self._check_running_and_points(trajectory)
            handle.validated = validate_trajectory(
                trajectory, self.specs, now_s=now, current_positions=list(self.desired),
                start_tolerance=self.start_tolerance, check_velocity=self.check_velocity_limits)
            if self.check_velocity_limits:
                self._check_time_left(handle.validated, now)
        except InvalidTrajectory as exc:
            self.goals.reject(handle, exc, now)
            raise
        self.goals.queue(handle, now)
        return handle

    def tolerances_held_to(self, tolerances: GoalTolerances | None
                           ) -> tuple[tuple[float, ...], tuple[float, ...], float]:
        """(path tolerances, goal tolerances per joint, goal time [s]) a goal is held to: the controller's, with the
        goal's own over them (0 keeps the controller's, negative: unchecked). InvalidTrajectory for a joint the
        controller does not have or a value that is not a number."""
        if tolerances is None:
            return tuple(self.path_tolerance), tuple(self.goal_tolerance), self.goal_time_s

        def merged(defaults, given: Mapping[str, float], what: str) -> tuple[float, ...]:
            for name, value in given.items():
                if name not in self.joint_names:
                    raise InvalidTrajectory(TrajectoryErrorCode.INVALID_JOINTS, "no joint of that name in this "
                                            f"controller ({', '.join(self.joint_names)})", field=what, joint=name)
                if not isinstance(value, (int, float)) or isinstance(value, bool) or math.isnan(value):
                    raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL, "must be a number", field=what,
                                            joint=name, value=value)
            return tuple(d if given.get(j, 0.0) == 0 else max(float(given[j]), 0.0)
                         for j, d in zip(self.joint_names, defaults))

        goal_time = tolerances.goal_time_s
        if not isinstance(goal_time, (int, float)) or not math.isfinite(goal_time) or goal_time < 0:
            raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL, "must be a finite time, not negative",
                                    field="goal_time_tolerance", value=goal_time)
        return (merged(self.path_tolerance, tolerances.path, "path_tolerance"),
                merged(self.goal_tolerance, tolerances.goal, "goal_tolerance"),
                float(goal_time) if goal_time > 0 else self.goal_time_s)

    def check_goal_shape(self, trajectory: JointTrajectory) -> None:
        """Check what does not depend on where the goal will start: joint names, point count and
        sizes, finite values, times, position and velocity limits, speeds between the goal's points.

        For servers that queue goals (the chapter's SimpleActionServers): a goal that can never run
        is refused on arrival; where it starts is checked by :meth:`submit` when its turn comes.
        Raises :class:`InvalidTrajectory`; the refused goal is kept in the goals' history as
        REJECTED, as :meth:`submit` keeps its refusals (the run's record lists both).
        """
        try:
            self._check_shape(trajectory)
        except InvalidTrajectory as exc:
            self.goals.reject(self.goals.new(trajectory), exc, self._last_time_s)
            raise

    def _check_shape(self, trajectory: JointTrajectory) -> None:
        self._check_running_and_points(trajectory)
        # Pretend the goal starts at its own first point: the start check and the first segment's
        # speed are then about the goal alone.
        start = list(self.desired)
        points = trajectory.points if isinstance(trajectory, JointTrajectory) else ()
        if points and isinstance(trajectory.joint_names, tuple):
            first = points[0].positions
            for name, q in zip(trajectory.joint_names, first if isinstance(first, tuple) else ()):
                if name in self.joint_names and isinstance(q, (int, float)) and math.isfinite(q):
                    start[self.joint_names.index(name)] = float(q)
        validate_trajectory(trajectory, self.specs, now_s=self._last_time_s, current_positions=start,
                            start_tolerance=math.inf, check_velocity=self.check_velocity_limits)

    def _check_running_and_points(self, trajectory: JointTrajectory) -> None:
        if not self._running:
            raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL, "the trajectory controller is not running",
                                    value=self.name)
        fault = self.hardware.fault
        if fault is not None:
            raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL, f"the hardware cannot be commanded: {fault}",
                                    value=self.name)
        points = trajectory.points if isinstance(trajectory, JointTrajectory) else ()
        if isinstance(points, tuple) and 0 < len(points) < self.min_points:
            raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL,
                                    f"needs at least {self.min_points} points", value=len(points))

    def _check_time_left(self, goal: ValidatedTrajectory, now_s: float) -> None:
        """A goal stamped in the past skips its past points: the first future point must still be
        reachable from the current desired position within the velocity limits."""
        times = goal.start_time_s + goal.times_s
        future = np.flatnonzero(times > now_s + 1e-9)
        if future.size == 0:
            return
        k = int(future[0])
        left = times[k] - now_s
        current = np.asarray(self.desired)[list(goal.joint_indices)]
        for j, col in enumerate(goal.joint_indices):
            speed = abs(goal.positions[k, j] - current[j]) / left
            limit = self.specs[col].max_velocity
            if speed > limit * (1 + 1e-9):
                raise InvalidTrajectory(
                    TrajectoryErrorCode.INVALID_GOAL,
                    f"from the current position it needs {speed:.4g}/s in the {left:.4g} s left before "
                    f"this point (limit {limit:g}/s)", point=k, joint=self.specs[col].name,
                    value=float(goal.positions[k, j]))

    def plan_path(self, path: Sequence[Sequence[float]], *, timing: str = "ruckig",
                  joint_names: Sequence[str] | None = None, start_s: float = PATH_START_S) -> JointTrajectory:
        """Time a path (positions without times) from the current desired pose with
        :func:`~jointctl.trajectory.timing.time_path`, within the joints' velocity limits scaled by
        ``path_velocity_fraction`` and (``timing="ruckig"``, the default) ``max_acceleration`` and
        ``max_jerk``; ``"chapter"`` is the chapter's rule. The current pose is the first point,
        ``start_s`` after submission (the chapter's clients prepend it too).
        """
        return time_path(self.joint_names, self.desired, path, [spec.max_velocity for spec in self.specs],
                         timing=timing, path_joints=joint_names, velocity_fraction=self.path_velocity_fraction,
                         max_acceleration=self.max_acceleration, max_jerk=self.max_jerk, start_s=start_s)

    def stream_reference(self, positions: Sequence[float], velocities: Sequence[float] | None = None) -> None:
        """Set the references directly (a streamed command); held if the stream stops."""
        n = len(self.joint_names)
        velocities = [0.0] * n if velocities is None else velocities
        if len(positions) != n or len(velocities) != n:
            raise InvalidCommand(f"needs {n} values, in the order {', '.join(self.joint_names)}",
                                 source=self.name, field="reference", value=list(positions))
        for k, (q, v) in enumerate(zip(positions, velocities)):
            spec = self.specs[k]
            for what, x in (("position", q), ("velocity", v)):
                if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                    raise InvalidCommand("must be a finite number", source=self.name,
                                         field=f"reference.{what}[{spec.name}]", value=x)
            if spec.lower is not None and not spec.lower <= q <= spec.upper:
                raise InvalidCommand(f"outside the joint's range [{spec.lower}, {spec.upper}]",
                                     source=self.name, field=f"reference.position[{spec.name}]", value=q)
            if abs(v) > spec.max_velocity:
                raise InvalidCommand(f"above the joint's velocity limit {spec.max_velocity:g}",
                                     source=self.name, field=f"reference.velocity[{spec.name}]", value=v)
        with self._lock:
            self._streamed = (tuple(map(float, positions)), tuple(map(float, velocities)))

    # -- the cycle ---------------------------------------------------------------------------
    _last_time_s = 0.0
    _executed_at_s = math.inf  # when the hardware finished executing the goal handed over

    def update(self, time_s: float, period_s: float) -> None:
        self._last_time_s = time_s
        goals = self.goals
        if goals.pending is not None:
            handle = goals.take_pending()
            if handle is not None:
                self._activate(handle, time_s, period_s)
        if self._streamed is not None:
            self._take_stream(time_s)
        goal = goals.active
        if self.hardware.fault is not None:  # e.g. the robot's state went stale, or it stops by itself
            self._hardware_fault(time_s)
            goal = None
        plan = self._plan
        if goal is not None and goal.cancel_requested and plan is not None and not plan.stopping:
            plan = self._plan = Plan.stop(self._state(), time_s - period_s, period_s,  # from last cycle's
                                          self.stop_deceleration)                      # desired state
            goals.end(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL, "canceled", time_s)
            goal = None
            self.hardware.stop_motion()
        if plan is not None:
            stream_period = self._stream_period_s
            if stream_period is None:
                self._ref = plan.at(time_s, period_s)
            elif time_s + 1e-9 >= self._next_stream_s:
                self._next_stream_s += stream_period
                self._ref = plan.at(time_s, period_s)
        elif time_s > self._stream_deadline_s:  # watchdog: the stream stopped
            self._ref = interleave(self._ref[0::3], self._zeros, self._zeros)
            self._stream_deadline_s = math.inf
        self._write()
        if goal is not None and time_s + 1e-9 >= self._supervise_at:
            self._supervise(time_s, goal, plan)

    def _hardware_fault(self, time_s: float) -> None:
        """The hardware cannot be commanded (its ``fault``): goals end ABORTED saying why, and the
        references follow the measured position while the fault lasts, so nothing jumps when it
        clears (a robot stopping by itself is followed to where it comes to rest)."""
        if self.goals.active is not None or self.goals.pending is not None:
            self.goals.abort_all(f"the hardware cannot be commanded: {self.hardware.fault}", time_s)
        self._plan = None
        self._ref = interleave(self._of_joints(self.hardware.position), self._zeros, self._zeros)

    def _write(self) -> None:
        """The references in hand into the position controllers' reference interfaces. They come
        from validated goals and streams through polynomials: finite by construction."""
        ref = self._ref
        positions = ref[0::3]
        if self.velocity_feedforward:
            velocities, accelerations = ref[1::3], ref[2::3]
        else:
            velocities = accelerations = self._zeros
        span = self._span
        if span is not None:
            self._positions[span] = positions
            self._velocities[span] = velocities
            self._accelerations[span] = accelerations
            if self._in_use is not None:  # commanding position interfaces: the trace's reference
                self._in_use[span] = positions
            return
        for i, q, v, a in zip(self.hw_index, positions, velocities, accelerations):
            self._positions[i], self._velocities[i], self._accelerations[i] = q, v, a
        if self._in_use is not None:
            for i, q in zip(self.hw_index, positions):
                self._in_use[i] = q

    def _state(self) -> tuple[Row, Row, Row]:
        ref = self._ref
        return ref[0::3], ref[1::3], ref[2::3]

    def _activate(self, handle: GoalHandle, time_s: float, period_s: float) -> None:
        self.goals.activate(handle, time_s)
        self._streamed = None
        self._stream_deadline_s = math.inf
        # The desired state in hand is last cycle's: the splice continues from it, at its time.
        self._plan = Plan.splice(handle.validated, self._state(), time_s - period_s, time_s,
                                 interpolation=self.interpolation, stop_deceleration=self.stop_deceleration)
        self._next_stream_s = time_s
        self._next_feedback_s = time_s
        self._supervise_at = time_s
        if self._hands_over():
            self._hand_over(handle, time_s, period_s)

    def _hands_over(self) -> bool:
        """Whether goals go whole to the hardware (it interpolates them itself)."""
        return not self.downstream and self.hardware.takes_trajectories

    def _hand_over(self, handle: GoalHandle, time_s: float, period_s: float) -> None:
        """Hand the goal to hardware that executes whole trajectories: its own points (with their own
        times; of a goal stamped in the past, those still to come, from now), or, when the hardware asks
        for a sampling period, the goal as
        planned from this cycle sampled every period and at its end. The executor runs its own copy
        of the plan as usual, for feedback and the result."""
        hw = self.hardware
        step = hw.trajectory_sample_period_s
        goal = handle.validated
        hw_index = [self.hw_index[i] for i in goal.joint_indices]
        if step is None:
            offset = goal.start_time_s - time_s
            if offset > -LATE_START_S:  # the goal's own times, as ROS-I's client sends them
                keep = list(range(len(goal.times_s)))
                times = [float(t) for t in goal.times_s]
            else:  # stamped well in the past: what is left of it, from now
                keep = [k for k, t in enumerate(goal.times_s) if offset + float(t) > 1e-9] or [len(goal.times_s) - 1]
                times = [max(offset + float(goal.times_s[k]), period_s) for k in keep]
            rows = lambda array: None if array is None else [array[k] for k in keep]  # noqa: E731
            hw.execute_trajectory(hw_index, times, rows(goal.positions), rows(goal.velocities),
                                  rows(goal.accelerations))
            return
        plan = Plan.splice(goal, self._state(), time_s - period_s, time_s,
                           interpolation=self.interpolation, stop_deceleration=self.stop_deceleration)
        count = max(1, math.ceil((plan.end_s - time_s) / step - 1e-9))
        times = [time_s + k * step for k in range(1, count)] + [plan.end_s]
        samples = [plan.at(t, step) for t in times]
        hw.execute_trajectory(self.hw_index, [t - time_s for t in times], [row[0::3] for row in samples],
                              [row[1::3] for row in samples], [row[2::3] for row in samples])

    def _take_stream(self, time_s: float) -> None:
        with self._lock:
            streamed, self._streamed = self._streamed, None
        if streamed is None:
            return
        positions, velocities = streamed
        self.goals.end(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL, "replaced by streamed references",
                       time_s)
        self._plan = None
        self._ref = interleave(positions, velocities, self._zeros)
        self._stream_deadline_s = time_s + self.watchdog_timeout_s

    def _supervise(self, time_s: float, goal: GoalHandle, plan: Plan | None) -> None:
        """Feedback when due, then the tolerances: a goal straying from its path is aborted with a
        stop; at its end it succeeds, or is aborted ``goal_time_s`` later."""
        hw = self.hardware
        actual = self._of_joints(hw.position)
        desired = self._ref[0::3]
        if time_s + 1e-9 >= self._next_feedback_s:
            self._next_feedback_s += self._feedback_period_s
            feedback = TrajectoryFeedback(time_s, self.joint_names, desired, self._ref[1::3], actual,
                                          self._of_joints(hw.velocity))
            self.latest_feedback = feedback
            if goal.on_feedback is not None:
                goal.on_feedback(feedback)
        if plan is None:
            return
        if self._hands_over():
            self._supervise_hardware(time_s, goal, plan, actual, desired)
            return
        # Next cycle that needs this: every cycle when checking the path, else feedback or the end.
        checks_path = any(tol > 0 for tol in goal.path_tolerance)
        self._supervise_at = -math.inf if checks_path else min(self._next_feedback_s, plan.end_s)
        if time_s < plan.end_s and checks_path:
            k = path_violation(desired, actual, goal.path_tolerance)
            if k is not None:
                self._plan = Plan.stop(self._state(), time_s, 0.0,  # this cycle's desired state, at its time
                                       self.stop_deceleration)
                self.hardware.stop_motion()
                self.goals.end(GoalStatus.ABORTED, TrajectoryErrorCode.PATH_TOLERANCE_VIOLATED,
                               f"joint {self.joint_names[k]!r} is {abs(desired[k] - actual[k]):.4g} from "
                               f"its path (tolerance {goal.path_tolerance[k]})", time_s)
                return
        if time_s + 1e-9 < plan.end_s:
            return
        reached = goal_reached(desired, actual, self._of_joints(hw.velocity), goal.goal_tolerance,
                               self.stopped_velocity_tolerance, velocity_always=self.stopped_velocity_always)
        if reached and hw.in_motion is not True:  # and the hardware, if it says, says at rest
            self.goals.end(GoalStatus.SUCCEEDED, TrajectoryErrorCode.SUCCESSFUL, "", time_s)
        elif reached and time_s > plan.end_s + goal.goal_time_s:
            self.goals.end(GoalStatus.ABORTED, TrajectoryErrorCode.GOAL_TOLERANCE_VIOLATED,
                           f"the hardware still reports the robot in motion {goal.goal_time_s} s after the end",
                           time_s)
        elif time_s > plan.end_s + goal.goal_time_s:
            worst = worst_joint(desired, actual)
            self.goals.end(GoalStatus.ABORTED, TrajectoryErrorCode.GOAL_TOLERANCE_VIOLATED,
                           f"joint {self.joint_names[worst]!r} ended "
                           f"{abs(desired[worst] - actual[worst]):.4g} from its goal "
                           f"{goal.goal_time_s} s after the end", time_s)

    def _supervise_hardware(self, time_s: float, goal: GoalHandle, plan: Plan, actual: Row,
                            desired: Row) -> None:
        """A goal the hardware executes by its own timing (a controller's speed fractions may make it
        later than planned): it succeeds once its end time has come and the hardware has executed it,
        the joints are within the goal tolerance of its end and the hardware says the robot is at rest;
        it is aborted when the joints are not there ``goal_time_s`` after that, or, when the user set
        ``goal_time_s``, when the hardware still executes it that long after the goal's end. No path
        tolerance: the controller's timing, not the plan's, is the path's (as ROS-I's action server).
        Faults (a refused point, a lost connection, stale state) abort it in :meth:`update`."""
        hw = self.hardware
        if time_s + 1e-9 < plan.end_s:  # nothing to decide before the goal's end: feedback only
            self._executed_at_s = math.inf
            self._supervise_at = min(self._next_feedback_s, plan.end_s)
            return
        self._supervise_at = -math.inf  # from its end, every cycle: the hardware's word may come any time
        if hw.executing:
            self._executed_at_s = math.inf
            if self.goal_time_limited and time_s > plan.end_s + goal.goal_time_s:
                self.hardware.stop_motion()
                self.goals.end(GoalStatus.ABORTED, TrajectoryErrorCode.GOAL_TOLERANCE_VIOLATED,
                               f"the controller still executes the goal {goal.goal_time_s} s after its end "
                               f"(goal_time_s)", time_s)
            return
        self._executed_at_s = min(self._executed_at_s, time_s)
        reached = goal_reached(desired, actual, self._of_joints(hw.velocity), goal.goal_tolerance,
                               self.stopped_velocity_tolerance, velocity_always=self.stopped_velocity_always)
        if reached and hw.in_motion is not True:
            self.goals.end(GoalStatus.SUCCEEDED, TrajectoryErrorCode.SUCCESSFUL, "", time_s)
        elif time_s > self._executed_at_s + goal.goal_time_s:
            worst = worst_joint(desired, actual)
            self.goals.end(GoalStatus.ABORTED, TrajectoryErrorCode.GOAL_TOLERANCE_VIOLATED,
                           f"joint {self.joint_names[worst]!r} ended {abs(desired[worst] - actual[worst]):.4g} "
                           f"from its goal {goal.goal_time_s} s after the controller executed it", time_s)

"""Execute joint trajectories inside the control loop, like ros_control's joint_trajectory_controller.

``trajectory_controllers/JointTrajectoryExecutor`` is a chained controller: it
feeds position, velocity and acceleration references to one position
controller per joint, every cycle (or at ``stream_rate_hz``, holding in
between, as the chapter's action servers stream to their position
controllers). Goals arrive through :meth:`TrajectoryExecutor.submit` from any
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
"""

from __future__ import annotations

import itertools
import math
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from jointctl.control.controller import Controller, register_controller
from jointctl.control.joint_controllers import JointPositionController
from jointctl.control.params import Params
from jointctl.errors import ConfigError, InvalidCommand
from jointctl.hardware.interface import HardwareInterface
from jointctl.model.robot_model import RobotModel
from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.interpolation import Interpolant, build_interpolant
from jointctl.trajectory.messages import JointSpec, JointTrajectory
from jointctl.trajectory.timing import chapter_timing, ruckig_timing
from jointctl.trajectory.validation import ValidatedTrajectory, joint_specs_from_model, validate_trajectory

BLOCK_CYCLES = 256  # references are sampled this many cycles at a time (vectorised)
INTERPOLATIONS = ("linear", "cubic", "quintic", "auto")


class GoalStatus(Enum):
    PENDING = "pending"
    ACTIVE = "active"
    SUCCEEDED = "succeeded"
    ABORTED = "aborted"
    PREEMPTED = "preempted"
    REJECTED = "rejected"


@dataclass(frozen=True)
class GoalResult:
    """The terminal result of a goal: control_msgs/FollowJointTrajectoryResult semantics."""

    status: GoalStatus
    error_code: TrajectoryErrorCode
    error_string: str
    time_s: float


@dataclass(frozen=True)
class TrajectoryFeedback:
    """Desired and actual state of the executor's joints at ``time_s`` (SI units)."""

    time_s: float
    joint_names: tuple[str, ...]
    desired_positions: tuple[float, ...]
    desired_velocities: tuple[float, ...]
    actual_positions: tuple[float, ...]
    actual_velocities: tuple[float, ...]

    @property
    def errors(self) -> tuple[float, ...]:
        return tuple(d - a for d, a in zip(self.desired_positions, self.actual_positions))


class GoalHandle:
    """One goal's life. ``wait()`` blocks another thread until the terminal result."""

    def __init__(self, goal_id: int, trajectory: JointTrajectory,
                 on_feedback: Callable[[TrajectoryFeedback], None] | None = None,
                 on_done: Callable[[GoalResult], None] | None = None) -> None:
        self.id = goal_id
        self.trajectory = trajectory
        self.on_feedback = on_feedback
        self.on_done = on_done
        self.status = GoalStatus.PENDING
        self.result: GoalResult | None = None
        self.validated: ValidatedTrajectory | None = None
        self.cancel_requested = False
        self._done = threading.Event()
        self._finish_lock = threading.Lock()

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def cancel(self) -> None:
        """Ask for a controlled stop (thread-safe); the goal then ends PREEMPTED."""
        self.cancel_requested = True

    def wait(self, timeout_s: float | None = None) -> GoalResult | None:
        self._done.wait(timeout_s)
        return self.result

    def _finish(self, status: GoalStatus, code: TrajectoryErrorCode, text: str, time_s: float) -> bool:
        """Record the terminal result once; later calls are ignored (returns False)."""
        with self._finish_lock:
            if self.result is not None:
                return False
            self.status = status
            self.result = GoalResult(status, code, text, time_s)
        self._done.set()
        if self.on_done is not None:
            self.on_done(self.result)
        return True


@register_controller("trajectory_controllers/JointTrajectoryExecutor")
class TrajectoryExecutor(Controller):
    """Interpolates goals into references for one position controller per joint."""

    def __init__(self, name: str, params: Params) -> None:
        super().__init__(name, params)
        joints = params.raw("joints")
        if not isinstance(joints, list) or not joints or not all(isinstance(j, str) for j in joints):
            raise params.error("must be a non-empty list of joint names", "joints", joints)
        self.joint_names = tuple(joints)
        controllers = params.raw("position_controllers")
        if (not isinstance(controllers, list) or len(controllers) != len(joints)
                or not all(isinstance(c, str) for c in controllers)):
            raise params.error("must list one position controller per joint, in the order of joints",
                               "position_controllers", controllers)
        self.downstream = tuple(controllers)
        self.interpolation = params.string("interpolation", "cubic")
        if self.interpolation not in INTERPOLATIONS:
            raise params.error(f"must be one of {', '.join(INTERPOLATIONS)}", "interpolation",
                               self.interpolation)
        self.stream_rate_hz = params.number("stream_rate_hz", None, positive=True)
        self.velocity_feedforward = params.boolean("velocity_feedforward", True)
        self.feedback_rate_hz = params.number("feedback_rate_hz", 20.0, positive=True)
        self.goal_time_s = params.number("goal_time_s", 0.5, minimum=0)
        self.stopped_velocity_tolerance = params.number("stopped_velocity_tolerance", 0.01, minimum=0)
        self.goal_tolerance = self._per_joint(params, "goal_tolerance", 0.0)
        self.path_tolerance = self._per_joint(params, "path_tolerance", 0.0)
        self.stop_deceleration = self._per_joint(params, "stop_deceleration", 5.0, positive=True)
        self.watchdog_timeout_s = params.number("watchdog_timeout_s", 0.5, positive=True)
        self.max_acceleration = self._per_joint(params, "max_acceleration", 2.0, positive=True)
        self.max_jerk = self._per_joint(params, "max_jerk", 20.0, positive=True)
        self.path_velocity_fraction = params.number("path_velocity_fraction", 0.5, positive=True)
        self.start_tolerance = params.number("start_tolerance", 1e-3, minimum=0)
        self.check_velocity_limits = params.boolean("check_velocity_limits", True)
        self.min_points = int(params.number("min_points", 1, positive=True))
        self._checks_path = any(tol > 0 for tol in self.path_tolerance)
        params.reject_unknown({"type"})
        self.active_goal: GoalHandle | None = None
        self.goals_served = 0
        self.latest_feedback: TrajectoryFeedback | None = None
        self._pending: GoalHandle | None = None
        self._streamed: tuple | None = None
        self._lock = threading.Lock()
        self._goal_ids = itertools.count(1)
        self._running = False

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

    # -- controller contract -----------------------------------------------------------------
    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        return tuple((c, "command") for c in self.downstream)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        self.hardware = hardware
        self.hw_index = [hardware.joint_index(j, source=self.source, field=f"{self.field}.joints")
                         for j in self.joint_names]
        self.specs: tuple[JointSpec, ...] = joint_specs_from_model(robot, self.joint_names)

    def bind_downstream(self, controllers: dict[str, Controller]) -> None:
        targets = []
        for joint, name in zip(self.joint_names, self.downstream):
            c = controllers[name]
            if not isinstance(c, JointPositionController) or c.joint != joint:
                raise ConfigError(f"must be a position controller of joint {joint!r}", source=self.source,
                                  field=f"{self.field}.position_controllers", value=name)
            targets.append(c)
        self.targets = tuple(targets)

    def start(self, time_s: float) -> None:
        self.hardware.read()
        n = len(self.joint_names)
        self.desired = [self.hardware.position[i] for i in self.hw_index]
        self.desired_velocity = [0.0] * n
        self.desired_acceleration = [0.0] * n
        self._plan: _Plan | None = None
        self._next_stream_s = time_s
        self._next_feedback_s = time_s
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
        for handle in (self._pending, self.active_goal):
            if handle is not None:
                handle._finish(GoalStatus.ABORTED, TrajectoryErrorCode.INVALID_GOAL, why, time_s)
        self._pending = self.active_goal = None
        self._plan = None
        for target, q in zip(self.targets, self.desired):
            target.set_command(q, 0.0, 0.0)  # the position controllers hold, without feed-forward

    # -- doors (any thread) ------------------------------------------------------------------
    def submit(self, trajectory: JointTrajectory, *, now_s: float | None = None,
               on_feedback: Callable[[TrajectoryFeedback], None] | None = None,
               on_done: Callable[[GoalResult], None] | None = None) -> GoalHandle:
        """Validate ``trajectory`` against the current desired state and queue it.

        Raises :class:`InvalidTrajectory` (nothing moves) when it is refused; the
        handle then never becomes active. ``now_s`` is the loop time (default: the
        time of the last cycle).
        """
        handle = GoalHandle(next(self._goal_ids), trajectory, on_feedback, on_done)
        now = self._last_time_s if now_s is None else now_s
        try:
            if not self._running:
                raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL, "the trajectory controller is not running",
                                        value=self.name)
            points = trajectory.points if isinstance(trajectory, JointTrajectory) else ()
            if isinstance(points, tuple) and 0 < len(points) < self.min_points:
                raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL,
                                        f"needs at least {self.min_points} points", value=len(points))
            handle.validated = validate_trajectory(
                trajectory, self.specs, now_s=now, current_positions=list(self.desired),
                start_tolerance=self.start_tolerance, check_velocity=self.check_velocity_limits)
            if self.check_velocity_limits:
                self._check_time_left(handle.validated, now)
        except InvalidTrajectory as exc:
            handle._finish(GoalStatus.REJECTED, exc.error_code, str(exc), now)
            raise
        with self._lock:
            previous, self._pending = self._pending, handle
        if previous is not None:
            previous._finish(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL,
                             f"replaced by goal {handle.id} before it started", now)
        return handle

    def check_goal_shape(self, trajectory: JointTrajectory) -> None:
        """Check what does not depend on where the goal will start: joint names, point count and
        sizes, finite values, times, position and velocity limits, speeds between the goal's points.

        For servers that queue goals (the chapter's SimpleActionServers): a goal that can never run
        is refused on arrival; where it starts is checked by :meth:`submit` when its turn comes.
        Raises :class:`InvalidTrajectory`.
        """
        if not self._running:
            raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL, "the trajectory controller is not running",
                                    value=self.name)
        points = trajectory.points if isinstance(trajectory, JointTrajectory) else ()
        if isinstance(points, tuple) and 0 < len(points) < self.min_points:
            raise InvalidTrajectory(TrajectoryErrorCode.INVALID_GOAL,
                                    f"needs at least {self.min_points} points", value=len(points))
        # Pretend the goal starts at its own first point: the start check and the first segment's
        # speed are then about the goal alone.
        start = list(self.desired)
        if points and isinstance(trajectory.joint_names, tuple):
            first = points[0].positions
            for name, q in zip(trajectory.joint_names, first if isinstance(first, tuple) else ()):
                if name in self.joint_names and isinstance(q, (int, float)) and math.isfinite(q):
                    start[self.joint_names.index(name)] = float(q)
        validate_trajectory(trajectory, self.specs, now_s=self._last_time_s, current_positions=start,
                            start_tolerance=math.inf, check_velocity=self.check_velocity_limits)

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
                  joint_names: Sequence[str] | None = None, start_s: float = 0.1) -> JointTrajectory:
        """Time a path (positions without times) from the current desired pose.

        ``timing="ruckig"`` (the default): jerk-limited and time-optimal per segment within the
        joints' velocity limits (scaled by ``path_velocity_fraction``), ``max_acceleration`` and
        ``max_jerk``; ``"chapter"``: the chapter's rule (slowest joint at
        ``path_velocity_fraction`` of its velocity limit, at least 20 ms a segment), positions only.
        The current pose is the first point, ``start_s`` after submission (the chapter's clients
        prepend it too).
        """
        names = tuple(joint_names or self.joint_names)
        columns = [self.joint_names.index(n) for n in names]
        path = np.asarray(path, dtype=float).reshape(-1, len(names))
        current = np.asarray(self.desired)[columns]
        full = np.vstack((current, path))
        vmax = np.array([self.specs[c].max_velocity for c in columns]) * self.path_velocity_fraction
        if timing == "chapter":
            times = chapter_timing(full, vmax, velocity_fraction=1.0)
            return JointTrajectory.from_arrays(names, times + start_s, full)
        if timing != "ruckig":
            raise ValueError(f"timing must be 'ruckig' or 'chapter', got {timing!r}")
        amax = np.array([self.max_acceleration[c] for c in columns])
        jmax = np.array([self.max_jerk[c] for c in columns])
        times, positions, velocities, accelerations = ruckig_timing(full, vmax, amax, jmax)
        return JointTrajectory.from_arrays(names, times + start_s, positions, velocities, accelerations)

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

    def update(self, time_s: float, period_s: float) -> None:
        self._last_time_s = time_s
        if self._pending is not None:
            with self._lock:
                handle, self._pending = self._pending, None
            self._activate(handle, time_s, period_s)
        if self._streamed is not None:
            self._take_stream(time_s, period_s)
        goal = self.active_goal
        if goal is not None and goal.cancel_requested and self._plan is not None and not self._plan.stopping:
            self._plan = _Plan.stop(time_s - period_s, period_s, self)  # from last cycle's desired state
            if goal._finish(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL, "canceled", time_s):
                self.active_goal = None
        plan = self._plan
        if plan is not None and (self.stream_rate_hz is None or time_s + 1e-9 >= self._next_stream_s):
            if self.stream_rate_hz is not None:
                self._next_stream_s += 1.0 / self.stream_rate_hz
            plan.sample_into(time_s, period_s, self)
        elif time_s > self._stream_deadline_s:  # watchdog: the stream stopped
            self.desired_velocity = [0.0] * len(self.desired)
            self.desired_acceleration = [0.0] * len(self.desired)
            self._stream_deadline_s = math.inf
        self._write()
        if self.active_goal is not None:
            self._supervise(time_s, plan)

    def _write(self) -> None:
        # References come from validated goals through polynomials: finite by construction.
        if self.velocity_feedforward:
            for target, q, v, a in zip(self.targets, self.desired, self.desired_velocity,
                                       self.desired_acceleration):
                target.set_reference(q, v, a)
        else:
            for target, q in zip(self.targets, self.desired):
                target.set_reference(q, 0.0, 0.0)

    def _activate(self, handle: GoalHandle, time_s: float, period_s: float) -> None:
        previous = self.active_goal
        if previous is not None:
            previous._finish(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL,
                             f"replaced by goal {handle.id}", time_s)
        self._streamed = None
        self._stream_deadline_s = math.inf
        # The desired state in hand is last cycle's: the splice continues from it, at its time.
        self._plan = _Plan.splice(handle.validated, time_s - period_s, time_s, self)
        self.active_goal = handle
        self.goals_served += 1
        handle.status = GoalStatus.ACTIVE
        self._next_stream_s = time_s
        self._next_feedback_s = time_s

    def _take_stream(self, time_s: float, period_s: float) -> None:
        with self._lock:
            streamed, self._streamed = self._streamed, None
        if streamed is None:
            return
        positions, velocities = streamed
        if self.active_goal is not None:
            self.active_goal._finish(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL,
                                     "replaced by streamed references", time_s)
            self.active_goal = None
        self._plan = None
        self.desired = list(positions)
        self.desired_velocity = list(velocities)
        self.desired_acceleration = [0.0] * len(positions)
        self._stream_deadline_s = time_s + self.watchdog_timeout_s

    def _supervise(self, time_s: float, plan: _Plan | None) -> None:
        goal = self.active_goal
        hw = self.hardware
        if plan is not None and time_s + 1e-9 < plan.end_s and time_s + 1e-9 < self._next_feedback_s \
                and not self._checks_path:
            return  # nothing to report or check this cycle
        actual = [hw.position[i] for i in self.hw_index]
        if time_s + 1e-9 >= self._next_feedback_s:
            self._next_feedback_s += 1.0 / self.feedback_rate_hz
            feedback = TrajectoryFeedback(time_s, self.joint_names, tuple(self.desired),
                                          tuple(self.desired_velocity), tuple(actual),
                                          tuple(hw.velocity[i] for i in self.hw_index))
            self.latest_feedback = feedback
            if goal.on_feedback is not None:
                goal.on_feedback(feedback)
        if plan is None:
            return
        for k, (d, a, tol) in enumerate(zip(self.desired, actual, self.path_tolerance)):
            if tol > 0 and abs(d - a) > tol and time_s < plan.end_s:
                self._plan = _Plan.stop(time_s, 0.0, self)  # this cycle's desired state, at its time
                goal._finish(GoalStatus.ABORTED, TrajectoryErrorCode.PATH_TOLERANCE_VIOLATED,
                             f"joint {self.joint_names[k]!r} is {abs(d - a):.4g} from its path "
                             f"(tolerance {tol})", time_s)
                self.active_goal = None
                return
        if time_s + 1e-9 < plan.end_s:
            return
        within = all(tol <= 0 or abs(d - a) <= tol
                     for d, a, tol in zip(self.desired, actual, self.goal_tolerance))
        checked = any(tol > 0 for tol in self.goal_tolerance)
        stopped = not checked or all(abs(hw.velocity[i]) <= self.stopped_velocity_tolerance
                                     for i in self.hw_index)
        if within and stopped:
            goal._finish(GoalStatus.SUCCEEDED, TrajectoryErrorCode.SUCCESSFUL, "", time_s)
            self.active_goal = None
        elif time_s > plan.end_s + self.goal_time_s:
            worst = max(range(len(actual)), key=lambda k: abs(self.desired[k] - actual[k]))
            goal._finish(GoalStatus.ABORTED, TrajectoryErrorCode.GOAL_TOLERANCE_VIOLATED,
                         f"joint {self.joint_names[worst]!r} ended "
                         f"{abs(self.desired[worst] - actual[worst]):.4g} from its goal "
                         f"{self.goal_time_s} s after the end", time_s)
            self.active_goal = None


class _Plan:
    """References over time for an executor's joints: one or more interpolants, each over some
    of the joints (``parts`` of (interpolant, columns)), sampled a block of cycles at a time."""

    def __init__(self, parts: list[tuple[Interpolant, np.ndarray]], start_s: float, *,
                 stopping: bool = False) -> None:
        self.parts = parts
        self.start_s = start_s
        self.end_s = start_s + max(interp.duration_s for interp, _ in parts)
        self.stopping = stopping
        self._block_t0 = start_s
        self._rows: list = []  # empty: the first sample_into fills a block

    @classmethod
    def splice(cls, goal: ValidatedTrajectory, start_s: float, time_s: float,
               executor: TrajectoryExecutor) -> _Plan:
        """From the executor's desired state (that of loop time ``start_s``) into the goal's points
        after ``time_s``; joints the goal does not name come to rest (within their stop
        deceleration) and hold."""
        columns = np.asarray(goal.joint_indices, dtype=int)
        times = goal.start_time_s + goal.times_s
        future = times > time_s + 1e-9
        if not future.any():  # the whole goal lies in the past: go to its last point now
            future[-1] = True
            times = times.copy()
            times[-1] = time_s + 1e-3
        q0 = np.asarray(executor.desired)[columns]
        v0 = np.asarray(executor.desired_velocity)[columns]
        a0 = np.asarray(executor.desired_acceleration)[columns]
        knot_times = np.concatenate(([0.0], times[future] - start_s))
        positions = np.vstack((q0, goal.positions[future]))
        kind = executor.interpolation
        given_v = goal.velocities is not None
        given_a = goal.accelerations is not None and given_v
        if kind == "auto":
            kind = "quintic" if given_a else "cubic" if given_v else "linear"
        if kind == "quintic" and not given_a:
            kind = "cubic"
        if kind == "linear":
            interp = build_interpolant(knot_times, positions, kind="linear")
        elif kind == "cubic" and not given_v:
            interp = build_interpolant(knot_times, positions, kind="spline", start_velocity=v0)
        else:
            velocities = np.vstack((v0, goal.velocities[future]))
            accelerations = np.vstack((a0, goal.accelerations[future])) if kind == "quintic" else None
            interp = build_interpolant(knot_times, positions, velocities, accelerations, kind=kind)
        parts = [(interp, columns)]
        omitted = np.setdiff1d(np.arange(len(executor.desired)), columns)
        if omitted.size:
            parts.append(_stop_part(executor, omitted))
        return cls(parts, start_s)

    @classmethod
    def stop(cls, start_s: float, period_s: float, executor: TrajectoryExecutor) -> _Plan:
        """Every joint decelerates to rest, all together, from the desired state of ``start_s``."""
        return cls([_stop_part(executor, np.arange(len(executor.desired)), period_s)], start_s,
                   stopping=True)

    def sample_into(self, time_s: float, period_s: float, executor: TrajectoryExecutor) -> None:
        k = round((time_s - self._block_t0) / period_s) if period_s > 0 else -1
        if not 0 <= k < BLOCK_CYCLES or not self._rows:
            taus = (time_s - self.start_s) + period_s * np.arange(BLOCK_CYCLES)
            self._rows = []
            n = len(executor.desired)
            for interp, columns in self.parts:
                pos, vel, acc = interp.sample(taus)
                every = len(columns) == n and bool(np.all(columns == np.arange(n)))
                self._rows.append((None if every else columns.tolist(), pos.tolist(), vel.tolist(),
                                   acc.tolist()))
            self._block_t0 = time_s
            k = 0
        desired, velocity, acceleration = executor.desired, executor.desired_velocity, executor.desired_acceleration
        for columns, pos, vel, acc in self._rows:
            if columns is None:  # every joint, in order
                desired[:], velocity[:], acceleration[:] = pos[k], vel[k], acc[k]
                continue
            q, v, a = pos[k], vel[k], acc[k]
            for j, col in enumerate(columns):
                desired[col], velocity[col], acceleration[col] = q[j], v[j], a[j]


def _stop_part(executor: TrajectoryExecutor, columns: np.ndarray,
               period_s: float = 0.0) -> tuple[Interpolant, np.ndarray]:
    """The given joints decelerate uniformly to rest together, each within its stop deceleration:
    q0 + v0·τ - v0·τ²/(2T) up to T = max |v0|/a_max, then hold."""
    q0 = np.asarray(executor.desired)[columns]
    v0 = np.asarray(executor.desired_velocity)[columns]
    decel = np.asarray(executor.stop_deceleration)[columns]
    duration = max(float(np.max(np.abs(v0) / decel)), period_s, 1e-3)
    positions = np.vstack((q0, q0 + v0 * duration / 2))
    velocities = np.vstack((v0, np.zeros_like(v0)))
    return build_interpolant(np.array([0.0, duration]), positions, velocities, kind="cubic"), columns

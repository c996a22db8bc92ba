"""The life of trajectory goals: control_msgs/FollowJointTrajectory semantics, without ROS.

A goal is submitted (validated at once: REJECTED, or queued PENDING), becomes ACTIVE at the
start of the next cycle, and ends exactly once: SUCCEEDED, ABORTED (tolerances, a failure,
a stop) or PREEMPTED (canceled, or replaced by a newer goal or by streamed references).
:class:`GoalQueue` holds the executor's one pending and one active goal and enforces that
every goal gets exactly one terminal result; :class:`GoalHandle` is what the submitter keeps.
Doors (``submit``, ``cancel``) may be used from any thread; the rest runs in the loop.
"""

from __future__ import annotations

import itertools
import threading
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import Enum

from jointctl.trajectory.errors import InvalidTrajectory, TrajectoryErrorCode
from jointctl.trajectory.messages import JointTrajectory
from jointctl.trajectory.validation import ValidatedTrajectory

#: How many goals an executor remembers for the run's record (a served robot may get many).
HISTORY_LENGTH = 10_000


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


@dataclass(frozen=True)
class GoalTolerances:
    """A goal's own tolerances, as control_msgs/FollowJointTrajectory's goal carries them: per joint name a position
    tolerance [m or rad] along the path (``path``) and at the end (``goal``), and the time the joints may take after
    the goal's end to get there (``goal_time_s`` [s]). For each, 0 (or absent) keeps the controller's own, a negative
    value takes the check away ("erased"), a positive one replaces it."""

    path: Mapping[str, float] = field(default_factory=dict)
    goal: Mapping[str, float] = field(default_factory=dict)
    goal_time_s: float = 0.0


class GoalHandle:
    """One goal's life. ``wait()`` blocks another thread until the terminal result. ``path_tolerance``,
    ``goal_tolerance`` (per joint of the executor, 0: unchecked) and ``goal_time_s`` are the ones it is held to
    (the executor's, or the goal's own: :class:`GoalTolerances`), set when it is submitted."""

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
        self.path_tolerance: tuple[float, ...] = ()
        self.goal_tolerance: tuple[float, ...] = ()
        self.goal_time_s = 0.0
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


class GoalQueue:
    """An executor's goals: at most one pending (submitted, not yet picked up by the loop) and one
    active. A newer goal preempts the one it replaces; every goal ends exactly once."""

    def __init__(self) -> None:
        self.pending: GoalHandle | None = None
        self.active: GoalHandle | None = None
        #: Goals that became active (the chapter's servers report it).
        self.served = 0
        #: Every goal submitted, rejected ones too, the last HISTORY_LENGTH (a run's record lists them).
        self.history: deque[GoalHandle] = deque(maxlen=HISTORY_LENGTH)
        self._lock = threading.Lock()
        self._ids = itertools.count(1)

    def new(self, trajectory: JointTrajectory, on_feedback: Callable[[TrajectoryFeedback], None] | None = None,
            on_done: Callable[[GoalResult], None] | None = None) -> GoalHandle:
        """A handle with the next goal id (any thread), kept in :attr:`history`."""
        handle = GoalHandle(next(self._ids), trajectory, on_feedback, on_done)
        self.history.append(handle)
        return handle

    @staticmethod
    def reject(handle: GoalHandle, error: InvalidTrajectory, time_s: float) -> None:
        """``handle`` was refused on arrival: REJECTED with the error's code and text."""
        handle._finish(GoalStatus.REJECTED, error.error_code, str(error), time_s)

    def queue(self, handle: GoalHandle, time_s: float) -> None:
        """``handle`` (validated) waits for the next cycle, replacing a goal that still waits (any thread)."""
        with self._lock:
            previous, self.pending = self.pending, handle
        if previous is not None:
            previous._finish(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL,
                             f"replaced by goal {handle.id} before it started", time_s)

    def take_pending(self) -> GoalHandle | None:
        with self._lock:
            handle, self.pending = self.pending, None
        return handle

    def activate(self, handle: GoalHandle, time_s: float) -> None:
        """``handle`` becomes the active goal; the one it replaces ends PREEMPTED."""
        if self.active is not None:
            self.active._finish(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL,
                                f"replaced by goal {handle.id}", time_s)
        self.active = handle
        self.served += 1
        handle.status = GoalStatus.ACTIVE

    def end(self, status: GoalStatus, code: TrajectoryErrorCode, text: str, time_s: float) -> None:
        """The active goal ends with this result (if it had not ended already); none is active after."""
        handle, self.active = self.active, None
        if handle is not None:
            handle._finish(status, code, text, time_s)

    def abort_all(self, why: str, time_s: float) -> None:
        """The pending and the active goal end ABORTED saying ``why`` (the executor stopped or failed)."""
        with self._lock:
            pending, self.pending = self.pending, None
        active, self.active = self.active, None
        for handle in (pending, active):
            if handle is not None:
                handle._finish(GoalStatus.ABORTED, TrajectoryErrorCode.INVALID_GOAL, why, time_s)

"""The compiled form of :class:`~jointctl.trajectory.executor.TrajectoryExecutor`'s cycle between events:
sampling its plan (:meth:`~jointctl.trajectory.plan.Plan.at`, at the loop rate or sample-and-hold at
``stream_rate_hz``), the stream watchdog, writing the references into its position controllers' reference
interfaces, and the supervision of the active goal (feedback when due, kept as ``latest_feedback``; the path
tolerance every cycle; the goal's end).

The plan is packed joint by joint: each joint's interpolant (its part of the plan) as knot times, the polynomial
coefficients of its segments in powers of ``t - t_k`` and its values before the first and after the last knot,
evaluated operation for operation as :mod:`~jointctl.trajectory.interpolation` does on the grid of
:class:`~jointctl.trajectory.plan.Plan`'s blocks (``BLOCK_CYCLES`` cycles from the loop time of the cycle that
first needs one): the same bits.

Events stay in Python: a goal arriving, a splice, a stream, a cancel, a hardware fault (the compiled run runs
such a cycle in Python), and a goal's end: :func:`executor_update` says when the supervision decides one (a path
tolerance violated, the goal reached, its goal time over); the stretch ends after that cycle and the Python
supervision, on the same state, ends the goal as at that cycle.
"""

from __future__ import annotations

import math

import numpy as np

from jointctl.jit import kernel
from jointctl.trajectory.executor import TrajectoryExecutor
from jointctl.trajectory.goals import TrajectoryFeedback
from jointctl.trajectory.plan import BLOCK_CYCLES

#: The parameters: whether velocities and accelerations are sent, the stream period [s] (0: every cycle), the
#: feedback period [s], the stopped velocity tolerance [/s], whether it is checked without a goal tolerance.
VELOCITY_FEEDFORWARD, STREAM_PERIOD, FEEDBACK_PERIOD, STOPPED_VELOCITY, VELOCITY_ALWAYS = range(5)
PARAMETERS = 5
#: The state: whether there is a plan, its start and end [s] (loop time), whether a block of it is in hand and
#: the cycle it starts at, the next stream and feedback times, the next supervision, the stream watchdog's
#: deadline [s], whether a goal is active and its goal time [s], the last update's time, whether feedback was
#: kept (and its time), whether a goal's end is decided (and at which cycle).
(HAS_PLAN, PLAN_START, PLAN_END, HAS_BLOCK, BLOCK_CYCLE, NEXT_STREAM, NEXT_FEEDBACK, SUPERVISE_AT, STREAM_DEADLINE,
 GOAL_ACTIVE, GOAL_TIME, LAST_TIME, FEEDBACK_KEPT, FEEDBACK_TIME, DECIDED, DECIDED_CYCLE) = range(16)
STATE = 16
#: ``ends`` per joint: the first knot's position, the last knot's position, velocity and acceleration.
FIRST, LAST, LAST_VELOCITY, LAST_ACCELERATION = range(4)
_ORDER = {"linear": 2, "cubic": 4, "quintic": 6}
#: ``feedback`` rows: the desired positions and velocities, the actual positions and velocities.
FEEDBACK_ROWS = 4


class ExecutorArrays:
    """The arrays of ``executor`` (running, commanding position controllers) for loop period ``period_s``."""

    def __init__(self, executor: TrajectoryExecutor, period_s: float) -> None:
        ex = self.executor = executor
        self.period_s = period_s
        n = len(ex.joint_names)
        self.hw_index = np.array(ex.hw_index, dtype=np.int64)
        stream = ex._stream_period_s
        self.parameters = np.array([float(ex.velocity_feedforward), 0.0 if stream is None else stream,
                                    ex._feedback_period_s, ex.stopped_velocity_tolerance,
                                    float(ex.stopped_velocity_always)])
        self.ref = np.array(ex._ref, dtype=float).reshape(n, 3)
        goal = ex.goals.active
        self.path_tolerance = np.array(goal.path_tolerance if goal is not None else [0.0] * n, dtype=float)
        self.goal_tolerance = np.array(goal.goal_tolerance if goal is not None else [0.0] * n, dtype=float)
        plan = ex._plan
        has_block = plan is not None and plan._count > 0
        self.state = np.array([
            float(plan is not None), plan.start_s if plan else 0.0, plan.end_s if plan else 0.0,
            float(has_block), round(plan._block_t0 / period_s) if has_block else 0.0,
            ex._next_stream_s, ex._next_feedback_s, ex._supervise_at, ex._stream_deadline_s,
            float(goal is not None), goal.goal_time_s if goal is not None else 0.0, ex._last_time_s,
            0.0, 0.0, 0.0, 0.0])
        self.feedback = np.zeros((FEEDBACK_ROWS, n))
        self._pack_plan(plan, n)

    def _pack_plan(self, plan, n: int) -> None:
        parts = plan.parts if plan is not None else []
        knots = max([len(interp.times_s) for interp, _ in parts] or [1])
        self.knots = np.ones(n, dtype=np.int64)
        self.order = np.full(n, 2, dtype=np.int64)
        self.times = np.zeros((n, knots))
        self.coefficients = np.zeros((n, max(knots - 1, 1), 6))
        self.ends = np.zeros((n, 4))
        for interp, columns in parts:
            count = len(interp.times_s)
            for c, j in enumerate(np.asarray(columns, dtype=int)):
                self.knots[j], self.order[j] = count, _ORDER[interp.kind]
                self.times[j, :count] = interp.times_s
                self.coefficients[j, :count - 1] = interp.coefficients[:, c, :]
                self.ends[j] = (interp.positions[0, c], interp.positions[-1, c], interp.velocities[-1, c],
                                interp.accelerations[-1, c])

    @property
    def decided_cycle(self) -> int | None:
        """The cycle whose supervision decided the goal's end (the Python finishes it), or None."""
        return int(self.state[DECIDED_CYCLE]) if self.state[DECIDED] else None

    def unpack(self) -> None:
        """Put the references, the times and the plan's block in hand back into the executor (and the feedback
        kept last, as ``latest_feedback``)."""
        ex, state, period = self.executor, self.state, self.period_s
        ex._ref = tuple(self.ref.ravel().tolist())
        ex._next_stream_s = float(state[NEXT_STREAM])
        ex._next_feedback_s = float(state[NEXT_FEEDBACK])
        ex._supervise_at = float(state[SUPERVISE_AT])
        ex._stream_deadline_s = float(state[STREAM_DEADLINE])
        ex._last_time_s = float(state[LAST_TIME])
        plan = ex._plan
        if plan is not None and state[HAS_BLOCK]:
            start = int(state[BLOCK_CYCLE]) * period  # the loop time of the block's first cycle
            if plan._count == 0 or plan._block_t0 != start:  # the same grid, so the same rows, in Python
                plan._sample_blocks(start, period)
        if state[FEEDBACK_KEPT]:
            desired, desired_v, actual, actual_v = (tuple(row) for row in self.feedback.tolist())
            ex.latest_feedback = TrajectoryFeedback(float(state[FEEDBACK_TIME]), ex.joint_names, desired, desired_v,
                                                    actual, actual_v)
            state[FEEDBACK_KEPT] = 0.0


class NoExecutor:
    """The arrays of :class:`ExecutorArrays` for a loop without an executor (never read)."""

    def __init__(self) -> None:
        self.parameters, self.state = np.zeros(PARAMETERS), np.zeros(STATE)
        self.hw_index = self.knots = self.order = np.zeros(0, dtype=np.int64)
        self.ref, self.ends, self.feedback, self.times = np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((4, 0)), \
            np.zeros((0, 1))
        self.path_tolerance = self.goal_tolerance = np.zeros(0)
        self.coefficients = np.zeros((0, 1, 6))


@kernel
def _coefficient(coefficients, j, s, i, derivative):
    """Coefficient ``i`` of segment ``s`` of joint ``j`` for the position (``derivative`` 0), the velocity (1:
    ``c[i+1]·(i+1)``) or the acceleration (2: the velocity's ``[i+1]·(i+1)``), as ``interpolation._Work`` makes
    them."""
    if derivative == 0:
        return coefficients[j, s, i]
    if derivative == 1:
        return coefficients[j, s, i + 1] if i == 0 else coefficients[j, s, i + 1] * float(i + 1)
    if i == 0:
        return coefficients[j, s, 2] * 2.0
    return (coefficients[j, s, i + 2] * float(i + 2)) * float(i + 1)


@kernel
def _horner(coefficients, j, s, order, derivative, tau):
    """Horner's scheme of segment ``s`` of joint ``j`` in the order of operations of ``interpolation._horner``."""
    m = order - derivative
    out = _coefficient(coefficients, j, s, m - 1, derivative) * tau
    for i in range(m - 2, 0, -1):
        out += _coefficient(coefficients, j, s, i, derivative)
        out *= tau
    return out + _coefficient(coefficients, j, s, 0, derivative)


@kernel
def plan_sample(times, knots, order, coefficients, ends, j, t):
    """Joint ``j``'s position, velocity and acceleration at ``t`` [s since the plan's start] (``Interpolant``'s
    values: held before the first knot and after the last, the last knot's at its time)."""
    count = knots[j]
    if t < times[j, 0]:
        return ends[j, FIRST], 0.0, 0.0
    if t >= times[j, count - 1]:
        if t == times[j, count - 1]:
            return ends[j, LAST], ends[j, LAST_VELOCITY], ends[j, LAST_ACCELERATION]
        return ends[j, LAST], 0.0, 0.0
    s = 0
    while s + 2 < count and times[j, s + 1] <= t:
        s += 1
    tau = t - times[j, s]
    kind = order[j]
    p = _horner(coefficients, j, s, kind, 0, tau)
    if kind == 2:  # linear: the slope, no acceleration
        return p, coefficients[j, s, 1], 0.0
    return p, _horner(coefficients, j, s, kind, 1, tau), _horner(coefficients, j, s, kind, 2, tau)


@kernel
def _sample_plan(state, times, knots, order, coefficients, ends, ref, k, period_s):
    """``Plan.at`` for cycle ``k``: the row of its block (a new block from this cycle when out of the one in
    hand), at ``block start - plan start + period·row``."""
    row = k - int(state[BLOCK_CYCLE])
    if state[HAS_BLOCK] == 0.0 or not 0 <= row < BLOCK_CYCLES:
        state[HAS_BLOCK] = 1.0
        state[BLOCK_CYCLE] = float(k)
        row = 0
    since = int(state[BLOCK_CYCLE]) * period_s - state[PLAN_START]
    t = since + period_s * float(row)
    for j in range(ref.shape[0]):
        ref[j, 0], ref[j, 1], ref[j, 2] = plan_sample(times, knots, order, coefficients, ends, j, t)


@kernel
def _supervise(parameters, state, hw_index, ref, path_tolerance, goal_tolerance, feedback, position, velocity,
               time_s):
    """``TrajectoryExecutor._supervise`` up to its decision: feedback when due, then True when the goal's end is
    decided at this cycle (the path left, the goal reached, or its goal time over)."""
    if time_s + 1e-9 >= state[NEXT_FEEDBACK]:
        state[NEXT_FEEDBACK] += parameters[FEEDBACK_PERIOD]
        for j in range(ref.shape[0]):
            i = hw_index[j]
            feedback[0, j], feedback[1, j] = ref[j, 0], ref[j, 1]
            feedback[2, j], feedback[3, j] = position[i], velocity[i]
        state[FEEDBACK_KEPT], state[FEEDBACK_TIME] = 1.0, time_s
    if state[HAS_PLAN] == 0.0:
        return False
    end = state[PLAN_END]
    checks_path = False
    for j in range(path_tolerance.shape[0]):
        if path_tolerance[j] > 0:
            checks_path = True
    if checks_path:
        state[SUPERVISE_AT] = -math.inf
    else:
        state[SUPERVISE_AT] = min(state[NEXT_FEEDBACK], end)
    if time_s < end and checks_path:
        for j in range(ref.shape[0]):
            tol = path_tolerance[j]
            if tol > 0 and abs(ref[j, 0] - position[hw_index[j]]) > tol:
                return True
    if time_s + 1e-9 < end:
        return False
    if _goal_reached(parameters, hw_index, ref, goal_tolerance, position, velocity):
        return True  # (the simulated hardware says nothing of being in motion)
    return time_s > end + state[GOAL_TIME]


@kernel
def _goal_reached(parameters, hw_index, ref, tolerance, position, velocity):
    """``tolerances.goal_reached`` on the executor's joints."""
    stopped = parameters[STOPPED_VELOCITY]
    within = True
    any_tolerance = False
    for j in range(ref.shape[0]):
        tol = tolerance[j]
        if tol > 0:
            any_tolerance = True
            if abs(ref[j, 0] - position[hw_index[j]]) > tol:
                within = False
    if parameters[VELOCITY_ALWAYS] != 0.0:
        if not within:
            return False
        if stopped <= 0:
            return True
    else:
        if not any_tolerance:
            return True
        if not within:
            return False
    for j in range(ref.shape[0]):
        if abs(velocity[hw_index[j]]) > stopped:
            return False
    return True


@kernel
def executor_update(parameters, state, hw_index, ref, path_tolerance, goal_tolerance, times, knots, order,
                    coefficients, ends, feedback, position, velocity, reference_positions, reference_velocities,
                    reference_accelerations, k, time_s, period_s):
    """``TrajectoryExecutor.update`` of cycle ``k`` at ``time_s`` [s] without events; True when the supervision
    decides the goal's end at this cycle (``state[DECIDED]``: the Python ends it after the cycle)."""
    state[LAST_TIME] = time_s
    if state[HAS_PLAN] != 0.0:
        stream_period = parameters[STREAM_PERIOD]
        if stream_period == 0.0:
            _sample_plan(state, times, knots, order, coefficients, ends, ref, k, period_s)
        elif time_s + 1e-9 >= state[NEXT_STREAM]:
            state[NEXT_STREAM] += stream_period
            _sample_plan(state, times, knots, order, coefficients, ends, ref, k, period_s)
    elif time_s > state[STREAM_DEADLINE]:  # watchdog: the stream stopped
        for j in range(ref.shape[0]):
            ref[j, 1] = 0.0
            ref[j, 2] = 0.0
        state[STREAM_DEADLINE] = math.inf
    send = parameters[VELOCITY_FEEDFORWARD] != 0.0
    for j in range(ref.shape[0]):
        i = hw_index[j]
        reference_positions[i] = ref[j, 0]
        reference_velocities[i] = ref[j, 1] if send else 0.0
        reference_accelerations[i] = ref[j, 2] if send else 0.0
    if state[GOAL_ACTIVE] != 0.0 and time_s + 1e-9 >= state[SUPERVISE_AT]:
        if _supervise(parameters, state, hw_index, ref, path_tolerance, goal_tolerance, feedback, position, velocity,
                      time_s):
            state[DECIDED], state[DECIDED_CYCLE] = 1.0, float(k)
            return True
    return False

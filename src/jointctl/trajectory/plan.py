"""What an executor's joints follow over time: goals spliced onto the current state, and stops.

A :class:`Plan` holds one or more interpolants, each over some of the executor's joints, in
time since its start. :meth:`Plan.splice` continues from the desired state in hand (position
and velocity, so there is no jump) into a goal's future points, bringing the joints the goal
does not name to rest; :meth:`Plan.stop` decelerates every joint to rest together.

The loop reads references with :meth:`Plan.at` once a cycle. They are sampled on grids of
``BLOCK_CYCLES`` cycles, each starting at the loop time of the cycle that first needs it (the
values depend on the grid, to the last bit), several blocks in one vectorised evaluation when
the loop's times allow, into a buffer of doubles, one row a cycle. A cycle unpacks its row
(one C call for every joint's three values): it costs neither an evaluation nor thousands of
Python floats made at once and kept for a block.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

import numpy as np

from jointctl.trajectory.interpolation import Interpolant, build_interpolant, sample_block
from jointctl.trajectory.validation import ValidatedTrajectory

BLOCK_CYCLES = 256  # references are sampled on grids of this many cycles (vectorised)
BLOCKS_AHEAD = 4  # blocks evaluated in one call when the loop's times allow (see Plan._sample_blocks)
INTERPOLATIONS = ("linear", "cubic", "quintic", "auto")

#: The desired positions, velocities and accelerations of every joint, in the executor's order.
State = tuple[Sequence[float], Sequence[float], Sequence[float]]
#: One cycle's references, joint by joint: (q0, v0, a0, q1, v1, a1, ...).
Row = tuple[float, ...]
Part = tuple[Interpolant, np.ndarray]


class Plan:
    """References over time for ``n_joints`` joints: ``parts`` of (interpolant, columns), each
    interpolant over the joints ``columns`` in time since ``start_s`` (loop time, s)."""

    def __init__(self, parts: list[Part], n_joints: int, start_s: float, *, stopping: bool = False) -> None:
        self.parts = parts
        self.start_s = start_s
        self.end_s = start_s + max(interp.duration_s for interp, _ in parts)
        self.stopping = stopping
        self._n = n_joints
        self._whole = len(parts) == 1 and np.array_equal(parts[0][1], np.arange(n_joints))
        self._block_t0 = start_s
        self._count = 0  # cycles in the block in hand (none yet)
        self._block = bytearray()  # rows of doubles: (cycles, joints, 3), reused block after block
        self._rows: np.ndarray | None = None  # the same memory as an array
        self._offset = 0  # bytes before the block in hand's first row
        self._ahead: list[float] = []  # loop times at which the next blocks in _block start
        self._row_bytes = 3 * n_joints * 8
        self._unpack = struct.Struct(f"@{3 * n_joints}d").unpack_from  # native, as numpy writes them

    @classmethod
    def splice(cls, goal: ValidatedTrajectory, state: State, start_s: float, time_s: float, *,
               interpolation: str, stop_deceleration: Sequence[float]) -> Plan:
        """From ``state`` (the desired state of loop time ``start_s``) into the goal's points after
        ``time_s``; joints the goal does not name come to rest (within their stop deceleration)
        and hold. ``interpolation`` is one of :data:`INTERPOLATIONS`."""
        positions_now, velocities_now, accelerations_now = state
        columns = np.asarray(goal.joint_indices, dtype=int)
        times = goal.start_time_s + goal.times_s
        future = times > time_s + 1e-9
        if not future.any():  # the whole goal lies in the past: go to its last point now
            future[-1] = True
            times = times.copy()
            times[-1] = time_s + 1e-3
        q0 = np.asarray(positions_now)[columns]
        v0 = np.asarray(velocities_now)[columns]
        a0 = np.asarray(accelerations_now)[columns]
        knot_times = np.concatenate(([0.0], times[future] - start_s))
        positions = np.vstack((q0, goal.positions[future]))
        kind = interpolation
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
        n = len(positions_now)
        parts = [(interp, columns)]
        omitted = np.setdiff1d(np.arange(n), columns)
        if omitted.size:
            parts.append(stop_part(positions_now, velocities_now, stop_deceleration, omitted))
        return cls(parts, n, start_s)

    @classmethod
    def stop(cls, state: State, start_s: float, period_s: float, stop_deceleration: Sequence[float]) -> Plan:
        """Every joint decelerates to rest, all together, from ``state`` (that of loop time ``start_s``)."""
        n = len(state[0])
        return cls([stop_part(state[0], state[1], stop_deceleration, np.arange(n), period_s)], n, start_s,
                   stopping=True)

    def at(self, time_s: float, period_s: float) -> Row:
        """Desired position, velocity and acceleration of every joint at loop time ``time_s``, in a
        cycle of ``period_s``, joint by joint: (q0, v0, a0, q1, v1, a1, ...)."""
        k = round((time_s - self._block_t0) / period_s) if period_s > 0 else -1
        if not 0 <= k < self._count:
            self._next_block(time_s, period_s)
            k = 0
        return self._unpack(self._block, self._offset + k * self._row_bytes)

    def _next_block(self, time_s: float, period_s: float) -> None:
        """Make the block of cycles from ``time_s`` on the one in hand: sampled already if an earlier
        evaluation predicted that a block starts at ``time_s``, else sampled now."""
        if self._ahead and time_s == self._ahead[0]:
            del self._ahead[0]
            self._offset += BLOCK_CYCLES * self._row_bytes
            self._block_t0 = time_s
            return
        self._sample_blocks(time_s, period_s)

    def _sample_blocks(self, time_s: float, period_s: float) -> None:
        """Sample ``BLOCK_CYCLES`` cycles from ``time_s`` on, each at ``time_s + k·period_s`` (one
        cycle when the period is not positive).

        The values depend on where a block starts (its grid), so a block always starts at the loop
        time of the cycle that needs it. When ``time_s`` is a whole number of periods (the loop's
        times are ``cycle·period_s``), the blocks that will follow, if the loop runs a cycle at a
        time, start at ``(cycle + m·BLOCK_CYCLES)·period_s``: the very times the loop will pass.
        ``BLOCKS_AHEAD`` blocks are then evaluated in one call; a later block is used only if the
        loop does reach its start exactly (see :meth:`_next_block`).
        """
        since = time_s - self.start_s
        if period_s > 0:
            count, step, starts = BLOCK_CYCLES, period_s, [since]
            cycle = round(time_s / period_s)
            if cycle * period_s == time_s:
                self._ahead = [(cycle + m * BLOCK_CYCLES) * period_s for m in range(1, BLOCKS_AHEAD)]
                starts += [t - self.start_s for t in self._ahead]
            else:
                self._ahead = []
        else:
            count, step, starts, self._ahead = 1, 1.0, [since], []
        cycles = count * len(starts)
        if self._rows is None or self._rows.shape[0] != cycles:
            self._block = bytearray(cycles * self._row_bytes)
            self._rows = np.frombuffer(self._block, dtype=float).reshape(cycles, self._n, 3)
        if self._whole:
            sample_block(self.parts[0][0], starts, step, count, out=self._rows)
        else:
            for interp, columns in self.parts:
                q, v, a = sample_block(interp, starts, step, count)
                self._rows[:, columns, 0], self._rows[:, columns, 1], self._rows[:, columns, 2] = q, v, a
        self._offset = 0
        self._block_t0 = time_s
        self._count = count


def stop_part(positions: Sequence[float], velocities: Sequence[float], deceleration: Sequence[float],
              columns: np.ndarray, period_s: float = 0.0) -> Part:
    """The joints ``columns`` decelerate uniformly to rest together, each within its deceleration:
    q0 + v0·τ - v0·τ²/(2T) up to T = max |v0|/a_max (at least ``period_s`` and 1 ms), then hold."""
    q0 = np.asarray(positions)[columns]
    v0 = np.asarray(velocities)[columns]
    decel = np.asarray(deceleration)[columns]
    duration = max(float(np.max(np.abs(v0) / decel)), period_s, 1e-3)
    knots = np.vstack((q0, q0 + v0 * duration / 2))
    knot_velocities = np.vstack((v0, np.zeros_like(v0)))
    return build_interpolant(np.array([0.0, duration]), knots, knot_velocities, kind="cubic"), columns


def interleave(positions: Sequence[float], velocities: Sequence[float], accelerations: Sequence[float]) -> Row:
    """A row of references, joint by joint, as :meth:`Plan.at` gives it."""
    return tuple(x for row in zip(positions, velocities, accelerations) for x in row)

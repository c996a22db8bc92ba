"""What an executor's joints follow over time: goals spliced onto the current state, and stops.

A :class:`Plan` holds one or more interpolants, each over some of the executor's joints, in
time since its start. :meth:`Plan.splice` continues from the desired state in hand (position
and velocity, so there is no jump) into a goal's future points, bringing the joints the goal
does not name to rest; :meth:`Plan.stop` decelerates every joint to rest together.

The loop reads references with :meth:`Plan.at` once a cycle. They are sampled a block of
``BLOCK_CYCLES`` cycles at a time (one vectorised evaluation) into a buffer of doubles, one row
a cycle, and a cycle unpacks its row (one C call for every joint's three values), so a cycle
costs neither an evaluation nor thousands of Python floats made at once and kept for a block.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

import numpy as np

from jointctl.trajectory.interpolation import Interpolant, build_interpolant, sample_block
from jointctl.trajectory.validation import ValidatedTrajectory

BLOCK_CYCLES = 256  # references are sampled this many cycles at a time (vectorised)
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
        self._block = b""
        self._row_bytes = 3 * n_joints * 8
        self._unpack = struct.Struct(f"={3 * n_joints}d").unpack_from

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
            self._sample_block(time_s, period_s)
            k = 0
        return self._unpack(self._block, k * self._row_bytes)

    def _sample_block(self, time_s: float, period_s: float) -> None:
        """Sample the cycles from ``time_s`` on (one cycle when the period is not positive)."""
        count = BLOCK_CYCLES if period_s > 0 else 1
        step = period_s if period_s > 0 else 1.0
        since_start = time_s - self.start_s
        if self._whole:
            q, v, a = sample_block(self.parts[0][0], since_start, step, count)
        else:
            q, v, a = np.empty((3, count, self._n))
            for interp, columns in self.parts:
                q[:, columns], v[:, columns], a[:, columns] = sample_block(interp, since_start, step, count)
        self._block = np.stack((q, v, a), axis=-1).tobytes()  # (count, joints, 3) doubles
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

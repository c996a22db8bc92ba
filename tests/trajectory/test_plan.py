"""Tests for jointctl.trajectory.plan: references cycle by cycle from blocks of samples.

A block's values depend on its grid (its first cycle's loop time plus k periods), so the
references a cycle gets must be those of the block that starts at the loop time of the cycle
that needed it, whether that block was evaluated then or ahead of time.
"""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.trajectory.interpolation import build_interpolant, sample_block
from jointctl.trajectory.plan import BLOCK_CYCLES, Plan, interleave, stop_part

PERIOD = 0.001


def _interpolant(n_joints: int = 3, knots: int = 40, seed: int = 0):
    rng = np.random.default_rng(seed)
    times = np.concatenate(([0.0], np.cumsum(rng.uniform(0.05, 0.2, knots - 1))))
    positions = rng.normal(size=(knots, n_joints))
    return build_interpolant(times, positions, rng.normal(size=(knots, n_joints)), kind="cubic")


def _expected(interp, start_s: float, cycles: list[tuple[float, float]]) -> list[tuple]:
    """Rows as blocks evaluated one at a time give them: ``cycles`` are (time, block start time)."""
    rows = []
    for time_s, block_t0 in cycles:
        k = round((time_s - block_t0) / PERIOD)
        q, v, a = sample_block(interp, block_t0 - start_s, PERIOD, BLOCK_CYCLES)
        rows.append(interleave(q[k], v[k], a[k]))
    return rows


def _blocks(times: list[float]) -> list[tuple[float, float]]:
    """(time, start of its block) as the plan's rule makes them: a new block when k leaves [0, 256)."""
    out, t0 = [], None
    for t in times:
        if t0 is None or not 0 <= round((t - t0) / PERIOD) < BLOCK_CYCLES:
            t0 = t
        out.append((t, t0))
    return out


@pytest.mark.parametrize("case", ["loop times", "offset times", "every 10th cycle", "a jump"])
def test_each_cycle_gets_the_row_of_the_block_that_starts_at_the_cycle_that_needed_it(case) -> None:
    interp = _interpolant()
    start_s = 0.2
    cycles = range(201, 201 + 3000)
    times = {"loop times": [c * PERIOD for c in cycles],                 # blocks evaluated ahead
             "offset times": [0.0003 + c * PERIOD for c in cycles],      # not whole periods: one at a time
             "every 10th cycle": [c * PERIOD for c in cycles[::10]],     # a stream rate: predicted starts missed
             "a jump": [c * PERIOD for c in [*range(201, 900), *range(1500, 2600)]]}[case]
    plan = Plan([(interp, np.arange(3))], 3, start_s)
    got = [plan.at(t, PERIOD) for t in times]
    assert got == _expected(interp, start_s, _blocks(times))


def test_blocks_ahead_are_evaluated_in_fewer_calls(monkeypatch) -> None:
    import jointctl.trajectory.plan as plan_module

    calls = []
    original = plan_module.sample_block
    monkeypatch.setattr(plan_module, "sample_block", lambda *a, **k: calls.append(a[1]) or original(*a, **k))
    plan = Plan([(_interpolant(), np.arange(3))], 3, 0.0)
    for c in range(4 * BLOCK_CYCLES * 2):
        plan.at(c * PERIOD, PERIOD)
    assert len(calls) == 2 and all(len(starts) == plan_module.BLOCKS_AHEAD for starts in calls)


def test_parts_over_some_joints_fill_their_columns() -> None:
    moving = _interpolant(n_joints=2, seed=1)
    stopping = stop_part([0.5, -0.1, 0.3], [0.0, 2.0, 0.0], [5.0, 5.0, 5.0], np.array([1]))
    plan = Plan([(moving, np.array([0, 2])), stopping], 3, 1.0)
    for time_s in (1.0, 1.05, 1.3, 1.5):
        row = plan.at(time_s, PERIOD)
        q, v, a = moving.sample(time_s - 1.0)
        qs, vs, as_ = stopping[0].sample(time_s - 1.0)
        # (equal to sampling at the time itself up to the rounding of the block's grid)
        assert row == pytest.approx(interleave([q[0], qs[0], q[1]], [v[0], vs[0], v[1]], [a[0], as_[0], a[1]]),
                                    rel=0, abs=1e-12)
    # The stopped joint came to rest within its deceleration: 2 m/s at 5 m/s² is 0.4 s, 0.4 m on.
    assert plan.at(1.5, PERIOD)[3:6] == pytest.approx((-0.1 + 0.4, 0.0, 0.0))


def test_a_period_of_zero_samples_the_time_itself() -> None:
    interp = _interpolant()
    plan = Plan([(interp, np.arange(3))], 3, 0.0)
    for time_s in (0.5, 0.5, 0.7, 0.6):
        q, v, a = interp.sample(time_s)
        assert plan.at(time_s, 0.0) == interleave(q, v, a)

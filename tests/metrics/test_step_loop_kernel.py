"""The compiled joint loop (jointctl.metrics.step_loop_kernel) runs JointLoop.run's cycles to the bit: every
combination of law, derivative, integral clamps, feed-forward, delay, start and loads, both ways compared with
``array_equal``; a load that is not a table keeps the Python loop."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from jointctl.metrics.step_loop import HoldingEffort, JointLoop, _compiled_run, holding_effort, reference_step
from jointctl.model import load_robot_model
from jointctl.paths import robots_dir

H = 0.001
#: A load that varies along the joint (a pendulum's m·g·l·sin over ±1.5 rad), and a lighter model of it.
GRID = np.linspace(-1.5, 1.5, 61)
PLANT = HoldingEffort(-1.5, 0.05, 12.0 * np.sin(GRID), np.diff(12.0 * np.sin(GRID)) / 0.05)
MODEL = HoldingEffort(-1.5, 0.05, 9.0 * np.sin(GRID), np.diff(9.0 * np.sin(GRID)) / 0.05)


def test_a_table_reads_linearly_inside_and_straight_on_beyond_its_grid():
    for q in (-1.5, -0.731, 0.0, 0.42, 1.4999):
        assert PLANT(q) == pytest.approx(np.interp(q, GRID, 12.0 * np.sin(GRID)), abs=1e-12)
    slope_right = (12.0 * np.sin(1.5) - 12.0 * np.sin(1.45)) / 0.05
    assert PLANT(1.7) == pytest.approx(12.0 * np.sin(1.45) + slope_right * 0.25, abs=1e-12)
    assert HoldingEffort.zero()(-3.0) == 0.0 and HoldingEffort.zero()(5.0) == 0.0


CASES = list(itertools.product(
    ["ros_control", "control_toolbox"], ["error", "measurement"],
    [(0.0, np.inf, None, False), (300.0, 4.0, None, False), (300.0, 4.0, -1.0, True)],  # i, clamp, clamp_min, aw
    [(False, None, None), (True, PLANT, None), (True, PLANT, MODEL), (False, PLANT, None)],  # ff, hold, ff hold
    [0, 1, 3], [None, (0.1, -0.2)], [12.0, np.inf]))


@pytest.mark.parametrize(("law", "derivative", "integral", "loads", "delay", "start", "limit"), CASES)
def test_the_compiled_loop_runs_the_python_loops_cycles(law, derivative, integral, loads, delay, start, limit):
    i, clamp, clamp_min, antiwindup = integral
    feedforward, hold, model = loads
    loop = JointLoop(1.3, 8.0, H, limit, hold, p=500.0, i=i, d=25.0, i_clamp=clamp, i_clamp_min=clamp_min,
                     antiwindup=antiwindup, derivative=derivative, feedforward=feedforward, integrator="euler",
                     substeps=2, feedforward_hold=model, delay_cycles=delay, law=law)
    reference = reference_step(0.1, -0.3, hold_s=0.05, ramp_s=0.02, after_s=0.4, period_s=H)
    for kwargs in ({}, {"until_peak": True}, {"reference_rate": np.gradient(reference, H)}):
        python = loop.run(reference, start=start, compiled=False, **kwargs)
        compiled = loop.run(reference, start=start, **kwargs)
        for a, b in zip(python, compiled):
            assert np.array_equal(a, b)
    assert python[0].size == reference.size and np.ptp(python[0]) > 0.1  # it moved


def test_the_one_dof_robots_own_table_runs_compiled_and_a_callable_load_in_python():
    robot = load_robot_model(robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro")
    hold = holding_effort(robot, "joint1", {"joint1": -0.2}, (0.0, 0.0, -9.81))
    assert isinstance(hold, HoldingEffort)
    loop = JointLoop(1.01, 10.0, H, 100.0, hold, p=400.0, d=20.0, integrator="euler")
    reference = reference_step(-0.2, -0.3, after_s=1.0)
    arguments = ((0, 0, 0, 0, 0, 0), (H, 0, 0, 0, 0, 0, 0), (False,) * 6, reference, None, (0.0,) * 4, 0.0, 1)
    assert _compiled_run(loop, *arguments) is not None
    assert _compiled_run(JointLoop(1.01, 10.0, H, hold=lambda q: 9.9), *arguments) is None
    python, compiled = loop.run(reference, compiled=False), loop.run(reference)
    assert all(np.array_equal(a, b) for a, b in zip(python, compiled))
    assert compiled[0][-1] == pytest.approx(-0.5 - 1.01 * 9.81 / 400.0, abs=2e-4)  # the P loop's sag m·g/p

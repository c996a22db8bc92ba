"""The robust design's check on a served robot, without one: the gains it sets (pid_controller's parameters) and how
long the robot holds before the step (the slowest mode of the loop taking the integral's worst start to a tenth of
the settling band). The check itself runs against a served robot in tests/ros2/test_served_tools.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jointctl.sweep.robust_served import HOLD_S, ros2_gains, served_hold_s


def result(gains: dict, *, load: float = 9.9, inertia=(1.01, 2.01), damping=(10.0, 10.0), step: float = 0.3) -> dict:
    return {"robust": {"gains": gains, "law": "control_toolbox", "derivative": "error", "feedforward": []},
            "family": {"gravity_load_max": load, "inertia": list(inertia), "damping": list(damping)},
            "spec": {"step": step}, "joint": "joint1"}


def test_the_gains_are_pid_controllers_parameters_with_the_clamp_both_ways() -> None:
    gains = {"p": 2504.2604156, "i": 521.72092, "d": 136.9648782, "i_clamp": 117.9162, "antiwindup": True}
    assert ros2_gains(result(gains), "joint1") == {"p": 2504.260416, "i": 521.72092, "d": 136.964878,
                                                   "i_clamp_max": 117.9162, "i_clamp_min": -117.9162,
                                                   "antiwindup": True}
    assert ros2_gains(result({"p": 400, "i": 0.0, "d": 20}), "joint1") == {"p": 400.0, "i": 0.0, "d": 20.0}


def test_without_an_integral_the_robot_holds_a_second() -> None:
    assert served_hold_s(result({"p": 400.0, "i": 0.0, "d": 20.0})) == HOLD_S


def test_with_an_integral_the_hold_outlasts_the_slowest_mode_from_the_clamp() -> None:
    # p 2504, i 521.7, d 137 on 1.01-2.01 kg with 10 N·s/m: the slowest root of m s³ + (b + d) s² + p s + i is about
    # i/p = 0.208/s; the integral may start at its clamp, (117.9 + 9.9)/p = 51 mm from where it holds the load, and
    # must take that to 0.2 % of the 0.3 m step.
    gains = {"p": 2504.26, "i": 521.72, "d": 136.96, "i_clamp": 117.92, "antiwindup": True}
    offset = (117.92 + 9.9) / 2504.26
    rates = [min(-np.roots([m, 10.0 + 136.96, 2504.26, 521.72]).real) for m in (1.01, 2.01)]
    expected = 0.5 + math.log(offset / (0.002 * 0.3)) / min(rates)
    assert served_hold_s(result(gains)) == pytest.approx(expected, rel=1e-9)
    assert 20.0 < expected < 25.0

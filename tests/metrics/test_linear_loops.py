"""Coupled linear loops: one joint is the textbook loop; two coupled joints against their modes
written out by hand; the kick of a derivative on the error; loops with no rest or no stability."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from jointctl.metrics.linear_loops import linear_step
from jointctl.metrics.response import second_order_theory


def test_one_joint_is_the_textbook_second_order_loop():
    result = linear_step([[1.01]], [[400.0]], [[10.0]], 0, 400.0)
    theory = second_order_theory(1.01, 400.0, 10.0)
    assert result.final == pytest.approx(1.0)
    assert result.natural_frequency_rad_s == pytest.approx(theory["natural_frequency_rad_s"], rel=1e-12)
    assert result.damping_ratio == pytest.approx(theory["damping_ratio"], rel=1e-12)
    assert result.overshoot_pct == pytest.approx(theory["overshoot_pct"], rel=1e-9)
    assert result.second_share == 0.0 and result.oscillating


def test_a_stiffer_load_than_gain_rests_short_of_the_reference():
    # k = Kp + 100: the joint moves Kp/k of the step.
    result = linear_step([[1.0]], [[500.0]], [[10.0]], 0, 400.0)
    assert result.final == pytest.approx(0.8)
    assert result.natural_frequency_rad_s == pytest.approx(math.sqrt(500.0), rel=1e-12)


def test_the_kick_of_a_derivative_on_the_error_is_the_loops_zero():
    # p/(m s² + (b+d) s + p) plus the impulse d: the loop (d s + p)/(m s² + (b + d) s + p).
    m, b, p, d = 1.0, 2.0, 400.0, 10.0
    result = linear_step([[m]], [[p]], [[b + d]], 0, p, kick=d)
    t = np.linspace(0, 3, 30_001)
    _, y = signal.step(signal.lti([d, p], [m, b + d, p]), T=t)
    assert result.overshoot_pct == pytest.approx(100 * (y.max() - 1.0), rel=1e-6)


def test_the_step_response_in_time_is_the_loops_transfer_functions():
    # The same loop with its kick, and a stiffer load resting short of the reference: y(t) of the step.
    t = np.linspace(0, 3, 3001)
    for stiffness, kick in ((400.0, 10.0), (500.0, 0.0)):
        result = linear_step([[1.0]], [[stiffness]], [[12.0]], 0, 400.0, kick=kick)
        _, y = signal.step(signal.lti([kick, 400.0] if kick else [400.0], [1.0, 12.0, stiffness]), T=t)
        assert result.position(t) == pytest.approx(y, abs=1e-9)
        assert result.position(-0.5) == 0.0 and result.position(50.0) == pytest.approx(result.final)


def test_two_coupled_joints_ring_at_their_modes_and_the_dominant_one_is_named():
    # Two masses, the second hung on the first by a spring: the first's step rings mostly at the slow mode.
    mass = np.diag([1.0, 0.1])
    stiffness = np.array([[100.0 + 50.0, -50.0], [-50.0, 50.0]])
    damping = np.diag([2.0, 0.2])
    result = linear_step(mass, stiffness, damping, 0, 100.0)
    a = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.inv(mass) @ stiffness, -np.linalg.inv(mass) @ damping]])
    frequencies = sorted(abs(x) for x in np.linalg.eigvals(a) if x.imag > 0)
    assert [m.natural_frequency_rad_s for m in sorted(result.modes, key=lambda m: m.natural_frequency_rad_s)] == \
        pytest.approx(frequencies, rel=1e-12)
    assert result.natural_frequency_rad_s == pytest.approx(frequencies[0], rel=1e-12)
    assert 0 < result.second_share < 1
    # Its overshoot: the joint's own step response of the full system.
    sys = signal.StateSpace(a, np.array([[0.0], [0.0], [100.0], [0.0]]), np.array([[1.0, 0, 0, 0]]), [[0.0]])
    t = np.linspace(0, 10, 200_001)
    _, y = signal.step(sys, T=t)
    final = np.linalg.solve(stiffness, [100.0, 0.0])[0]
    assert result.final == pytest.approx(final, rel=1e-12)
    assert result.overshoot_pct == pytest.approx(100 * (y.max() - final) / final, rel=1e-6)


@pytest.mark.parametrize("stiffness, text", [([[0.0]], "singular"), ([[-10.0]], "not stable")])
def test_loops_without_a_rest_or_stability_are_refused(stiffness, text):
    with pytest.raises(ValueError, match=text):
        linear_step([[1.0]], stiffness, [[1.0]], 0, 1.0)

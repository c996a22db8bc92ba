"""control_toolbox 3.4.0's PID (``src/pid.cpp``) against numbers computed by hand from its source."""

from __future__ import annotations

import math

import pytest

from jointctl.control.toolbox_pid import ToolboxGains, ToolboxPid, period_ns, shortest_angular_distance
from jointctl.errors import ConfigError

DT = 10_000_000  # 10 ms: a 100 Hz controller manager


def test_the_first_rate_is_the_error_over_dt_and_then_its_difference():
    pid = ToolboxPid(ToolboxGains(p=2.0, d=0.5))
    # p_error_last starts at 0: the first call differentiates from 0, a kick of d·e/dt even for a held error.
    assert pid.compute(0.3, DT) == pytest.approx(2.0 * 0.3 + 0.5 * 0.3 / 0.01, rel=1e-15)
    assert pid.compute(0.3, DT) == pytest.approx(2.0 * 0.3, rel=1e-15)
    assert pid.compute(0.1, DT) == pytest.approx(2.0 * 0.1 + 0.5 * (0.1 - 0.3) / 0.01, rel=1e-15)


def test_the_integral_with_the_default_clamps_does_nothing_without_antiwindup():
    pid = ToolboxPid(ToolboxGains(p=0.0, i=10.0))  # i_clamp_max = i_clamp_min = 0, ros2_controllers' defaults
    assert [pid.compute(1.0, DT) for _ in range(5)] == [0.0] * 5
    assert pid.i_error == pytest.approx(0.05, rel=1e-12)  # the error is still integrated


def test_without_antiwindup_the_term_is_clamped_and_the_integral_winds_up():
    pid = ToolboxPid(ToolboxGains(i=2.0, i_max=1.0, i_min=-1.0))
    for _ in range(100):  # 1 s of error 1: i_error 1.0, i·i_error 2.0 clamped to 1
        command = pid.compute(1.0, DT)
    assert command == pytest.approx(1.0) and pid.i_error == pytest.approx(1.0, rel=1e-12)
    for _ in range(25):  # error -1 for 0.25 s: i_error 0.75, the term 1.5 still clamped at 1
        command = pid.compute(-1.0, DT)
    assert command == pytest.approx(1.0) and pid.i_error == pytest.approx(0.75, rel=1e-12)


def test_with_antiwindup_the_integral_itself_is_clamped_to_the_clamps_over_i():
    pid = ToolboxPid(ToolboxGains(i=2.0, i_max=1.0, i_min=-1.0, antiwindup=True))
    for _ in range(100):
        pid.compute(1.0, DT)
    assert pid.i_error == pytest.approx(0.5, rel=1e-12)  # i_max / i
    for _ in range(25):  # 0.5 - 0.25 = 0.25: the term 0.5, unclamped
        command = pid.compute(-1.0, DT)
    assert command == pytest.approx(2.0 * 0.25, rel=1e-12)


def test_antiwindup_with_a_zero_i_clamps_nothing_and_adds_nothing():
    pid = ToolboxPid(ToolboxGains(p=1.0, i=0.0, i_max=1.0, i_min=-1.0, antiwindup=True))
    for _ in range(300):
        command = pid.compute(1.0, DT)
    assert command == pytest.approx(1.0) and pid.i_error == pytest.approx(3.0, rel=1e-12)


def test_a_given_rate_is_used_as_it_is():
    pid = ToolboxPid(ToolboxGains(p=3.0, d=0.2))
    assert pid.compute_with_rate(0.5, -4.0, DT) == pytest.approx(3.0 * 0.5 + 0.2 * -4.0, rel=1e-15)
    assert pid.p_error_last == 0.0  # only computeCommand(error, dt) keeps the last error


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_error_or_a_zero_dt_gives_zero_and_keeps_the_last_error(bad):
    pid = ToolboxPid(ToolboxGains(p=1.0, i=1.0, i_max=5.0, i_min=-5.0, d=1.0))
    pid.compute(0.2, DT)
    assert pid.compute(bad, DT) == 0.0 and pid.p_error_last == 0.2
    assert pid.compute_with_rate(0.1, bad, DT) == 0.0 and pid.i_error == pytest.approx(0.002)
    assert pid.compute(0.4, 0) == 0.0 and pid.p_error_last == 0.2


def test_clamps_the_wrong_way_round_are_refused():
    with pytest.raises(ConfigError):
        ToolboxGains(i_max=-1.0, i_min=1.0)


def test_durations_are_whole_nanoseconds():
    assert period_ns(0.01) == 10_000_000 and period_ns(0.002) == 2_000_000 and period_ns(1 / 300) == 3_333_333


@pytest.mark.parametrize(("start", "end", "distance"), [
    (-3.0, 3.0, 6.0 - 2 * math.pi), (3.0, -3.0, 2 * math.pi - 6.0), (0.0, math.pi, math.pi),
    (0.0, -math.pi, math.pi), (0.5, 0.25, -0.25), (0.0, 7.0, 7.0 - 2 * math.pi)])
def test_the_shortest_angle_is_the_angles_package_one(start, end, distance):
    # angles::normalize_angle: fmod(a + π, 2π), then + π when <= 0, else - π: (-π, π].
    assert shortest_angular_distance(start, end) == pytest.approx(distance, abs=1e-12)

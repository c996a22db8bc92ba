"""Tests of Pid and PidGains: arithmetic, integral clamping, anti-windup, limits, validation."""

from __future__ import annotations

import math

import pytest

from jointctl.control.params import Params
from jointctl.control.pid import Pid, PidGains
from jointctl.errors import ConfigError

DT = 0.001


def gains(**kw) -> PidGains:
    kw.setdefault("i_clamp_min", -1e6)
    kw.setdefault("i_clamp_max", 1e6)
    return PidGains(**kw)


# -- arithmetic -----------------------------------------------------------------------
def test_proportional_term() -> None:
    pid = Pid(gains(p=400.0))
    assert pid.compute(-0.3, 0.0, DT) == pytest.approx(-120.0)
    assert pid.compute(0.25, 99.0, DT) == pytest.approx(100.0)  # d = 0: the rate is ignored


def test_derivative_term_uses_the_given_rate() -> None:
    pid = Pid(gains(d=20.0))
    assert pid.compute(5.0, -0.2, DT) == pytest.approx(-4.0)
    assert pid.compute(0.0, 1.5, DT) == pytest.approx(30.0)


def test_p_i_d_together() -> None:
    pid = Pid(gains(p=2.0, i=10.0, d=0.5))
    # 2*3 + 10*3*0.01 + 0.5*(-4) = 6 + 0.3 - 2
    assert pid.compute(3.0, -4.0, 0.01) == pytest.approx(4.3)
    # integral now 0.3 + 10*(-1)*0.01 = 0.2; 2*(-1) + 0.2 + 0.5*2 = -0.8
    assert pid.compute(-1.0, 2.0, 0.01) == pytest.approx(-0.8)


def test_integral_accumulates_i_times_error_times_dt() -> None:
    pid = Pid(gains(i=10.0))
    outputs = [pid.compute(2.0, 0.0, 0.01) for _ in range(3)]
    assert outputs == pytest.approx([0.2, 0.4, 0.6])
    assert pid.i_state == pytest.approx(0.6)
    # dt matters: the same error over a period 10 times longer adds 10 times more.
    assert pid.compute(2.0, 0.0, 0.1) == pytest.approx(0.6 + 2.0)


def test_reset_clears_the_integral() -> None:
    pid = Pid(gains(i=10.0))
    pid.compute(1.0, 0.0, 0.1)
    assert pid.i_state == pytest.approx(1.0)
    pid.reset()
    assert pid.i_state == 0.0
    assert pid.compute(0.0, 0.0, 0.1) == 0.0


# -- integral clamping and anti-windup -------------------------------------------------
def test_integral_contribution_is_clamped_but_state_winds_up_without_antiwindup() -> None:
    pid = Pid(PidGains(i=100.0, i_clamp_min=-1.0, i_clamp_max=2.0))
    assert pid.compute(1.0, 0.0, 0.1) == pytest.approx(2.0)  # 10 clamped to i_clamp_max
    assert pid.i_state == pytest.approx(10.0)  # the state itself keeps the full sum
    assert pid.compute(-3.0, 0.0, 0.1) == pytest.approx(-1.0)  # 10 - 30 = -20 clamped to -1
    assert pid.i_state == pytest.approx(-20.0)


def test_integral_state_is_clamped_with_antiwindup() -> None:
    pid = Pid(PidGains(i=100.0, i_clamp_min=-1.0, i_clamp_max=2.0, antiwindup=True))
    assert pid.compute(1.0, 0.0, 0.1) == pytest.approx(2.0)
    assert pid.i_state == pytest.approx(2.0)
    assert pid.compute(-3.0, 0.0, 0.1) == pytest.approx(-1.0)
    assert pid.i_state == pytest.approx(-1.0)


def _recovery(antiwindup: bool) -> tuple[float, list[float]]:
    """Saturate the integral for 5 periods, then reverse the error; outputs after reversal."""
    pid = Pid(PidGains(i=100.0, i_clamp_min=-1.0, i_clamp_max=1.0, antiwindup=antiwindup))
    for _ in range(5):
        assert pid.compute(1.0, 0.0, 0.1) == pytest.approx(1.0)
    wound = pid.i_state
    return wound, [pid.compute(-1.0, 0.0, 0.1) for _ in range(7)]


def test_antiwindup_recovers_immediately_and_windup_delays_recovery() -> None:
    wound, with_aw = _recovery(antiwindup=True)
    assert wound == pytest.approx(1.0)
    # 1 - 10 = -9, clamped: the output reverses on the first period after the error does.
    assert with_aw == pytest.approx([-1.0] * 7)

    wound, without_aw = _recovery(antiwindup=False)
    assert wound == pytest.approx(50.0)  # 5 * 100 * 1 * 0.1
    # The state unwinds 50 -> 40, 30, 20, 10, 0, -10: four periods still pushing the wrong way.
    assert without_aw == pytest.approx([1.0, 1.0, 1.0, 1.0, 0.0, -1.0, -1.0], abs=1e-9)
    late = next(k for k, u in enumerate(without_aw) if u < 0)
    early = next(k for k, u in enumerate(with_aw) if u < 0)
    assert (early, late) == (0, 5)


# -- output limit ----------------------------------------------------------------------
def test_output_clamped_to_the_output_limit() -> None:
    pid = Pid(gains(p=400.0), output_limit=1000.0)
    assert pid.compute(1.0, 0.0, DT) == pytest.approx(400.0)
    assert pid.compute(3.0, 0.0, DT) == 1000.0
    assert pid.compute(-3.0, 0.0, DT) == -1000.0
    assert pid.output_limit == 1000.0


def test_output_limit_applies_to_the_sum_of_the_terms() -> None:
    pid = Pid(PidGains(p=1.0, i=1.0, d=1.0, i_clamp_min=-5.0, i_clamp_max=5.0), output_limit=6.0)
    pid.i_state = 4.0
    # 2 + (4 + 0) + 3 = 9 -> 6
    assert pid.compute(2.0, 3.0, 0.0) == 6.0


def test_no_output_limit_by_default() -> None:
    pid = Pid(gains(p=1e6))
    assert pid.compute(1e3, 0.0, DT) == pytest.approx(1e9)


# -- gains -----------------------------------------------------------------------------
def test_set_gains_takes_effect_at_the_next_compute() -> None:
    pid = Pid(gains(p=1.0, i=10.0))
    assert pid.compute(1.0, 0.0, 0.1) == pytest.approx(1.0 + 1.0)
    new = gains(p=3.0, i=10.0, d=2.0)
    pid.set_gains(new)
    assert pid.gains is new
    # The integral is kept (no reset): 3*1 + (1 + 1) + 2*0.5
    assert pid.compute(1.0, 0.5, 0.1) == pytest.approx(3.0 + 2.0 + 1.0)


def test_set_gains_changes_the_clamp_too() -> None:
    pid = Pid(PidGains(i=100.0, i_clamp_min=-10.0, i_clamp_max=10.0))
    assert pid.compute(1.0, 0.0, 0.05) == pytest.approx(5.0)
    pid.set_gains(PidGains(i=100.0, i_clamp_min=-2.0, i_clamp_max=2.0))
    assert pid.compute(0.0, 0.0, 0.05) == pytest.approx(2.0)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("p", -1.0), ("i", -0.5), ("d", -1e-9),
        ("p", math.nan), ("i", math.inf), ("d", -math.inf),
        ("i_clamp_min", math.nan), ("i_clamp_max", "x"),
        ("p", True), ("d", False), ("i", "1.0"), ("p", None),
    ],
)
def test_pid_gains_refuses_bad_values(field: str, value) -> None:
    kw = {"i_clamp_min": -1.0, "i_clamp_max": 1.0, field: value}
    with pytest.raises(ConfigError) as info:
        PidGains(**kw)
    assert info.value.field == f"pid.{field}"
    assert info.value.has_value
    if isinstance(value, float) and math.isnan(value):
        assert math.isnan(info.value.value)
    else:
        assert info.value.value is value or info.value.value == value


def test_pid_gains_refuses_clamp_min_above_max() -> None:
    with pytest.raises(ConfigError) as info:
        PidGains(i=1.0, i_clamp_min=2.0, i_clamp_max=1.0)
    assert info.value.field == "pid.i_clamp_min"
    assert info.value.value == 2.0


def test_pid_gains_accepts_ints_and_zero_width_clamp() -> None:
    g = PidGains(p=400, i=0, d=0, i_clamp_min=-3, i_clamp_max=-3)
    assert (g.p, g.i_clamp_min, g.i_clamp_max) == (400, -3, -3)


# -- from_params ------------------------------------------------------------------------
def pid_params(values: dict) -> Params:
    return Params(values, source="gains.yaml", field="one_DOF_robot.ctl.pid")


def test_from_params_defaults_the_clamp_to_the_given_effort_limit() -> None:
    g = PidGains.from_params(pid_params({"p": 400.0, "i": 2.0}), default_i_clamp=1000.0)
    assert g == PidGains(p=400.0, i=2.0, d=0.0, i_clamp_min=-1000.0, i_clamp_max=1000.0,
                         antiwindup=False)


def test_from_params_empty_mapping_is_all_zero_gains() -> None:
    g = PidGains.from_params(pid_params({}), default_i_clamp=50.0)
    assert (g.p, g.i, g.d, g.i_clamp_min, g.i_clamp_max, g.antiwindup) == (0, 0, 0, -50, 50, False)


def test_from_params_i_clamp_sets_both_bounds() -> None:
    g = PidGains.from_params(pid_params({"i": 1.0, "i_clamp": 5.0}), default_i_clamp=1000.0)
    assert (g.i_clamp_min, g.i_clamp_max) == (-5.0, 5.0)


def test_from_params_explicit_bounds_override_i_clamp() -> None:
    g = PidGains.from_params(pid_params({"i_clamp": 5.0, "i_clamp_max": 7.0}), default_i_clamp=1000.0)
    assert (g.i_clamp_min, g.i_clamp_max) == (-5.0, 7.0)
    g = PidGains.from_params(pid_params({"i_clamp_min": -2.0, "i_clamp_max": 3.0, "antiwindup": True}),
                             default_i_clamp=1000.0)
    assert (g.i_clamp_min, g.i_clamp_max, g.antiwindup) == (-2.0, 3.0, True)


def test_from_params_accepts_publish_state() -> None:
    g = PidGains.from_params(pid_params({"p": 1.0, "publish_state": True}), default_i_clamp=1.0)
    assert g.p == 1.0


@pytest.mark.parametrize("typo", ["P", "kp", "i_clamp_maximum", "anti_windup"])
def test_from_params_refuses_unknown_keys(typo: str) -> None:
    with pytest.raises(ConfigError) as info:
        PidGains.from_params(pid_params({"p": 1.0, typo: 3}), default_i_clamp=1000.0)
    err = info.value
    assert err.field == f"one_DOF_robot.ctl.pid.{typo}"
    assert err.value == 3
    assert err.source == "gains.yaml"
    assert "unknown field" in err.message
    assert f"one_DOF_robot.ctl.pid.{typo}" in str(err)


@pytest.mark.parametrize(
    ("values", "key", "words"),
    [
        ({"p": -5}, "p", "must not be negative"),
        ({"d": "high"}, "d", "must be a number"),
        ({"i": math.nan}, "i", "must be finite"),
        ({"i": True}, "i", "must be a number"),
        ({"i_clamp": -1.0}, "i_clamp", "must not be negative"),
        ({"i_clamp_min": 3.0, "i_clamp_max": 1.0}, "i_clamp_min", "above"),
        ({"antiwindup": "yes"}, "antiwindup", "true or false"),
    ],
)
def test_from_params_refusals_name_the_field(values: dict, key: str, words: str) -> None:
    with pytest.raises(ConfigError) as info:
        PidGains.from_params(pid_params(values), default_i_clamp=1000.0)
    assert info.value.field == f"one_DOF_robot.ctl.pid.{key}"
    assert info.value.source == "gains.yaml"
    assert words in info.value.message


@pytest.mark.parametrize("key", ["i_clamp", "i_clamp_min", "i_clamp_max"])
def test_yaml_clamps_must_be_finite(key: str) -> None:
    from jointctl.control.params import Params
    from jointctl.errors import ConfigError

    params = Params({"p": 1.0, key: math.inf}, source="gains.yaml", field="ns.ctl.pid")
    with pytest.raises(ConfigError, match=rf"gains.yaml: ns.ctl.pid.{key}: must be finite"):
        PidGains.from_params(params, default_i_clamp=10.0)

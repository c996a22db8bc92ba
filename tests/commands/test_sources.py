"""Tests of the command signal sources sampled by the control loop."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from jointctl.errors import ConfigError, ExpressionError
from jointctl.commands.sources import (
    ChirpSource,
    CommandSource,
    ConstantSource,
    ExpressionSource,
    SineSource,
    StepSource,
    command_source_from_config,
)

LOOP_HZ = 1000


def loop_times(seconds: float) -> list[float]:
    """Loop times of a 1 kHz loop, computed as the loop does (cycle / rate)."""
    return [n / LOOP_HZ for n in range(int(seconds * LOOP_HZ))]


def test_constant() -> None:
    source = ConstantSource(-0.3)
    assert [source.sample(t) for t in (0.0, 0.5, 100.0)] == [-0.3, -0.3, -0.3]
    assert source.rejected_samples == 0
    assert source.last_error is None


def test_step_switches_at_its_time() -> None:
    source = StepSource(-0.2, -0.5, 0.5)
    assert source.sample(0.0) == -0.2
    assert source.sample(0.499) == -0.2
    assert source.sample(0.5) == -0.5
    assert source.sample(3.0) == -0.5


def test_a_step_with_a_ramp_moves_in_a_straight_line_over_ramp_s() -> None:
    source = command_source_from_config({"type": "step", "from": -0.2, "to": -0.5, "at": 0.5, "ramp_s": 0.1},
                                        field="commands.c", source="s.yaml")
    assert source.sample(0.499) == -0.2
    assert source.sample(0.5) == -0.2
    assert source.sample(0.525) == pytest.approx(-0.275, abs=1e-12)
    assert source.sample(0.55) == pytest.approx(-0.35, abs=1e-12)
    assert source.sample(0.6) == -0.5
    with pytest.raises(ConfigError, match=r"commands\.c\.ramp_s.*-0\.1") as caught:
        command_source_from_config({"type": "step", "from": 0, "to": 1, "at": 0, "ramp_s": -0.1},
                                   field="commands.c", source="s.yaml")
    assert "0 s or more" in str(caught.value)


def test_chapter_expression_at_100_hz_holds_between_messages() -> None:
    source = ExpressionSource("0.1*sin(i/5)-0.5", rate_hz=100.0)
    for n, t in enumerate(loop_times(2.0)):
        k = n // 10  # 10 loop cycles per message at 1 kHz / 100 Hz
        t_k = k / 100.0
        assert source.sample(t) == pytest.approx(0.1 * math.sin(20.0 * t_k) - 0.5, abs=1e-15)
    assert source.sample(0.0) == -0.5
    assert source.sample(0.009) == -0.5  # held until message 1 at 0.01 s
    assert source.sample(0.01) == pytest.approx(0.1 * math.sin(0.2) - 0.5)
    assert source.rejected_samples == 0


def test_expression_with_time_uses_message_time() -> None:
    source = ExpressionSource("t", rate_hz=4.0)
    assert [source.sample(t) for t in (0.0, 0.2, 0.25, 0.3, 0.74, 0.75)] == [0.0, 0.0, 0.25, 0.25, 0.5, 0.75]


def test_message_index_tolerates_rounding_of_loop_time() -> None:
    source = ExpressionSource("i", rate_hz=100.0)
    # 0.07 * 100 == 7.000000000000001, 0.29 * 100 == 28.999999999999996
    assert source.sample(0.07) == 7.0
    assert source.sample(0.29) == 29.0
    assert source.sample(0.0299) == 2.0


def test_expression_evaluates_once_per_message() -> None:
    source = ExpressionSource("i", rate_hz=100.0)
    calls = 0
    evaluate = source.expression.evaluate

    class Counting:
        def evaluate(self, i: float, t: float) -> float:
            nonlocal calls
            calls += 1
            return evaluate(i, t)

    source.expression = Counting()  # type: ignore[assignment]
    for t in loop_times(1.0):
        source.sample(t)
    assert calls == 100


def test_sine_matches_the_sine_commander() -> None:
    source = SineSource(0.1, 3.0, offset=-0.5, rate_hz=100.0)
    velocity = SineSource(0.1, 3.0, offset=-0.5, rate_hz=100.0, derivative=True)
    omega = 2 * math.pi * 3.0
    for n, t in enumerate(loop_times(1.0)):
        t_k = (n // 10) / 100.0
        assert source.sample(t) == pytest.approx(-0.5 + 0.1 * math.sin(omega * t_k), abs=1e-15)
        assert velocity.sample(t) == pytest.approx(omega * 0.1 * math.cos(omega * t_k), abs=1e-14)
    assert source.sample(1 / 36) == pytest.approx(-0.5 + 0.1 * math.sin(omega * 0.02))  # held 0.02 s message
    assert velocity.sample(0.0) == pytest.approx(0.6 * math.pi)


def test_sine_zero_frequency_is_its_offset() -> None:
    assert SineSource(2.0, 0.0, offset=0.25).sample(1.234) == 0.25


def test_runtime_error_holds_last_value_and_counts() -> None:
    source = ExpressionSource("1/(i-3)", rate_hz=10.0, field="cmd.expression", source="s.yaml")
    values = [source.sample(t) for t in (0.0, 0.1, 0.2, 0.3, 0.33, 0.36, 0.4, 0.5)]
    assert values == pytest.approx([-1 / 3, -1 / 2, -1.0, -1.0, -1.0, -1.0, 1.0, 0.5])
    # the failed message is evaluated once, not once per loop cycle
    assert source.rejected_samples == 1
    assert source.last_error is not None
    assert "division by zero" in source.last_error
    assert "i=3, t=0.3 s" in source.last_error
    assert source.last_error.startswith("s.yaml: cmd.expression: ")


def test_last_error_keeps_the_first_error() -> None:
    source = ExpressionSource("sqrt(2 - i)", rate_hz=1.0)
    assert [source.sample(float(k)) for k in range(5)] == pytest.approx([math.sqrt(2), 1.0, 0.0, 0.0, 0.0])
    assert source.rejected_samples == 2
    assert source.last_error is not None and "i=3," in source.last_error


def test_failing_first_sample_raises() -> None:
    source = ExpressionSource("log(t)", rate_hz=100.0)
    with pytest.raises(ExpressionError, match=r"math domain error"):
        source.sample(0.0)
    with pytest.raises(ExpressionError):  # still nothing to hold
        source.sample(0.005)
    assert source.sample(0.01) == pytest.approx(math.log(0.01))
    assert source.rejected_samples == 2


def test_reset_clears_cache_and_counts() -> None:
    source = ExpressionSource("1/(i-1)", rate_hz=1.0)
    source.sample(0.0)
    source.sample(1.0)
    assert source.rejected_samples == 1
    source.reset()
    assert source.rejected_samples == 0
    assert source.last_error is None
    assert source.sample(2.0) == 1.0
    sine = SineSource(1.0, 1.0, rate_hz=4.0)
    assert sine.sample(0.25) == pytest.approx(1.0)
    sine.reset()
    assert sine.sample(0.0) == 0.0


def test_bad_expression_is_refused_at_construction() -> None:
    with pytest.raises(ExpressionError, match=r"unknown function '__import__'"):
        ExpressionSource("__import__('os')")


def test_constructors_validate() -> None:
    with pytest.raises(ConfigError, match="finite"):
        ConstantSource(math.nan)
    with pytest.raises(ConfigError, match="must be a number"):
        StepSource(True, 1.0, 0.5)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="rate must be above 0"):
        SineSource(1.0, 1.0, rate_hz=0.0)
    with pytest.raises(ConfigError, match="frequency"):
        SineSource(1.0, -1.0)
    with pytest.raises(ConfigError, match="rate must be above 0"):
        ExpressionSource("t", rate_hz=-5.0)


# --- factory -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("config", "times", "expected"),
    [
        ({"type": "constant", "value": -0.3}, [0.0, 1.0], [-0.3, -0.3]),
        ({"type": "constant", "value": 2}, [0.0], [2.0]),
        ({"type": "step", "from": -0.2, "to": -0.5, "at": 0.5}, [0.0, 0.5], [-0.2, -0.5]),
        (
            {"type": "sine", "amplitude": 0.1, "frequency_hz": 3, "offset": -0.5, "rate_hz": 100, "derivative": False},
            [0.0, 0.025],
            [-0.5, -0.5 + 0.1 * math.sin(2 * math.pi * 3 * 0.02)],
        ),
        ({"type": "sine", "amplitude": 1, "frequency_hz": 1}, [0.25], [1.0]),
        (
            {"type": "sine", "amplitude": 0.1, "frequency_hz": 3, "derivative": True},
            [0.0],
            [0.6 * math.pi],
        ),
        (
            {"type": "expression", "expression": "0.1*sin(i/5)-0.5", "rate_hz": 100},
            [0.0, 0.015],
            [-0.5, 0.1 * math.sin(0.2) - 0.5],
        ),
        ({"type": "expression", "expression": "i"}, [0.0, 0.0199, 0.02], [0.0, 1.0, 2.0]),
    ],
)
def test_factory_builds_sources(config: dict[str, Any], times: list[float], expected: list[float]) -> None:
    source = command_source_from_config(config, field="cmd", source="s.yaml")
    assert isinstance(source, CommandSource)
    assert [source.sample(t) for t in times] == pytest.approx(expected, abs=1e-12)


def test_factory_types() -> None:
    def build(config: dict[str, Any]) -> CommandSource:
        return command_source_from_config(config, field="cmd", source=None)

    assert build({"type": "constant", "value": 1}) == ConstantSource(1.0)
    assert build({"type": "step", "from": 0, "to": 1, "at": 2}) == StepSource(0.0, 1.0, 2.0)
    sine = build({"type": "sine", "amplitude": 1, "frequency_hz": 2, "rate_hz": 50})
    assert sine == SineSource(1.0, 2.0, 0.0, 50.0, False)
    expression = build({"type": "expression", "expression": "t", "rate_hz": 10})
    assert isinstance(expression, ExpressionSource)
    assert expression.rate_hz == 10.0
    assert expression.expression_text == "t"


_UNSET = object()


@pytest.mark.parametrize(
    ("config", "field", "value", "words"),
    [
        ({"type": "ramp", "value": 1}, "cmd.type", "ramp", "unknown command source type"),
        ({"type": 3}, "cmd.type", 3, "unknown command source type"),
        ({"value": 1}, "cmd.type", _UNSET, "missing key 'type'"),
        ({"type": "constant"}, "cmd.value", _UNSET, "missing key"),
        ({"type": "constant", "value": 1, "unit": "rad"}, "cmd.unit", "rad", "unknown key"),
        ({"type": "constant", "value": "fast"}, "cmd.value", "fast", "must be a number"),
        ({"type": "constant", "value": "1e-3"}, "cmd.value", "1e-3", "1.0e-3"),
        ({"type": "constant", "value": True}, "cmd.value", True, "must be a number"),
        ({"type": "constant", "value": None}, "cmd.value", None, "must be a number"),
        ({"type": "constant", "value": math.inf}, "cmd.value", math.inf, "finite"),
        ({"type": "step", "from": 0, "to": 1}, "cmd.at", _UNSET, "missing key"),
        ({"type": "step", "from": 0, "to": math.nan, "at": 1}, "cmd.to", math.nan, "finite"),
        ({"type": "sine", "amplitude": 1, "frequency_hz": 1, "rate_hz": 0}, "cmd.rate_hz", 0, "above 0"),
        ({"type": "sine", "amplitude": 1, "frequency_hz": 1, "rate_hz": -10}, "cmd.rate_hz", -10, "above 0"),
        ({"type": "sine", "amplitude": 1, "frequency_hz": -2}, "cmd.frequency_hz", -2, "0 Hz or more"),
        ({"type": "sine", "amplitude": False, "frequency_hz": 1}, "cmd.amplitude", False, "must be a number"),
        ({"type": "sine", "amplitude": 1, "frequency_hz": 1, "derivative": "yes"}, "cmd.derivative", "yes", "true or false"),
        ({"type": "sine", "amplitude": 1, "frequency_hz": 1, "phase": 0.5}, "cmd.phase", 0.5, "unknown key"),
        ({"type": "expression", "expression": 0.5}, "cmd.expression", 0.5, "must be a string"),
        ({"type": "expression", "expression": "t", "rate_hz": "100"}, "cmd.rate_hz", "100", "must be a number"),
        ({"type": "expression", "expression": "t", "amplitude": 1}, "cmd.amplitude", 1, "unknown key"),
    ],
)
def test_factory_errors_name_field_and_value(config: dict[str, Any], field: str, value: object, words: str) -> None:
    with pytest.raises(ConfigError) as info:
        command_source_from_config(config, field="cmd", source="s.yaml")
    error = info.value
    assert error.field == field
    assert error.source == "s.yaml"
    assert words in str(error)
    assert str(error).startswith(f"s.yaml: {field}: ")
    if value is _UNSET:
        assert not error.has_value
    elif isinstance(value, float) and math.isnan(value):
        assert math.isnan(error.value)
    else:
        assert error.value == value and type(error.value) is type(value)
        assert f"(got {value!r})" in str(error)


def test_factory_refuses_non_mapping() -> None:
    with pytest.raises(ConfigError, match=r"s.yaml: cmd: a command source must be a mapping") as info:
        command_source_from_config([1, 2], field="cmd", source="s.yaml")  # type: ignore[arg-type]
    assert info.value.value == [1, 2]


def test_factory_expression_error_names_the_field() -> None:
    with pytest.raises(ExpressionError) as info:
        command_source_from_config({"type": "expression", "expression": "(1).real"}, field="cmd", source="s.yaml")
    assert info.value.field == "cmd.expression"
    assert info.value.source == "s.yaml"
    assert str(info.value).startswith("s.yaml: cmd.expression: attribute access is not allowed at column 1")


def test_extremes_bound_every_value_a_source_sends() -> None:
    # What a controller's limits are checked against before the run: each bound with the key that sets it.
    assert ConstantSource(-0.3).extremes() == (("value", -0.3),)
    assert StepSource(-0.2, -0.5, 0.5).extremes() == (("from", -0.2), ("to", -0.5))
    sine = SineSource(-0.1, 3.0, offset=-0.5)  # a negative amplitude is the same crests, half a period later
    assert sine.extremes() == (("offset", -0.5), ("amplitude", pytest.approx(-0.4)), ("amplitude", -0.6))
    sent = [sine.sample(k / 1000) for k in range(1000)]
    assert -0.6 <= min(sent) and max(sent) <= -0.4
    velocity = SineSource(0.1, 3.0, derivative=True)
    assert velocity.extremes() == (("amplitude", pytest.approx(2 * math.pi * 0.3)),
                                   ("amplitude", pytest.approx(-2 * math.pi * 0.3)))
    assert ExpressionSource("sin(t)").extremes() == ()  # known only as it runs


def test_a_chirp_sweeps_its_frequency_in_a_straight_line_and_rests_at_its_offset_outside() -> None:
    chirp = ChirpSource(0.05, 1.0, 9.0, 4.0, offset=-0.5, at_s=1.0)
    assert chirp.sample(0.999) == chirp.sample(5.001) == -0.5
    times = np.arange(1.0, 5.0, 1e-5)
    values = np.array([chirp.sample(t) for t in times]) + 0.5
    assert np.abs(values).max() == pytest.approx(0.05, rel=1e-6)
    # Upward zero crossings are one period apart: the period there is 1/f(τ), f(τ) = 1 + 8·τ/4 Hz.
    rising = times[1:][(values[:-1] < 0) & (values[1:] >= 0)]
    middle = (rising[1:] + rising[:-1]) / 2 - 1.0
    measured = 1.0 / np.diff(rising)
    assert len(rising) == 19  # the phase runs 2π·(1·4 + ½·8·4) = 2π·20: rising through 2π·1 ... 2π·19 inside
    assert measured == pytest.approx(1.0 + 2.0 * middle, rel=2e-3)


def test_a_chirp_from_the_scenario_mapping_and_its_refusals() -> None:
    chirp = command_source_from_config({"type": "chirp", "amplitude": 0.1, "f_start_hz": 0.5, "f_end_hz": 5,
                                        "duration_s": 2, "offset": 0.2, "at": 1}, field="cmd", source="s.yaml")
    assert chirp == ChirpSource(0.1, 0.5, 5.0, 2.0, 0.2, 1.0)
    assert chirp.extremes() == (("offset", 0.2), ("amplitude", pytest.approx(0.3)), ("amplitude", 0.1))
    for key, value, words in (("duration_s", 0, "above 0 s"), ("f_end_hz", -1, "0 Hz or more"),
                              ("f_start_hz", "x", "must be a number")):
        config = {"type": "chirp", "amplitude": 0.1, "f_start_hz": 0.5, "f_end_hz": 5, "duration_s": 2, key: value}
        with pytest.raises(ConfigError, match=words) as info:
            command_source_from_config(config, field="cmd", source="s.yaml")
        assert info.value.field == f"cmd.{key}" and info.value.value == value

"""--spec: terms, verdicts, and the metric names it is checked against."""

from __future__ import annotations

import pytest

from jointctl.errors import ConfigError
from jointctl.sweep.criteria import parse_spec


def test_terms_bound_metrics_from_above_or_below():
    spec = parse_spec("overshoot_pct<=10, settling_time_s<0.3,damping_ratio>=0.5, x.y>-1e-3")
    assert [(t.metric, t.op, t.limit) for t in spec.terms] == [
        ("overshoot_pct", "<=", 10.0), ("settling_time_s", "<", 0.3), ("damping_ratio", ">=", 0.5),
        ("x.y", ">", -0.001)]
    assert [t.upper for t in spec.terms] == [True, True, False, False]
    assert str(spec) == "overshoot_pct<=10,settling_time_s<0.3,damping_ratio>=0.5,x.y>-0.001"


def test_a_run_passes_when_every_term_holds_and_an_unmeasured_metric_fails():
    spec = parse_spec("overshoot_pct<=10,settling_time_s<=0.3")
    assert spec.verdict({"overshoot_pct": 10.0, "settling_time_s": 0.2}) is True
    assert spec.verdict({"overshoot_pct": 10.01, "settling_time_s": 0.2}) is False
    assert spec.verdict({"overshoot_pct": 5.0, "settling_time_s": None}) is False  # never settled
    assert spec.verdict({"overshoot_pct": 5.0}) is False
    assert parse_spec(None).verdict({"a": 1.0}) is None and not parse_spec("  ")


@pytest.mark.parametrize("text, bad", [("overshoot_pct=10", "overshoot_pct=10"), ("a<=ten", "a<=ten"),
                                       ("a<=1,,b<=2", ""), ("<=3", "<=3"), ("a<=nan", "a<=nan")])
def test_malformed_terms_are_refused_naming_the_term(text, bad):
    with pytest.raises(ConfigError) as caught:
        parse_spec(text)
    assert caught.value.field == "--spec" and caught.value.value == bad


def test_a_metric_the_analysis_does_not_report_is_named_with_the_nearest():
    spec = parse_spec("overshot_pct<=10")
    with pytest.raises(ConfigError, match="did you mean 'overshoot_pct'") as caught:
        spec.check_metrics(["overshoot_pct", "settling_time_s"])
    assert caught.value.field == "--spec" and caught.value.value == "overshot_pct"
    parse_spec("settling_time_s<=1").check_metrics(["overshoot_pct", "settling_time_s"])

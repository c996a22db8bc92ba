"""--vary parsing (grids, lists, distributions, and what is refused) and the runs a sweep expands to."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.errors import ConfigError
from jointctl.scenario.spec import parse_override
from jointctl.sweep.variations import (check_samples, expand, noise_seed, parse_variation, variations_from,
                                       yaml_text)


def test_a_grid_is_evenly_spaced_from_a_to_b():
    v = parse_variation("payload_kg=0:5:6")
    assert v.field == "payload_kg" and not v.is_distribution
    assert v.values == (0.0, 1.0, 2.0, 3.0, 4.0, 5.0)
    assert parse_variation("gravity=-9.81:-1.62:2").values == (-9.81, -1.62)


def test_a_list_is_read_as_yaml():
    assert parse_variation("controllers.c.pid.p=[200, 4e2, 1_000]").values == (200, 400.0, 1000)
    assert parse_variation("controller_file=[position, velocity]").values == ("position", "velocity")


def test_a_list_may_be_written_without_brackets():
    for field, text in (("payload_kg", "0,5"), ("payload_kg", " 0, 2.5 ,5 "), ("controller_file", "position,velocity")):
        assert parse_variation(f"{field}={text}").values == parse_variation(f"{field}=[{text}]").values
    assert parse_variation("payload_kg=0,5").values == (0, 5)
    with pytest.raises(ConfigError, match="a list is") as caught:
        parse_variation("payload_kg=0,,5")
    assert caught.value.field == "payload_kg" and caught.value.value == "0,,5"


def test_distributions_draw_from_their_parameters():
    uniform, normal = parse_variation("model.joint1.damping=uniform(7, 13)"), parse_variation("x=normal(10,3)")
    assert uniform.distribution == "uniform" and uniform.params == (7.0, 13.0) and uniform.representative == 10.0
    assert normal.distribution == "normal" and normal.params == (10.0, 3.0) and normal.representative == 10.0
    rng = np.random.default_rng(0)
    draws = np.array([normal.draw(rng) for _ in range(4000)])
    # The sample mean and standard deviation of n draws are within 4 standard errors: σ/√n and σ/√(2n).
    assert abs(draws.mean() - 10.0) < 4 * 3 / np.sqrt(4000)
    assert abs(draws.std() - 3.0) < 4 * 3 / np.sqrt(2 * 4000)
    low = [uniform.draw(rng) for _ in range(1000)]
    assert 7 <= min(low) and max(low) <= 13


@pytest.mark.parametrize("item, field, says", [
    ("foo=1:2", "foo", "a grid is a:b:n"),
    ("foo=1:2:3:4", "foo", "a grid is a:b:n"),
    ("payload_kg=0:x:3", "payload_kg", "a grid's end must be a finite number"),
    ("payload_kg=0:5:2.5", "payload_kg", "whole number, 2 or more"),
    ("payload_kg=0:5:1", "payload_kg", "whole number, 2 or more"),
    ("payload_kg=[]", "payload_kg", "one value or more"),
    ("payload_kg=[[1], 2]", "payload_kg", "finite numbers, true/false or words"),
    ("payload_kg=[1, .nan]", "payload_kg", "finite numbers"),
    ("payload_kg=[1, 2", "payload_kg", "a list is"),
    ("payload_kg=gauss(1, 2)", "payload_kg", "unknown distribution"),
    ("payload_kg=uniform(1)", "payload_kg", "uniform takes two numbers"),
    ("payload_kg=uniform(3, 1)", "payload_kg", "a < b"),
    ("payload_kg=normal(3, 0)", "payload_kg", "positive sigma"),
    ("payload_kg=normal(3, inf)", "payload_kg", "finite number"),
    ("payload_kg=3", "payload_kg", "a single value is a --set"),
])
def test_malformed_values_are_refused_naming_the_field_and_what_was_given(item, field, says):
    with pytest.raises(ConfigError) as caught:
        parse_variation(item)
    assert caught.value.source == "--vary" and caught.value.field == field
    assert says in caught.value.message
    assert caught.value.value == item.partition("=")[2]


@pytest.mark.parametrize("item", ["1:2:3", "=1:2:3", "a..b=1:2:3", "payload_kg"])
def test_an_item_without_a_field_is_refused(item):
    with pytest.raises(ConfigError, match="expected FIELD=VALUES"):
        parse_variation(item)


def test_unknown_fields_are_named_with_the_nearest_known_one():
    for given, nearest in (("payload=0:1:2", "payload_kg"), ("gravty=[1, 2]", "gravity"),
                           ("noise.postion=[0, 1]", "noise.position"), ("latency=[0, 1]", "latency_cycles")):
        with pytest.raises(ConfigError) as caught:
            variations_from([given])
        assert caught.value.field == given.partition("=")[0]
        assert f"did you mean {nearest!r}" in caught.value.message


def test_nothing_to_vary_and_a_field_varied_twice_are_refused():
    with pytest.raises(ConfigError, match="nothing to vary"):
        variations_from([])
    with pytest.raises(ConfigError, match="varied twice"):
        variations_from(["payload_kg=0:1:2", "payload_kg=[3]"])


def test_a_grid_of_latencies_holds_whole_numbers():
    (v,) = variations_from(["latency_cycles=0:4:5"])
    assert v.values == (0, 1, 2, 3, 4) and all(isinstance(x, int) for x in v.values)


def test_samples_are_needed_with_a_distribution_and_must_be_positive():
    grid, normal = parse_variation("payload_kg=0:1:2"), parse_variation("x=normal(0, 1)")
    assert check_samples(None, 0, [grid]) == 1
    with pytest.raises(ConfigError, match="number of samples") as caught:
        check_samples(None, 0, [grid, normal])
    assert caught.value.field == "--samples"
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ConfigError):
            check_samples(bad, 0, [normal])
    with pytest.raises(ConfigError) as caught:
        check_samples(3, -1, [normal])
    assert caught.value.field == "--seed"


def test_grids_make_a_full_factorial_the_first_varying_slowest():
    runs = expand([parse_variation("a=[1, 2]"), parse_variation("b=[10, 20, 30]")], 1, 0)
    assert runs == [{"a": 1, "b": 10}, {"a": 1, "b": 20}, {"a": 1, "b": 30},
                    {"a": 2, "b": 10}, {"a": 2, "b": 20}, {"a": 2, "b": 30}]


def test_every_grid_point_sees_the_same_draws_and_the_seed_decides_them():
    variations = [parse_variation("a=[1, 2]"), parse_variation("d=uniform(0, 1)")]
    runs = expand(variations, 3, 7)
    assert [r["a"] for r in runs] == [1, 1, 1, 2, 2, 2]
    draws = [r["d"] for r in runs]
    assert draws[:3] == draws[3:] and len(set(draws[:3])) == 3  # common random numbers across grid points
    assert expand(variations, 3, 7) == runs
    assert [r["d"] for r in expand(variations, 3, 8)][:3] != draws[:3]
    # The first draws do not change when more samples are asked for: draw k depends on (seed, k) only.
    assert [r["d"] for r in expand(variations, 5, 7)][:3] == draws[:3]


def test_a_latency_drawn_from_a_distribution_is_a_whole_number_of_cycles():
    runs = expand(variations_from(["latency_cycles=uniform(0, 4)"]), 20, 0)
    assert all(isinstance(r["latency_cycles"], int) and 0 <= r["latency_cycles"] <= 4 for r in runs)


def test_noise_seeds_differ_per_run_and_from_the_draws():
    assert noise_seed(1, 0) != noise_seed(1, 1) != noise_seed(2, 1)


@pytest.mark.parametrize("value", [0.1, 1e-05, -250.0, 3, 1_000_000, True, False, "position", "1e3", "a: b"])
def test_values_reach_the_scenario_as_they_were(value):
    key, back = parse_override(f"x={yaml_text(value)}")
    assert back == value and type(back) is type(value)

"""Every way a page's message can be refused, and what the accepted ones become."""

from __future__ import annotations

import json

import pytest

from jointctl.errors import ConfigError, ExpressionError, JointCtlError
from jointctl.commands.sources import ExpressionSource, StepSource
from jointctl.tuning.requests import (MAX_REQUEST_CHARS, Control, RequestError, SelectJoint, SetGain, SetGravity,
                                      SetSource, parse_request)


def parse(message) -> object:
    return parse_request(json.dumps(message))


def test_accepted_requests_become_typed_requests():
    assert parse({"type": "gain", "controller": "c", "name": "p", "value": 1600}) == SetGain("c", "p", 1600)
    assert parse({"type": "joint", "joint": "joint1"}) == SelectJoint("joint1")
    assert parse({"type": "gravity", "value": 0}) == SetGravity(0.0)
    for action in ("pause", "resume", "reset", "drop_weight", "save_gains"):
        assert parse({"type": action}) == Control(action)
    step = parse({"type": "source", "controller": "c", "source": {"type": "step", "from": -0.5, "to": -0.3, "at": 1}})
    assert isinstance(step, SetSource) and isinstance(step.source, StepSource)
    assert step.description == {"type": "step", "from": -0.5, "to": -0.3, "at": 1}
    expression = parse({"type": "source", "controller": "c",
                        "source": {"type": "expression", "expression": "0.1*sin(i/5)-0.5", "rate_hz": 100}})
    assert isinstance(expression.source, ExpressionSource)
    assert expression.source.sample(0.0) == pytest.approx(-0.5)
    hold = parse({"type": "source", "controller": "c", "source": {"type": "hold"}})
    assert hold.source is None and hold.description == {"type": "hold"}


@pytest.mark.parametrize("text, field, words", [
    (b"{}", "message", "JSON text"),
    ("{", "message", "not JSON"),
    ('{"type": "gravity", "value": NaN}', "message", "not a JSON number"),
    ("[1, 2]", "message", "JSON object"),
    ('{"type": "launch"}', "type", "unknown request"),
    ('{"value": 1}', "type", "unknown request"),
    ('{"type": "pause", "now": true}', "now", "unknown key"),
    ('{"type": "gain", "controller": "c", "name": "p"}', "value", "missing"),
    ('{"type": "gain", "controller": 3, "name": "p", "value": 1}', "controller", "must be a string"),
    ('{"type": "joint", "joint": null}', "joint", "must be a string"),
    ('{"type": "gravity", "value": "down"}', "gravity", "finite number"),
    ('{"type": "gravity", "value": true}', "gravity", "finite number"),
    ('{"type": "gravity", "value": 1e400}', "gravity", "finite number"),
    ('{"type": "source", "controller": "c", "source": {"type": "hold", "value": 1}}', "source", "no parameters"),
])
def test_malformed_messages_are_refused_naming_the_field(text, field, words):
    with pytest.raises(RequestError) as caught:
        parse_request(text)
    assert caught.value.field == field
    assert words in str(caught.value)


def test_a_message_beyond_the_limit_is_refused_before_parsing():
    with pytest.raises(RequestError, match="too long"):
        parse_request(" " * (MAX_REQUEST_CHARS + 1))


@pytest.mark.parametrize("source, field, words", [
    ({"type": "ramp"}, "source.type", "unknown command source type"),
    ({"type": "constant"}, "source.value", "missing key"),
    ({"type": "constant", "value": "0.1; rm -rf /"}, "source.value", "must be a number"),
    ({"type": "sine", "amplitude": 0.1, "frequency_hz": -1}, "source.frequency_hz", "0 Hz or more"),
    ({"type": "sine", "amplitude": 0.1, "frequency_hz": 1, "rate_hz": 0}, "source.rate_hz", "above 0 Hz"),
    ({"type": "step", "from": 0, "to": 1, "at": 1, "by": 2}, "source.by", "unknown key"),
    ({"type": "expression", "expression": 5}, "source.expression", "must be a string"),
])
def test_bad_sources_are_refused_naming_the_field(source, field, words):
    with pytest.raises(ConfigError) as caught:
        parse({"type": "source", "controller": "c", "source": source})
    assert caught.value.field == field and words in str(caught.value)


@pytest.mark.parametrize("expression, words", [
    ("__import__('os')", "unknown function '__import__'"),
    ("().__class__.__bases__", "attribute access is not allowed"),
    ("open('/etc/passwd')", "unknown function 'open'"),
    ("[x for x in ()]", "not allowed"),
    ("lambda: 1", "not allowed"),
    ("0.1*sin(i/5", "source.expression"),
    ("x" * 10_000_000, "too long (10000000 characters"),
    ("log(t)", "log"),  # fails at its first message (t = 0): refused, not deferred
])
def test_hostile_or_failing_expressions_are_refused_and_never_run(expression, words):
    with pytest.raises(ExpressionError) as caught:
        parse({"type": "source", "controller": "c", "source": {"type": "expression", "expression": expression}})
    assert caught.value.field == "source.expression"
    assert words in str(caught.value)
    assert isinstance(caught.value, JointCtlError)


def test_analysis_requests_carry_their_spec_with_defaults():
    from jointctl.tuning.requests import Analyse

    assert parse_request('{"type": "identify", "controller": "c"}') == Analyse("identify", "c", {})
    assert parse_request('{"type": "autotune", "controller": "c", "bandwidth_hz": 5}') == \
        Analyse("autotune", "c", {"bandwidth_hz": 5.0, "zeta": 0.7, "step": 0.1})


@pytest.mark.parametrize("text, field", [
    ('{"type": "autotune", "controller": "c"}', "bandwidth_hz"),
    ('{"type": "autotune", "controller": "c", "bandwidth_hz": -5}', "bandwidth_hz"),
    ('{"type": "autotune", "controller": "c", "bandwidth_hz": 5, "zeta": "x"}', "zeta"),
    ('{"type": "bode", "controller": 3}', "controller"),
    ('{"type": "identify", "controller": "c", "joint": "j"}', "joint"),
])
def test_bad_analysis_requests_are_refused_naming_the_field(text, field):
    with pytest.raises(RequestError) as info:
        parse_request(text)
    assert info.value.field == field

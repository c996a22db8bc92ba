"""Tests of Params: typed reads whose refusals name ``<field>.<key>``, the value and the file."""

from __future__ import annotations

import math

import pytest

from jointctl.control.params import Params
from jointctl.errors import ConfigError

SOURCE = "config/gains.yaml"
FIELD = "one_DOF_robot.joint1_position_controller"


def params(**values) -> Params:
    return Params(values, source=SOURCE, field=FIELD)


def refusal(call) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        call()
    return info.value


# -- construction and paths -------------------------------------------------------------
@pytest.mark.parametrize("values", [None, 3, "p: 1", [1, 2]])
def test_params_must_be_a_mapping(values) -> None:
    err = refusal(lambda: Params(values, source=SOURCE, field=FIELD))
    assert err.field == FIELD
    assert err.source == SOURCE
    assert err.value == values


def test_path_joins_field_and_key() -> None:
    assert params().path("pid") == f"{FIELD}.pid"
    assert Params({}, source=None, field="").path("pid") == "pid"


def test_values_are_copied() -> None:
    raw = {"p": 1.0}
    p = Params(raw, source=None, field="x")
    raw["p"] = 2.0
    assert p.number("p") == 1.0


def test_error_text_reads_source_field_message_value() -> None:
    err = refusal(lambda: params(p=-5).number("p", minimum=0))
    assert str(err) == f"{SOURCE}: {FIELD}.p: must not be negative (got -5.0)"


# -- number -------------------------------------------------------------------------------
def test_number_returns_float() -> None:
    p = params(a=3, b=-2.5)
    assert p.number("a") == 3.0 and isinstance(p.number("a"), float)
    assert p.number("b") == -2.5


def test_number_default_when_missing_and_required_otherwise() -> None:
    p = params()
    assert p.number("rate", 50.0) == 50.0
    assert p.number("clamp", None) is None
    err = refusal(lambda: p.number("rate"))
    assert err.field == f"{FIELD}.rate"
    assert "is required" in err.message
    assert not err.has_value


@pytest.mark.parametrize("value", ["400", "fast", None, True, False, [1.0], {"v": 1}])
def test_number_refuses_non_numbers(value) -> None:
    err = refusal(lambda: params(gain=value).number("gain", 1.0))
    assert err.field == f"{FIELD}.gain"
    assert err.value == value and type(err.value) is type(value)
    assert "must be a number" in err.message
    assert f"{FIELD}.gain" in str(err) and repr(value) in str(err)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_number_refuses_non_finite(value: float) -> None:
    err = refusal(lambda: params(gain=value).number("gain"))
    assert err.field == f"{FIELD}.gain"
    assert "must be finite" in err.message
    assert repr(value) in str(err)


@pytest.mark.parametrize("value", [0, 0.0, -1, -1e-12])
def test_number_positive_refuses_zero_and_negative(value: float) -> None:
    err = refusal(lambda: params(rate=value).number("rate", positive=True))
    assert err.field == f"{FIELD}.rate"
    assert err.value == value
    assert "must be positive" in err.message


def test_number_minimum() -> None:
    assert params(p=0).number("p", minimum=0) == 0.0
    err = refusal(lambda: params(p=-0.1).number("p", minimum=0))
    assert (err.field, err.value, err.message) == (f"{FIELD}.p", -0.1, "must not be negative")
    err = refusal(lambda: params(n=1.5).number("n", minimum=2))
    assert (err.field, err.value) == (f"{FIELD}.n", 1.5)
    assert "at least 2" in err.message
    assert params(n=2).number("n", minimum=2) == 2.0


# -- string and boolean -----------------------------------------------------------------
def test_string() -> None:
    assert params(joint="joint1").string("joint") == "joint1"
    assert params().string("joint", "j0") == "j0"
    for value in ("", 5, None, ["joint1"]):
        err = refusal(lambda v=value: params(joint=v).string("joint"))
        assert err.field == f"{FIELD}.joint"
        assert err.value == value
        assert "non-empty string" in err.message
    err = refusal(lambda: params().string("joint"))
    assert err.field == f"{FIELD}.joint" and "is required" in err.message


def test_boolean() -> None:
    assert params(antiwindup=True).boolean("antiwindup") is True
    assert params(antiwindup=False).boolean("antiwindup", True) is False
    assert params().boolean("antiwindup", False) is False
    for value in ("true", "yes", 1, 0, None, 1.0):
        err = refusal(lambda v=value: params(antiwindup=v).boolean("antiwindup"))
        assert err.field == f"{FIELD}.antiwindup"
        assert err.value == value and type(err.value) is type(value)
        assert "true or false" in err.message


# -- child --------------------------------------------------------------------------------
def test_child_extends_the_field_path() -> None:
    pid = params(pid={"p": -1}).child("pid")
    assert pid.field == f"{FIELD}.pid"
    assert pid.source == SOURCE
    err = refusal(lambda: pid.number("p", minimum=0))
    assert err.field == f"{FIELD}.pid.p"


def test_child_must_be_a_mapping() -> None:
    err = refusal(lambda: params(pid=400).child("pid"))
    assert err.field == f"{FIELD}.pid"
    assert err.value == 400
    err = refusal(lambda: params().child("pid"))
    assert err.field == f"{FIELD}.pid" and "is required" in err.message


# -- reject_unknown -------------------------------------------------------------------------
def test_reject_unknown_names_the_first_unread_key() -> None:
    p = params(joint="joint1", jiont="joint2")
    p.string("joint")
    err = refusal(p.reject_unknown)
    assert err.field == f"{FIELD}.jiont"
    assert err.value == "joint2"
    assert err.message == "unknown field (did you mean 'joint'? known: joint)"


def test_reject_unknown_lists_keys_asked_about_with_has() -> None:
    """An optional block the controller asks about (``has("feedforward")``) is a key it accepts."""
    p = params(joint="joint1", pidd={"p": 1})
    p.string("joint")
    assert not p.has("pid") and not p.has("feedforward")
    err = refusal(lambda: p.reject_unknown({"type"}))
    assert err.field == f"{FIELD}.pidd"
    assert err.message == "unknown field (did you mean 'pid'? known: feedforward, joint, pid, type)"


def test_reject_unknown_without_a_near_key_only_lists_them() -> None:
    p = params(joint="joint1", gains={"p": 1})
    p.string("joint")
    err = refusal(p.reject_unknown)
    assert err.message == "unknown field (known: joint)"


@pytest.mark.parametrize("typo", ["jont", "jiont", "Joint", "joitn", "jnt", "joints"])
def test_a_misspelt_required_key_is_reported_as_unknown_not_missing(typo) -> None:
    p = params(type="x", **{typo: "joint1"}, pid={"p": 1.0})
    p.string("type")
    err = refusal(lambda: p.string("joint"))
    assert err.field == f"{FIELD}.{typo}"
    assert err.value == "joint1"
    assert err.message == "unknown field (did you mean 'joint'?)"


@pytest.mark.parametrize("other", ["wrist_joints", "joint_damping", "gains", "jointed_arm"])
def test_a_different_key_beside_a_missing_required_one_is_not_taken_for_a_typo(other) -> None:
    """A key that merely shares a word with the missing one may be read later: still "is required"."""
    p = params(**{other: 1})
    err = refusal(lambda: p.raw("joints" if other == "wrist_joints" else "joint"))
    assert "is required" in err.message and err.field in (f"{FIELD}.joint", f"{FIELD}.joints")


def test_a_key_already_read_is_not_taken_for_a_typo() -> None:
    p = params(joints=["a"])
    p.raw("joints")
    err = refusal(lambda: p.raw("joint"))
    assert err.field == f"{FIELD}.joint" and "is required" in err.message


def test_reject_unknown_accepts_read_and_allowed_keys() -> None:
    p = params(type="x", joint="joint1", rate=3)
    p.string("joint")
    p.number("rate", 0.0)
    p.reject_unknown({"type"})  # no error
    q = params(type="x")
    err = refusal(q.reject_unknown)
    assert err.field == f"{FIELD}.type"


def test_reading_a_default_marks_the_key_known() -> None:
    p = params(rate=3)
    p.number("other", 1.0)
    err = refusal(p.reject_unknown)
    assert err.field == f"{FIELD}.rate"
    assert "other" in err.message  # the known keys are listed

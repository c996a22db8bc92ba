"""Tests of the safe command expression language."""

from __future__ import annotations

import math
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointctl.errors import ExpressionError
from jointctl.commands.expression import FUNCTIONS, MAX_DEPTH, MAX_NODES, MAX_TEXT_LENGTH, parse_expression


def refused(text: str) -> str:
    with pytest.raises(ExpressionError) as info:
        parse_expression(text, field="scenario.command.expression", source="demo.yaml")
    error = info.value
    assert error.code == "expression"
    assert error.field == "scenario.command.expression"
    assert error.source == "demo.yaml"
    return str(error)


def test_chapter_example_values() -> None:
    expression = parse_expression("0.1*sin(i/5)-0.5")
    assert expression.text == "0.1*sin(i/5)-0.5"
    assert expression.variables == frozenset({"i"})
    for i in range(200):
        assert expression.evaluate(i, i / 100) == pytest.approx(0.1 * math.sin(i / 5) - 0.5, abs=1e-15)
    assert expression.evaluate(0, 0.0) == -0.5


@pytest.mark.parametrize(
    ("text", "i", "t", "expected"),
    [
        ("1 + 2 * 3", 0, 0.0, 7.0),
        ("(1 + 2) * 3", 0, 0.0, 9.0),
        ("-2 ** 2", 0, 0.0, -4.0),
        ("2 ** -1", 0, 0.0, 0.5),
        ("+t - -t", 0, 1.5, 3.0),
        ("7 % 3", 0, 0.0, 1.0),
        ("-7 % 3", 0, 0.0, 2.0),
        ("i / 4", 3, 0.0, 0.75),
        ("2 * pi * t", 0, 0.5, math.pi),
        ("e", 0, 0.0, math.e),
        ("atan2(1, 1)", 0, 0.0, math.pi / 4),
        ("log(e ** 2)", 0, 0.0, 2.0),
        ("log10(1000)", 0, 0.0, 3.0),
        ("sqrt(16)", 0, 0.0, 4.0),
        ("abs(-2.5)", 0, 0.0, 2.5),
        ("floor(-1.5) + ceil(1.2)", 0, 0.0, 0.0),
        ("min(3, i, 5)", 1, 0.0, 1.0),
        ("max(3, i, 5)", 9, 0.0, 9.0),
        ("sign(-0.3) * 10 + sign(0) + sign(t)", 0, 2.0, -9.0),
        ("clip(t, -1, 1)", 0, 7.0, 1.0),
        ("clip(t, -1, 1)", 0, -7.0, -1.0),
        ("clip(t, -1, 1)", 0, 0.25, 0.25),
        ("tanh(0) + cosh(0) + sinh(0) + exp(0)", 0, 0.0, 2.0),
        ("asin(1) + acos(1) + atan(0) + tan(0) + cos(pi)", 0, 0.0, math.pi / 2 - 1),
        ("1e-3 * 2", 0, 0.0, 0.002),
        ("  0.5 + i  ", 2, 0.0, 2.5),
    ],
)
def test_evaluates(text: str, i: int, t: float, expected: float) -> None:
    value = parse_expression(text).evaluate(i, t)
    assert isinstance(value, float)
    assert value == pytest.approx(expected, abs=1e-12)


def test_variables() -> None:
    assert parse_expression("1 + pi").variables == frozenset()
    assert parse_expression("t * i").variables == frozenset({"i", "t"})
    assert parse_expression("sin(t)").variables == frozenset({"t"})


def test_integer_powers_are_float_so_huge_powers_overflow_instead_of_hanging() -> None:
    expression = parse_expression("9**9**9**9")
    started = time.perf_counter()
    with pytest.raises(ExpressionError, match=r"overflow") as info:
        expression.evaluate(0, 0.0)
    assert time.perf_counter() - started < 10.0  # a hang guard (exact integer powers would run for ever), not a speed
    assert "9**9**9**9" in str(info.value)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("__import__('os')", ["unknown function '__import__'", "column 1"]),
        ("().__class__", ["attribute access", "column 1", "().__class__"]),
        ("(1).real", ["attribute access", "(1).real"]),
        ("1 + sin.__name__", ["attribute access", "column 5"]),
        ("[1][0]", ["subscript", "[1][0]"]),
        ("lambda: 1", ["lambda", "column 1"]),
        ("x", ["unknown name 'x'", "column 1"]),
        ("t + y", ["unknown name 'y'", "column 5"]),
        ("'a'", ["string literal", "'a'"]),
        ("1 if 1 else 2", ["conditional expression"]),
        ("1<2", ["comparison", "1<2"]),
        ("1 and 2", ["boolean operator"]),
        ("not 1", ["operator 'not'"]),
        ("~1", ["operator '~'"]),
        ("7 // 2", ["operator '//'"]),
        ("1 << 2", ["operator '<<'"]),
        ("sin(1,2)", ["function 'sin' takes 1 argument, got 2"]),
        ("atan2(1)", ["function 'atan2' takes 2 arguments, got 1"]),
        ("clip(1, 2)", ["function 'clip' takes 3 arguments, got 2"]),
        ("min(1)", ["function 'min' takes at least 2 arguments, got 1"]),
        ("sin(x=1)", ["keyword argument", "column 5", "x=1"]),
        ("max(*[1, 2])", ["starred argument", "column 5"]),
        ("[i for i in (1, 2)]", ["comprehension"]),
        ("(1, 2)", ["tuple"]),
        ("{1: 2}", ["dict"]),
        ("f'{t}'", ["f-string"]),
        ("True", ["literal True"]),
        ("None", ["literal None"]),
        ("2j", ["complex number"]),
        ("1e999", ["non-finite number literal"]),
        ("sin", ["function 'sin' must be called"]),
        ("t(1)", ["'t' is not a function"]),
        ("sin(1)(2)", ["call of something other than a function name"]),
        ("getattr(t, 'x')", ["unknown function 'getattr'"]),
        ("(t := 1)", ["assignment expression"]),
        ("1 +", ["syntax error", "column"]),
        ("sin(t", ["syntax error", "never closed"]),
        ("", ["empty"]),
        ("   ", ["empty"]),
        ("1\x00", ["null bytes"]),
    ],
)
def test_refused_constructs_are_named(text: str, words: list[str]) -> None:
    message = refused(text)
    for word in words:
        assert word in message


def test_column_counts_leading_spaces_and_characters() -> None:
    assert "unknown name 'x' at column 4" in refused("   x")
    # ast reports UTF-8 byte offsets; the message counts characters
    # (keywords are checked before positional arguments)
    assert "keyword argument in call of 'sin' is not allowed at column 11" in refused("sin('\u00e9\u00e9', x=1)")
    assert "unknown name '\u00e9\u00e9' at column 5" in refused("1 + \u00e9\u00e9 + x")


def test_syntax_error_on_second_line_names_line_and_column() -> None:
    message = refused("(1 +\n  $)")
    assert "line 2, column 3" in message


def test_ten_megabyte_text_is_refused_before_it_is_parsed(monkeypatch) -> None:
    text = "1+" * 5_000_000 + "1"
    from jointctl.commands import expression as module

    def never(*_args, **_kwargs):
        raise AssertionError("a text over the limit reached the parser")

    monkeypatch.setattr(module.ast, "parse", never)
    with pytest.raises(ExpressionError, match=r"too long \(10000001 characters, limit 1000\)") as info:
        parse_expression(text)
    assert len(str(info.value)) < 300


def test_text_length_limit_is_exact() -> None:
    assert parse_expression(" " * (MAX_TEXT_LENGTH - 1) + "1").evaluate(0, 0) == 1.0
    assert "too long (1001 characters, limit 1000)" in refused(" " * MAX_TEXT_LENGTH + "1")


def test_long_flat_sum_counts_as_nesting() -> None:
    # a+b+c+... is a left-leaning tree: one level per operator
    assert parse_expression("+".join(["1"] * MAX_DEPTH)).evaluate(0, 0) == MAX_DEPTH
    assert f"more than {MAX_DEPTH} levels" in refused("+".join(["1"] * (MAX_DEPTH + 1)))


def test_deep_brackets_are_refused_before_parsing() -> None:
    message = refused("(" * 200 + "1" + ")" * 200)
    assert f"more than {MAX_DEPTH} brackets" in message
    assert f"column {MAX_DEPTH + 1}" in message
    assert parse_expression("(" * MAX_DEPTH + "t" + ")" * MAX_DEPTH).evaluate(0, 2.0) == 2.0


def test_deep_tree_is_refused() -> None:
    message = refused("-" * 60 + "1")
    assert f"more than {MAX_DEPTH} levels" in message
    assert parse_expression("-" * (MAX_DEPTH - 1) + "1").evaluate(0, 0) == -1.0


def test_node_count_is_limited() -> None:
    message = refused("max(" + ",".join(["-i"] * 300) + ")")
    assert f"more than {MAX_NODES} nodes" in message
    # 2 (max + its name) + 2 per argument
    assert parse_expression("max(" + ",".join(["-i"] * 249) + ")").evaluate(3, 0) == -3.0


@pytest.mark.parametrize(
    ("text", "i", "t", "reason"),
    [
        ("1/(i-3)", 3, 0.0, "division by zero"),
        ("t % 0", 0, 1.0, "modulo"),
        ("log(t)", 0, 0.0, "math domain error"),
        ("sqrt(t)", 0, -1.0, "math domain error"),
        ("(-8) ** (1/3)", 0, 0.0, "math domain error"),
        ("0 ** -1", 0, 0.0, "math domain error"),
        ("exp(t)", 0, 1000.0, "overflow"),
        ("1e308 * 10", 0, 0.0, "'*' is not finite"),
        ("1e308 + 1e308", 0, 0.0, "'+' is not finite"),
        ("-1e308 - 1e308", 0, 0.0, "'-' is not finite"),
        ("1e308 / 0.1", 0, 0.0, "'/' is not finite"),
        ("atan(1e308 * 10)", 0, 0.0, "'*' is not finite"),
        ("clip(t, 1, -1)", 0, 0.0, "lower bound"),
    ],
)
def test_evaluation_errors_name_expression_and_inputs(text: str, i: int, t: float, reason: str) -> None:
    expression = parse_expression(text, field="cmd.expression", source="s.yaml")
    with pytest.raises(ExpressionError) as info:
        expression.evaluate(i, t)
    message = str(info.value)
    assert reason in message
    assert f"i={i:g}, t={t:g} s" in message
    assert text in message
    assert message.startswith("s.yaml: cmd.expression: ")


def test_non_finite_inputs_are_refused() -> None:
    with pytest.raises(ExpressionError, match="finite"):
        parse_expression("1").evaluate(0, math.inf)


def test_functions_table_matches_the_documented_set() -> None:
    assert set(FUNCTIONS) == set(
        "sin cos tan asin acos atan atan2 sinh cosh tanh exp log log10 sqrt abs floor ceil min max sign clip".split()
    )


def test_non_string_is_refused() -> None:
    with pytest.raises(ExpressionError, match="must be a string, not int"):
        parse_expression(3)  # type: ignore[arg-type]


_leaf = st.one_of(
    st.sampled_from(["i", "t", "pi", "e"]),
    st.floats(min_value=-1e3, max_value=1e3, allow_nan=False).map(repr),
)


def _combine(children: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    binary = st.tuples(children, st.sampled_from(["+", "-", "*", "/", "**", "%"]), children).map(
        lambda parts: f"({parts[0]} {parts[1]} {parts[2]})"
    )
    call = st.tuples(st.sampled_from(["sin", "cos", "tanh", "abs", "sign", "floor", "exp", "log"]), children).map(
        lambda parts: f"{parts[0]}({parts[1]})"
    )
    return st.one_of(binary, call, children.map(lambda c: f"-{c}"))


@settings(max_examples=300, deadline=None)
@given(
    text=st.recursive(_leaf, _combine, max_leaves=12),
    i=st.integers(min_value=0, max_value=10_000),
    t=st.floats(min_value=0, max_value=100, allow_nan=False),
)
def test_random_expressions_give_finite_floats_or_expression_errors(text: str, i: int, t: float) -> None:
    expression = parse_expression(text)
    try:
        value = expression.evaluate(i, t)
    except ExpressionError as error:
        assert "cannot evaluate" in str(error)
    else:
        assert isinstance(value, float)
        assert math.isfinite(value)

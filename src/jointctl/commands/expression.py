"""A small, safe arithmetic language for command signals.

Expressions look like rqt_gui's message publisher expressions, for example
``0.1*sin(i/5)-0.5``: ``i`` is the message count (0, 1, 2, ...) and ``t`` the
publication time in seconds. The text is parsed with :func:`ast.parse` and
checked node by node against a whitelist, then turned into a tree of nested
closures built once; evaluating walks those closures and never calls
``eval``/``exec``/``compile``.

The language:

* number literals (``1``, ``2.5``, ``1e-3``), all evaluated as floats;
* unary ``+`` and ``-``; binary ``+ - * / ** %``; parentheses;
* the variables ``i`` and ``t`` and the constants ``pi`` and ``e``;
* calls, by bare name, of :data:`FUNCTIONS` (``sin``, ``clip(x, lo, hi)``...).

Everything else is refused at parse time with an :class:`ExpressionError`
naming the construct and its column. The text is limited to
:data:`MAX_TEXT_LENGTH` characters (checked before parsing), the tree to
:data:`MAX_NODES` nodes and :data:`MAX_DEPTH` levels of nesting (brackets and
operators alike: a chain ``a+b+c+...`` nests one level per operator).

Every intermediate result is finite: an operation that overflows to
infinity, divides by zero or leaves a function's domain makes
:meth:`Expression.evaluate` raise an :class:`ExpressionError`.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable
from typing import Final

from jointctl.errors import ExpressionError

__all__ = [
    "CONSTANTS",
    "FUNCTIONS",
    "MAX_DEPTH",
    "MAX_NODES",
    "MAX_TEXT_LENGTH",
    "VARIABLES",
    "Expression",
    "parse_expression",
]

MAX_TEXT_LENGTH: Final = 1000
"""Longest accepted expression text, in characters."""
MAX_NODES: Final = 500
"""Most syntax-tree nodes (numbers, names, operators, calls) in one expression."""
MAX_DEPTH: Final = 50
"""Deepest accepted nesting, counting both brackets and tree levels."""

VARIABLES: Final = frozenset({"i", "t"})
"""``i``: message count (0, 1, 2, ...); ``t``: publication time in seconds."""
CONSTANTS: Final = {"pi": math.pi, "e": math.e}

_Node = Callable[[float, float], float]


class _NonFinite(ArithmeticError):
    """An operation produced an infinity or NaN."""


def _sign(x: float) -> float:
    return float((x > 0.0) - (x < 0.0))


def _clip(x: float, lo: float, hi: float) -> float:
    if lo > hi:
        raise ValueError(f"clip: lower bound {lo!r} is above upper bound {hi!r}")
    return min(max(x, lo), hi)


def _floor(x: float) -> float:
    return float(math.floor(x))


def _ceil(x: float) -> float:
    return float(math.ceil(x))


FUNCTIONS: Final[dict[str, tuple[Callable[..., float], int, int | None]]] = {
    # name: (implementation, least arguments, most arguments or None for any)
    "sin": (math.sin, 1, 1),
    "cos": (math.cos, 1, 1),
    "tan": (math.tan, 1, 1),
    "asin": (math.asin, 1, 1),
    "acos": (math.acos, 1, 1),
    "atan": (math.atan, 1, 1),
    "atan2": (math.atan2, 2, 2),
    "sinh": (math.sinh, 1, 1),
    "cosh": (math.cosh, 1, 1),
    "tanh": (math.tanh, 1, 1),
    "exp": (math.exp, 1, 1),
    "log": (math.log, 1, 1),
    "log10": (math.log10, 1, 1),
    "sqrt": (math.sqrt, 1, 1),
    "abs": (abs, 1, 1),
    "floor": (_floor, 1, 1),
    "ceil": (_ceil, 1, 1),
    "min": (min, 2, None),
    "max": (max, 2, None),
    "sign": (_sign, 1, 1),
    "clip": (_clip, 3, 3),
}
"""Callable functions: angles in radians, ``log`` is the natural logarithm."""

_isfinite = math.isfinite


def _checked(op: Callable[[float, float], float], a: _Node, b: _Node, symbol: str) -> _Node:
    def node(i: float, t: float) -> float:
        r = op(a(i, t), b(i, t))
        if not _isfinite(r):
            raise _NonFinite(f"result of '{symbol}' is not finite")
        return r

    return node


def _add(a: _Node, b: _Node) -> _Node:
    def node(i: float, t: float) -> float:
        r = a(i, t) + b(i, t)
        if not _isfinite(r):
            raise _NonFinite("result of '+' is not finite")
        return r

    return node


def _sub(a: _Node, b: _Node) -> _Node:
    def node(i: float, t: float) -> float:
        r = a(i, t) - b(i, t)
        if not _isfinite(r):
            raise _NonFinite("result of '-' is not finite")
        return r

    return node


def _mul(a: _Node, b: _Node) -> _Node:
    def node(i: float, t: float) -> float:
        r = a(i, t) * b(i, t)
        if not _isfinite(r):
            raise _NonFinite("result of '*' is not finite")
        return r

    return node


_BINARY: Final[dict[type[ast.operator], tuple[str, Callable[[_Node, _Node], _Node]]]] = {
    ast.Add: ("+", _add),
    ast.Sub: ("-", _sub),
    ast.Mult: ("*", _mul),
    # float '/' and '%' raise ZeroDivisionError; math.pow raises on overflow
    # and domain errors instead of returning inf or a complex number.
    ast.Div: ("/", lambda a, b: _checked(lambda x, y: x / y, a, b, "/")),
    ast.Pow: ("**", lambda a, b: _checked(math.pow, a, b, "**")),
    ast.Mod: ("%", lambda a, b: _checked(lambda x, y: x % y, a, b, "%")),
}

_OPERATOR_SYMBOLS: Final = {
    ast.FloorDiv: "//",
    ast.MatMult: "@",
    ast.LShift: "<<",
    ast.RShift: ">>",
    ast.BitOr: "|",
    ast.BitXor: "^",
    ast.BitAnd: "&",
    ast.Not: "not",
    ast.Invert: "~",
}

_CONSTRUCT_NAMES: Final[dict[type[ast.AST], str]] = {
    ast.Attribute: "attribute access",
    ast.Subscript: "subscript",
    ast.Lambda: "lambda",
    ast.ListComp: "comprehension",
    ast.SetComp: "comprehension",
    ast.DictComp: "comprehension",
    ast.GeneratorExp: "generator expression",
    ast.Compare: "comparison",
    ast.BoolOp: "boolean operator",
    ast.IfExp: "conditional expression",
    ast.Starred: "starred argument",
    ast.NamedExpr: "assignment expression",
    ast.List: "list",
    ast.Tuple: "tuple",
    ast.Set: "set",
    ast.Dict: "dict",
    ast.JoinedStr: "f-string",
    ast.FormattedValue: "f-string",
    ast.Await: "await",
    ast.Yield: "yield",
    ast.YieldFrom: "yield",
    ast.Slice: "slice",
}


class Expression:
    """A parsed, checked expression, evaluated by :meth:`evaluate`.

    Build one with :func:`parse_expression`. ``text`` is the source text,
    ``variables`` the subset of ``{"i", "t"}`` it uses.
    """

    __slots__ = ("text", "variables", "field", "source", "_root")

    def __init__(
        self,
        text: str,
        variables: frozenset[str],
        root: _Node,
        *,
        field: str,
        source: str | None,
    ) -> None:
        self.text = text
        self.variables = variables
        self.field = field
        self.source = source
        self._root = root

    def evaluate(self, i: float, t: float) -> float:
        """Value of the expression for message count ``i`` and time ``t`` (seconds).

        Raises :class:`ExpressionError` naming the expression, ``i`` and
        ``t`` on division by zero, a math domain error, an overflow or a
        non-finite result.
        """
        i = float(i)
        t = float(t)
        try:
            if not (_isfinite(i) and _isfinite(t)):
                raise _NonFinite("i and t must be finite")
            return self._root(i, t)
        except (ArithmeticError, ValueError) as exc:
            reason = str(exc) or type(exc).__name__
            if isinstance(exc, OverflowError):
                reason = f"overflow ({reason})"
            raise ExpressionError(
                f"cannot evaluate expression at i={i:g}, t={t:g} s: {reason}",
                source=self.source,
                field=self.field,
                value=self.text,
            ) from exc

    def __repr__(self) -> str:
        return f"Expression({self.text!r})"


def parse_expression(text: str, *, field: str = "expression", source: str | None = None) -> Expression:
    """Parse and check ``text``; return an :class:`Expression` ready to evaluate.

    ``field`` and ``source`` name where the text comes from in error
    messages. Raises :class:`ExpressionError` on anything outside the
    language or over the limits.
    """

    def fail(message: str, value: object = None) -> ExpressionError:
        return ExpressionError(message, source=source, field=field, value=text if value is None else value)

    if not isinstance(text, str):
        raise fail(f"expression must be a string, not {type(text).__name__}")
    if len(text) > MAX_TEXT_LENGTH:
        raise fail(
            f"expression is too long ({len(text)} characters, limit {MAX_TEXT_LENGTH})",
            value=text[:80],
        )
    body = text.lstrip()
    if not body.strip():
        raise fail("expression is empty")
    positions = _Positions(text, body)

    depth = 0
    for index, char in enumerate(text):
        if char in "([{":
            depth += 1
            if depth > MAX_DEPTH:
                raise fail(
                    f"expression nests too deeply (more than {MAX_DEPTH} brackets) "
                    f"at {positions.of_text_index(index)}"
                )
        elif char in ")]}":
            depth -= 1

    try:
        tree = ast.parse(body, mode="eval")
    except SyntaxError as exc:
        where = positions.of_char(exc.lineno or 1, (exc.offset or 1) - 1)
        raise fail(f"syntax error at {where}: {exc.msg}") from None
    except (ValueError, RecursionError, MemoryError) as exc:
        raise fail(f"cannot parse expression: {exc or type(exc).__name__}") from None

    compiler = _Compiler(body, positions, fail)
    root = compiler.compile(tree.body, 1)
    return Expression(text, frozenset(compiler.variables), root, field=field, source=source)


class _Positions:
    """Maps positions in the parsed (left-stripped) body back to the original text."""

    def __init__(self, text: str, body: str) -> None:
        self.text = text
        lead = text[: len(text) - len(body)]
        self.lead_lines = lead.count("\n")
        self.lead_column = len(lead) - (lead.rfind("\n") + 1)
        self.body_lines = body.split("\n")
        self.multiline = "\n" in text

    def of_char(self, lineno: int, column: int) -> str:
        """Describe 1-based ``lineno`` / 0-based character ``column`` of the body."""
        if lineno == 1:
            column += self.lead_column
        return self._describe(lineno + self.lead_lines, column)

    def of_node(self, node: ast.AST) -> str:
        lineno = getattr(node, "lineno", 1)
        offset = getattr(node, "col_offset", 0)
        line = self.body_lines[lineno - 1] if lineno - 1 < len(self.body_lines) else ""
        column = len(line.encode("utf-8")[:offset].decode("utf-8", "replace"))
        return self.of_char(lineno, column)

    def of_text_index(self, index: int) -> str:
        before = self.text[:index]
        return self._describe(before.count("\n") + 1, index - (before.rfind("\n") + 1))

    def _describe(self, lineno: int, column: int) -> str:
        if self.multiline:
            return f"line {lineno}, column {column + 1}"
        return f"column {column + 1}"


class _Compiler:
    """Checks an expression tree and turns it into nested closures."""

    def __init__(self, body: str, positions: _Positions, fail: Callable[..., ExpressionError]) -> None:
        self.body = body
        self.positions = positions
        self.fail = fail
        self.nodes = 0
        self.variables: set[str] = set()

    def refuse(self, node: ast.AST, what: str) -> ExpressionError:
        snippet = ast.get_source_segment(self.body, node) or ""
        if len(snippet) > 40:
            snippet = snippet[:37] + "..."
        shown = f": {snippet}" if snippet else ""
        return self.fail(f"{what} is not allowed at {self.positions.of_node(node)}{shown}")

    def compile(self, node: ast.AST, depth: int) -> _Node:
        self.nodes += 1
        if self.nodes > MAX_NODES:
            raise self.fail(
                f"expression has too many parts (more than {MAX_NODES} nodes); "
                f"limit reached at {self.positions.of_node(node)}"
            )
        if depth > MAX_DEPTH:
            raise self.fail(
                f"expression nests too deeply (more than {MAX_DEPTH} levels) "
                f"at {self.positions.of_node(node)}"
            )
        if isinstance(node, ast.Constant):
            return self.constant(node)
        if isinstance(node, ast.Name):
            return self.name(node)
        if isinstance(node, ast.UnaryOp):
            return self.unary(node, depth)
        if isinstance(node, ast.BinOp):
            return self.binary(node, depth)
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        what = _CONSTRUCT_NAMES.get(type(node), f"construct {type(node).__name__}")
        raise self.refuse(node, what)

    def constant(self, node: ast.Constant) -> _Node:
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            kind = {str: "string literal", bytes: "bytes literal", complex: "complex number"}.get(
                type(value), f"literal {value!r}"
            )
            raise self.refuse(node, kind)
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        if not math.isfinite(number):
            raise self.refuse(node, "non-finite number literal")
        return lambda i, t: number

    def name(self, node: ast.Name) -> _Node:
        if node.id == "i":
            self.variables.add("i")
            return lambda i, t: i
        if node.id == "t":
            self.variables.add("t")
            return lambda i, t: t
        if node.id in CONSTANTS:
            value = CONSTANTS[node.id]
            return lambda i, t: value
        if node.id in FUNCTIONS:
            raise self.fail(
                f"function '{node.id}' must be called, e.g. {node.id}(t), at {self.positions.of_node(node)}"
            )
        raise self.fail(
            f"unknown name '{node.id}' at {self.positions.of_node(node)} "
            f"(variables: i, t; constants: pi, e)"
        )

    def unary(self, node: ast.UnaryOp, depth: int) -> _Node:
        if isinstance(node.op, ast.UAdd):
            return self.compile(node.operand, depth + 1)
        if isinstance(node.op, ast.USub):
            operand = self.compile(node.operand, depth + 1)
            return lambda i, t: -operand(i, t)
        raise self.refuse(node, f"operator '{_OPERATOR_SYMBOLS.get(type(node.op), '?')}'")

    def binary(self, node: ast.BinOp, depth: int) -> _Node:
        entry = _BINARY.get(type(node.op))
        if entry is None:
            raise self.refuse(node, f"operator '{_OPERATOR_SYMBOLS.get(type(node.op), '?')}'")
        left = self.compile(node.left, depth + 1)
        right = self.compile(node.right, depth + 1)
        return entry[1](left, right)

    def call(self, node: ast.Call, depth: int) -> _Node:
        if not isinstance(node.func, ast.Name):
            raise self.refuse(node, "call of something other than a function name")
        name = node.func.id
        if name not in FUNCTIONS:
            where = self.positions.of_node(node)
            if name in VARIABLES or name in CONSTANTS:
                raise self.fail(f"'{name}' is not a function, at {where}")
            known = ", ".join(sorted(FUNCTIONS))
            raise self.fail(f"unknown function '{name}' at {where} (known: {known})")
        if node.keywords:
            raise self.refuse(node.keywords[0], f"keyword argument in call of '{name}'")
        for arg in node.args:
            if isinstance(arg, ast.Starred):
                raise self.refuse(arg, f"starred argument in call of '{name}'")
        function, least, most = FUNCTIONS[name]
        count = len(node.args)
        if count < least or (most is not None and count > most):
            wanted = f"{least}" if least == most else f"at least {least}" if most is None else f"{least} to {most}"
            raise self.fail(
                f"function '{name}' takes {wanted} argument{'s' if wanted != '1' else ''}, "
                f"got {count}, at {self.positions.of_node(node)}"
            )
        self.nodes += 1  # the function name
        args = [self.compile(arg, depth + 1) for arg in node.args]
        if count == 1:
            (a,) = args
            return lambda i, t: function(a(i, t))
        if count == 2:
            a, b = args
            return lambda i, t: function(a(i, t), b(i, t))
        if count == 3:
            a, b, c = args
            return lambda i, t: function(a(i, t), b(i, t), c(i, t))
        return lambda i, t: function(*[arg(i, t) for arg in args])

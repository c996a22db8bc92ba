"""``--spec``: what a run must meet to pass, e.g. ``overshoot_pct<=10,settling_time_s<=0.3``.

Each term is ``METRIC OP NUMBER`` with OP one of ``<=``, ``<``, ``>=``, ``>``; terms are separated by commas.
A run passes when every term holds. A metric the run did not measure (null: a step that never settled)
fails its term; a run that failed has no verdict.
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from jointctl.control.params import unknown_field_message
from jointctl.errors import ConfigError

_OPERATORS = {"<=": operator.le, "<": operator.lt, ">=": operator.ge, ">": operator.gt}
_TERM = re.compile(r"^\s*([A-Za-z_][\w.]*)\s*(<=|>=|<|>)\s*(\S+)\s*$")


@dataclass(frozen=True)
class Term:
    """``metric op limit``: ``<=``/``<`` bound the metric from above (its worst case is its largest value),
    ``>=``/``>`` from below."""

    metric: str
    op: str
    limit: float

    @property
    def upper(self) -> bool:
        return self.op in ("<=", "<")

    def holds(self, value: float | None) -> bool:
        return value is not None and math.isfinite(value) and _OPERATORS[self.op](value, self.limit)

    def __str__(self) -> str:
        return f"{self.metric}{self.op}{self.limit:g}"


@dataclass(frozen=True)
class Spec:
    terms: tuple[Term, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.terms)

    def term(self, metric: str) -> Term | None:
        """The first term on ``metric``, or None."""
        return next((t for t in self.terms if t.metric == metric), None)

    def verdict(self, metrics: Mapping[str, float | None]) -> bool | None:
        """True when every term holds on ``metrics``; None without terms."""
        if not self.terms:
            return None
        return all(term.holds(metrics.get(term.metric)) for term in self.terms)

    def check_metrics(self, known: Iterable[str]) -> None:
        """Refuse a term on a metric the analysis does not report, naming the nearest."""
        known = list(known)
        for term in self.terms:
            if term.metric not in known:
                raise ConfigError(unknown_field_message(term.metric, known).replace("unknown field", "unknown metric"),
                                  field="--spec", value=term.metric)

    def __str__(self) -> str:
        return ",".join(str(t) for t in self.terms)


def parse_spec(text: str | None) -> Spec:
    """``"a<=1,b>=2"`` -> :class:`Spec`; None or "" -> no terms; ConfigError naming ``--spec`` and the term."""
    if text is None or not text.strip():
        return Spec()
    terms = []
    for part in text.split(","):
        match = _TERM.match(part)
        if not match:
            raise ConfigError("each term is METRIC<=NUMBER (or <, >=, >), terms separated by commas",
                              field="--spec", value=part.strip())
        try:
            limit = float(match.group(3))
        except ValueError:
            limit = math.nan
        if not math.isfinite(limit):
            raise ConfigError("the limit must be a finite number", field="--spec", value=part.strip())
        terms.append(Term(match.group(1), match.group(2), limit))
    return Spec(tuple(terms))


__all__ = ["Spec", "Term", "parse_spec"]

"""The warnings every analysis ends with: figures that miss their theory or the user's spec, and
joints whose effort sat at its limit.

An analysis returns its measured figures with ``expected`` (its theory; None where it does not
apply) and, optionally, ``margins``: figure name -> :class:`~jointctl.metrics.expectations.Margin`
for figures whose margin depends on the run (a position's share of the step); the rest take
:data:`~jointctl.metrics.expectations.DEFAULT_MARGINS`. The scenario's ``analysis.spec`` (figure
name -> the value the user wants) is compared with the same margins, both ways. :func:`add_warnings`
turns these into ``warnings``: a list of sentences, empty when all is well.
"""

from __future__ import annotations

import math
from typing import Any

from jointctl.errors import ConfigError
from jointctl.metrics.expectations import (expectation_warnings, margin_for, saturation_share,
                                           saturation_warning)
from jointctl.recording.trace import Trace
from jointctl.scenario.session import Session
from jointctl.validate import finite_number


def check_spec(session: Session, params: dict[str, Any]) -> None:
    """Refuse an ``analysis.spec`` that is not a mapping of figure names to numbers (before the run)."""
    spec = params.get("spec")
    if spec is None:
        return
    if not isinstance(spec, dict):
        raise ConfigError("must be a mapping of figure names to the values wanted", source=session.scenario.source,
                          field="analysis.spec", value=spec)
    for key, value in spec.items():
        if finite_number(value) is None:
            raise ConfigError("must be a number", source=session.scenario.source, field=f"analysis.spec.{key}",
                              value=value)


def effort_saturation_warnings(session: Session, trace: Trace) -> list[str]:
    """A sentence for each joint whose recorded effort sat at its effort limit in some cycle of the run."""
    found = []
    for name in session.hardware.joint_names:
        limits = session.robot.joint(name).limits if session.robot.has_joint(name) else None
        limit = limits.effort if limits is not None and limits.effort > 0 else math.inf
        column = f"{name}.effort"
        if column not in trace.columns or not math.isfinite(limit):
            continue
        unit = "N" if session.robot.joint(name).is_prismatic else "N·m"
        sentence = saturation_warning(name, saturation_share(trace[column], limit), limit, unit)
        if sentence is not None:
            found.append(sentence)
    return found


def add_warnings(session: Session, trace: Trace, params: dict[str, Any], metrics: dict[str, Any]) -> dict[str, Any]:
    """``metrics`` with ``margins`` taken out and ``warnings`` (a list of sentences) added: figures
    off their expectation or the spec by more than their margin, and saturated efforts."""
    margins = metrics.pop("margins", None) or {}
    found = list(metrics.get("warnings", []))
    found += expectation_warnings(metrics, metrics.get("expected") or {}, margins)
    spec = params.get("spec") or {}
    found += expectation_warnings(metrics, {k: float(v) for k, v in spec.items()}, margins, against="spec")
    for key in spec:
        if key not in metrics:
            found.append(f"analysis.spec.{key}: this analysis measures no such figure; not compared.")
        elif margin_for(key, margins) is None:
            found.append(f"analysis.spec.{key}: jointctl states no margin for this figure; not compared.")
    found += effort_saturation_warnings(session, trace)
    metrics["warnings"] = found
    return metrics

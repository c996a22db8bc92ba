"""``metrics.json``: the figures of merit of a run, an identification, a frequency sweep or a tuning,
written as strict JSON by the one writer every experiment and tool uses (:func:`write_metrics`).

JSON has no Infinity or NaN (Python's ``json`` writes them, but browsers' ``JSON.parse``, ``jq`` and
most other languages' parsers refuse the file), so a figure that is not a finite number is written
as ``null``. **null means "not measured" or "unbounded"**: a step that never settled, a -3 dB
bandwidth or a -90° crossing outside the swept range, no resonance peak inside it, an infinite gain
margin of a loop whose phase never reaches -180°. Numpy scalars and arrays are written as numbers
and lists.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

METRICS_FILE = "metrics.json"


def json_ready(value: Any) -> Any:
    """``value`` with NaN and infinities (at any depth) as None, tuples and numpy arrays as lists and
    numpy scalars as Python numbers."""
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):  # numpy arrays and scalars
        return json_ready(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def metrics_json(metrics: Any) -> str:
    """``metrics`` as strict JSON text (indented; non-finite figures as null, see the module)."""
    return json.dumps(json_ready(metrics), indent=2, allow_nan=False)


def write_metrics(out_dir: str | Path, metrics: Any) -> Path:
    """Write ``out_dir/metrics.json`` (strict JSON, non-finite figures as null); returns its path."""
    path = Path(out_dir) / METRICS_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(metrics_json(metrics) + "\n")
    return path


__all__ = ["METRICS_FILE", "json_ready", "metrics_json", "write_metrics"]

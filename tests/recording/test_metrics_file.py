"""metrics.json is strict JSON: a figure that is NaN or infinite is written as null, whoever writes it."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from jointctl.recording.metrics_file import METRICS_FILE, json_ready, metrics_json, write_metrics

SRC = Path(__file__).resolve().parents[2] / "src" / "jointctl"


def strict_load(text: str):
    """Parse JSON as browsers, jq and serde do: NaN, Infinity and -Infinity are errors."""
    def refuse(constant: str):
        raise ValueError(f"not JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


def test_strict_load_refuses_what_python_writes_by_default() -> None:
    with pytest.raises(ValueError, match="NaN"):
        strict_load(json.dumps({"x": math.nan}))


def test_non_finite_figures_are_written_as_null_and_read_back_strictly(tmp_path) -> None:
    metrics = {"bandwidth_hz": math.nan, "gain_margin_db": math.inf, "phase": -math.inf, "ok": 1.5,
               "nested": {"list": [1.0, math.nan, (2.0, math.inf)]}, "flag": True, "none": None,
               "numpy": {"scalar": np.float64("nan"), "int": np.int64(3), "array": np.array([1.0, np.inf]),
                         "f32": np.float32(0.5), "bool": np.bool_(False)}}
    path = write_metrics(tmp_path / "out", metrics)
    assert path == tmp_path / "out" / METRICS_FILE
    assert strict_load(path.read_text()) == {
        "bandwidth_hz": None, "gain_margin_db": None, "phase": None, "ok": 1.5,
        "nested": {"list": [1.0, None, [2.0, None]]}, "flag": True, "none": None,
        "numpy": {"scalar": None, "int": 3, "array": [1.0, None], "f32": 0.5, "bool": False}}
    assert metrics["bandwidth_hz"] != metrics["bandwidth_hz"]  # the caller's figures are left as they are


def test_metrics_json_is_the_text_of_the_file(tmp_path) -> None:
    metrics = {"a": math.nan, "b": [1, 2]}
    assert write_metrics(tmp_path, metrics).read_text() == metrics_json(metrics) + "\n"
    assert json_ready(metrics) == {"a": None, "b": [1, 2]}


def test_every_metrics_json_goes_through_the_one_writer() -> None:
    """No module writes metrics.json (or any JSON file) itself: every experiment and tool calls
    write_metrics, so none can write NaN or Infinity."""
    offenders = []
    for path in SRC.rglob("*.py"):
        if path.name == "metrics_file.py":
            continue
        text = path.read_text()
        if re.search(r"write_text\(\s*json\.dumps|/\s*[\"']metrics\.json[\"']|json\.dump\(", text):
            offenders.append(str(path.relative_to(SRC)))
    assert offenders == []

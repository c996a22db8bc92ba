"""Record a run to ``trace.csv``: time, then command, position, velocity and effort per joint.

The recorder is a loop observer. Rows collect in memory and go to disk every
``chunk_rows`` rows, so memory stays flat however long the run; ``every``
keeps one cycle in ``every`` (decimation). Columns are ``time_s`` then, per
quantity, one column per joint: ``<joint>.command`` (the reference of the
controller commanding the joint: a position or a velocity), ``<joint>.position``,
``<joint>.velocity``, ``<joint>.effort``; then ``<sensor>.force_x`` ...
``<sensor>.torque_z`` for each force-torque sensor. SI units throughout.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointctl.hardware.interface import HardwareInterface

QUANTITIES = ("command", "position", "velocity", "effort")
WRENCH_AXES = ("force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z")


class _NoCommand:
    reference = math.nan


class TraceRecorder:
    """Streams one row per kept cycle to a CSV file. Use as a context manager or call close()."""

    def __init__(
        self,
        path: str | Path,
        hardware: HardwareInterface,
        commanders: Sequence[object | None],
        *,
        every: int = 1,
        chunk_rows: int = 4096,
    ) -> None:
        if every < 1:
            raise ValueError(f"every must be at least 1, got {every}")
        self.path = Path(path)
        self.hardware = hardware
        self._commanders = tuple(c if c is not None else _NoCommand() for c in commanders)
        self.every = every
        self.chunk_rows = chunk_rows
        self.columns = trace_columns(hardware.joint_names, hardware.sensor_names)
        self.rows_written = 0
        self._rows: list[tuple] = []
        self._countdown = 0
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = self.path.open("w", newline="")
        self._writer = csv.writer(self._file)
        self._writer.writerow(self.columns)
        self._wrenches = tuple(hardware.wrenches[s] for s in hardware.sensor_names)

    def __call__(self, time_s: float) -> None:
        if self._countdown:
            self._countdown -= 1
            return
        self._countdown = self.every - 1
        hw = self.hardware
        row = (time_s, *[c.reference for c in self._commanders], *hw.position, *hw.velocity,
               *hw.effort)
        for w in self._wrenches:
            row += tuple(w)
        rows = self._rows
        rows.append(row)
        if len(rows) >= self.chunk_rows:
            self.flush()

    def flush(self) -> None:
        if self._rows:
            self._writer.writerows(self._rows)
            self.rows_written += len(self._rows)
            self._rows.clear()
        self._file.flush()

    def close(self) -> None:
        if not self._file.closed:
            self.flush()
            self._file.close()

    def __enter__(self) -> TraceRecorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def trace_columns(joint_names: Sequence[str], sensor_names: Sequence[str] = ()) -> list[str]:
    columns = ["time_s"]
    for quantity in QUANTITIES:
        columns += [f"{j}.{quantity}" for j in joint_names]
    for s in sensor_names:
        columns += [f"{s}.{axis}" for axis in WRENCH_AXES]
    return columns


@dataclass(frozen=True)
class Trace:
    """A recorded run loaded back from ``trace.csv``: one numpy column per name."""

    columns: dict[str, np.ndarray]

    @property
    def time_s(self) -> np.ndarray:
        return self.columns["time_s"]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def joint(self, joint: str, quantity: str) -> np.ndarray:
        return self.columns[f"{joint}.{quantity}"]


def load_trace(path: str | Path) -> Trace:
    """Read a ``trace.csv`` written by :class:`TraceRecorder`."""
    path = Path(path)
    with path.open() as f:
        header = next(csv.reader(f))
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return Trace({name: data[:, k] for k, name in enumerate(header)})

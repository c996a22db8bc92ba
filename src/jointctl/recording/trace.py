"""Record a run to ``trace.csv``: time, then reference, position, velocity and effort per joint.

The recorder is a loop observer. Rows collect in memory and go to disk every
``chunk_rows`` rows, so memory stays flat however long the run; ``every``
keeps one cycle in ``every`` (decimation). Columns are ``time_s`` then, per
quantity, one column per joint: ``<joint>.reference`` (the reference of the
controller commanding the joint: a position or a velocity; NaN when none), ``<joint>.position``,
``<joint>.velocity``, ``<joint>.effort``; then ``<sensor>.force_x`` ...
``<sensor>.torque_z`` for each force-torque sensor. SI units throughout.
"""

from __future__ import annotations

import csv
import io
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointctl.hardware.interface import HardwareInterface

QUANTITIES = ("reference", "position", "velocity", "effort")
WRENCH_AXES = ("force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z")


class TraceRecorder:
    """Streams one row per kept cycle to disk; ``close()`` writes ``trace.csv``.

    During the run rows go, as raw float64, to a spool file next to the trace
    every ``chunk_rows`` rows; closing formats the spool into CSV chunk by
    chunk and removes it. Formatting text costs more than a control cycle, so
    it stays out of the loop, and memory stays flat however long the run.

    With ``path`` None the rows stay in memory, at full float64 precision (the CSV keeps ten significant digits),
    and :meth:`trace` gives them once closed: no file is written (a sweep's run, whose row keeps only figures).
    """

    def __init__(
        self,
        path: str | Path | None,
        hardware: HardwareInterface,
        references: Sequence[float],
        *,
        every: int = 1,
        chunk_rows: int = 8192,
    ) -> None:
        if every < 1:
            raise ValueError(f"every must be at least 1, got {every}")
        self.path = Path(path) if path is not None else None
        self.hardware = hardware
        self._references = references
        self.every = every
        self.columns = trace_columns(hardware.joint_names, hardware.sensor_names)
        self.rows_written = 0
        self.chunk_rows = chunk_rows
        # Each row is packed to raw float64 bytes at once: cheaper than an array of floats.
        self._pack = struct.Struct(f"<{len(self.columns)}d").pack
        self._rows: list[bytes] = []
        self._countdown = 0
        wrenches = tuple(hardware.wrenches[s] for s in hardware.sensor_names)
        self._wrench = wrenches[0] if len(wrenches) == 1 else None
        self._wrenches = wrenches
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._spool_path = self.path.with_name(f".{self.path.name}.f64")
            self._spool = self._spool_path.open("wb")
        else:
            self._spool_path = None
            self._spool = io.BytesIO()
        self._trace: Trace | None = None
        self.closed = False
        #: Called as :meth:`close` formats the spool, with each block of rows (float64, rows x columns) and
        #: their lines of trace.csv (text, no newline): other records of the same rows (``run.mcap``) are
        #: written in the same pass, with the same numbers.
        self.chunk_readers: list = []

    def __call__(self, time_s: float) -> None:
        if self._countdown:
            self._countdown -= 1
            return
        self._countdown = self.every - 1
        hw = self.hardware
        if self._wrench is not None:  # the usual case: one force-torque sensor
            row = self._pack(time_s, *self._references, *hw.position, *hw.velocity, *hw.effort,
                             *self._wrench)
        else:
            row = self._pack(time_s, *self._references, *hw.position, *hw.velocity, *hw.effort,
                             *[x for w in self._wrenches for x in w])
        rows = self._rows
        rows.append(row)
        if len(rows) >= self.chunk_rows:
            self.flush()

    def add_block(self, block: np.ndarray) -> None:
        """Add rows made elsewhere (a compiled run's: float64, rows x columns, in order) after the rows so far."""
        self.flush()
        if len(block):
            self._spool.write(np.ascontiguousarray(block, dtype="<f8").tobytes())
            self.rows_written += len(block)

    def flush(self) -> None:
        """Move the rows collected in memory to the spool file."""
        if self._rows:
            self._spool.write(b"".join(self._rows))
            self.rows_written += len(self._rows)
            self._rows.clear()
        self._spool.flush()

    def close(self) -> None:
        """Write ``trace.csv`` from the spool (ten significant digits) and remove the spool."""
        if self.closed:
            return
        self.flush()
        if self.path is None:
            data = np.frombuffer(self._spool.getvalue(), dtype="<f8").reshape(-1, len(self.columns)).copy()
            self._spool.close()
            self._trace = Trace({name: data[:, k] for k, name in enumerate(self.columns)})
            self.closed = True
            return
        self._spool.close()
        width = len(self.columns)
        row_format = ",".join(["%.10g"] * width)
        rows_per_chunk = self.chunk_rows
        failure = None
        with self.path.open("w") as out, self._spool_path.open("rb") as spool:
            out.write(",".join(self.columns) + "\n")
            while True:
                chunk = np.fromfile(spool, dtype=np.float64, count=rows_per_chunk * width)
                if chunk.size == 0:
                    break
                block = chunk.reshape(-1, width)
                lines = [row_format % tuple(r) for r in block.tolist()]
                out.write("\n".join(lines))
                out.write("\n")
                for reader in self.chunk_readers if failure is None else ():
                    try:
                        reader(block, lines)
                    except Exception as exc:  # noqa: BLE001  (trace.csv is finished first, then it is raised)
                        failure = exc
        self._spool_path.unlink()
        self.closed = True
        if failure is not None:
            raise failure

    def trace(self) -> Trace:
        """The rows recorded, as :func:`load_trace` would read them back but at full precision (a recorder
        without a ``path``, closed)."""
        if self._trace is None:
            raise RuntimeError("the trace is kept in memory only without a path, once the recorder is closed")
        return self._trace

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

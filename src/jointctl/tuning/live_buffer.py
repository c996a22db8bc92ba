"""The last seconds of a running loop, every cycle, for live plots and measurements.

:class:`LiveBuffer` is a loop observer: at the end of each cycle it stores one row (loop time,
then per joint the reference in use, position, velocity and effort, then the force along z of
each force-torque sensor in the chapter's sign) into a preallocated ring. It is written by the
loop thread only; other threads read rows by their running number (:attr:`count` rows have been
written since the last :meth:`clear`), and only rows the writer cannot be overwriting.
SI units: s, m or rad, m/s or rad/s, N or N·m, N.
"""

from __future__ import annotations

import numpy as np

from jointctl.hardware.interface import HardwareInterface

QUANTITIES = ("reference", "position", "velocity", "effort")
_GUARD_ROWS = 64  # rows next to the writer that readers leave alone


class LiveBuffer:
    """A ring of ``capacity`` rows; a callable loop observer."""

    def __init__(self, hardware: HardwareInterface, references, capacity: int) -> None:
        if capacity <= _GUARD_ROWS:
            raise ValueError(f"capacity must be above {_GUARD_ROWS} rows, got {capacity}")
        self.hardware = hardware
        self._references = references
        self.joint_names = tuple(hardware.joint_names)
        self.sensor_names = tuple(hardware.sensor_names)
        self.columns = ("time",) + tuple(f"{j}.{q}" for q in QUANTITIES for j in self.joint_names) + tuple(
            f"{s}.force_z" for s in self.sensor_names)
        self.capacity = capacity
        self.data = np.zeros((capacity, len(self.columns)))
        self.count = 0

    def clear(self) -> None:
        """Forget every row (the loop is not running)."""
        self.count = 0

    def column(self, name: str) -> int:
        return self.columns.index(name)

    def __call__(self, time_s: float) -> None:
        hw = self.hardware
        row = [time_s, *self._references, *hw.position, *hw.velocity, *hw.effort]
        for name in self.sensor_names:
            row.append(hw.wrenches[name][2])
        self.data[self.count % self.capacity] = row
        self.count += 1  # after the row: a reader that sees the count sees the row

    def readable_from(self) -> int:
        """The oldest row number a reader may still ask for."""
        return max(0, self.count - self.capacity + _GUARD_ROWS)

    def rows(self, start: int, stop: int | None = None, columns: list[int] | None = None,
             every: int = 1) -> tuple[np.ndarray, int, int]:
        """Rows ``start <= k < stop`` whose number is a multiple of ``every`` (a copy), clipped to
        what is readable; returns (rows, first row number asked, stop)."""
        end = self.count if stop is None else min(stop, self.count)
        first = max(start, self.readable_from())
        first += (-first) % every
        numbers = np.arange(first, end, every)
        cols = slice(None) if columns is None else columns
        block = self.data[numbers % self.capacity][:, cols] if len(numbers) else np.zeros(
            (0, len(self.columns) if columns is None else len(columns)))
        return block, first, max(end, first)

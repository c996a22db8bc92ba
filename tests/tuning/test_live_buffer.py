"""The live buffer: one row per cycle, readable by row number, safe to read while it wraps."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.hardware.interface import HardwareInterface
from jointctl.tuning.live_buffer import LiveBuffer


class _Hardware(HardwareInterface):
    def read(self) -> None:
        pass

    def write(self) -> None:
        pass

    def advance(self, period_s: float) -> None:
        pass

    def command_interfaces(self, joint: str) -> frozenset[str]:
        return frozenset()


def filled(cycles: int, capacity: int = 100) -> LiveBuffer:
    hw = _Hardware(("a", "b"), ("ft",))
    references = [0.0, 0.0]
    buffer = LiveBuffer(hw, references, capacity)
    for k in range(cycles):
        references[0] = -k
        hw.position[:] = [k * 0.001, 2.0]
        hw.wrenches["ft"][2] = -50.0
        buffer(k * 0.001)
    return buffer


def test_columns_are_time_then_each_quantity_per_joint_then_sensor_forces():
    buffer = filled(0)
    assert buffer.columns == ("time", "a.reference", "b.reference", "a.position", "b.position", "a.velocity",
                              "b.velocity", "a.effort", "b.effort", "ft.force_z")


def test_rows_are_read_by_number_and_thinned_by_their_number():
    buffer = filled(50, capacity=1000)
    rows, first, stop = buffer.rows(10, 20, [buffer.column("time"), buffer.column("a.reference")])
    assert (first, stop) == (10, 20)
    assert rows[:, 0] == pytest.approx(np.arange(10, 20) * 0.001)
    assert rows[:, 1] == pytest.approx(-np.arange(10, 20))
    thinned, first, _ = buffer.rows(9, None, [0], every=4)
    assert first == 12 and thinned[:, 0] == pytest.approx(np.arange(12, 50, 4) * 0.001)
    assert buffer.rows(0, None, [buffer.column("ft.force_z")])[0][:, 0] == pytest.approx(-50.0)


def test_after_wrapping_only_rows_the_writer_is_not_overwriting_are_readable():
    buffer = filled(1000, capacity=100)
    assert buffer.readable_from() == 1000 - 100 + 64
    rows, first, stop = buffer.rows(0, None, [0])
    assert first == buffer.readable_from() and stop == 1000
    assert rows[:, 0] == pytest.approx(np.arange(first, 1000) * 0.001)


def test_clear_starts_over_and_a_too_small_ring_is_refused():
    buffer = filled(30)
    buffer.clear()
    assert buffer.count == 0 and len(buffer.rows(0)[0]) == 0
    with pytest.raises(ValueError, match="capacity"):
        LiveBuffer(_Hardware(("a",)), [0.0], 10)

"""A test double of hardware that servos its joints itself: position command interfaces only, and
joints that follow the commands with a lag of their own, as an industrial controller's servos do.

Each joint is a first-order position servo with time constant ``lag_s``: over a period ``dt`` it
closes the fraction ``1 - exp(-dt / lag_s)`` of the gap between where it is and the last position
command written. So the measured position is never the command itself while the joint moves
(it lags by about ``velocity * lag_s``): a controller that holds the measured position can be told
from one that repeats its last command. A joint commanded where it is stays there exactly (the
gap is 0). ``velocity`` is the position's change over the last period.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from jointctl.hardware.interface import POSITION, HardwareInterface

#: The servos' time constant [s] (a stiff industrial position loop: some 10 ms).
LAG_S = 0.01


class ServoedHardware(HardwareInterface):
    """Joints ``joint_names`` at ``start`` [rad or m], servoed toward each position command when advanced."""

    def __init__(self, joint_names: Sequence[str], start: Sequence[float] | None = None,
                 interfaces=frozenset({POSITION}), lag_s: float = LAG_S) -> None:
        super().__init__(tuple(joint_names))
        if start is not None:
            self.position[:] = [float(q) for q in start]
        self.interfaces = frozenset(interfaces)
        self.lag_s = lag_s
        #: Every position command written, one list per cycle.
        self.sent: list[list[float]] = []

    def command_interfaces(self, joint: str) -> frozenset[str]:
        self.joint_index(joint)
        return self.interfaces

    def read(self) -> None:
        pass

    def write(self) -> None:
        self.sent.append(list(self.command_buffer(POSITION)))

    def advance(self, period_s: float) -> None:
        if not self.sent:
            return
        keep = math.exp(-period_s / self.lag_s)
        before = list(self.position)
        self.position[:] = [c + (q - c) * keep for q, c in zip(self.position, self.sent[-1])]
        self.velocity[:] = [(q - b) / period_s for q, b in zip(self.position, before)]

"""A test double of hardware that servos its joints itself: position command interfaces only, and
the joints follow the commands exactly, one period late (an industrial controller, idealised)."""

from __future__ import annotations

from collections.abc import Sequence

from jointctl.hardware.interface import POSITION, HardwareInterface


class ServoedHardware(HardwareInterface):
    """Joints ``joint_names`` at ``start`` [rad or m], moving to each position command when advanced."""

    def __init__(self, joint_names: Sequence[str], start: Sequence[float] | None = None,
                 interfaces=frozenset({POSITION})) -> None:
        super().__init__(tuple(joint_names))
        if start is not None:
            self.position[:] = [float(q) for q in start]
        self.interfaces = frozenset(interfaces)
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
        if self.sent:
            self.position[:] = self.sent[-1]

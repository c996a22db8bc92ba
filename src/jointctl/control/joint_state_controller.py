"""``joint_state_controller/JointStateController``: joint states at ``publish_rate``.

Every ``1/publish_rate`` seconds of loop time it takes a
:class:`JointStateSample` (sensor_msgs/JointState semantics), stores it in
:attr:`JointStateController.latest` (a single-slot door edges read) and hands
it to each subscriber. Subscribers run inside the loop: they must only queue.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from jointctl.control.controller import Controller
from jointctl.control.params import Params
from jointctl.hardware.interface import HardwareInterface
from jointctl.model.robot_model import RobotModel


@dataclass(frozen=True)
class JointStateSample:
    """Joint names and their position, velocity and effort at ``time_s`` (SI units)."""

    time_s: float
    name: tuple[str, ...]
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    effort: tuple[float, ...]


class JointStateController(Controller):
    """Publishes every joint's state; claims no command interface."""

    def __init__(self, name: str, params: Params) -> None:
        super().__init__(name, params)
        self.publish_rate_hz = params.number("publish_rate", 50.0, positive=True)
        params.reject_unknown({"type"})
        self.latest: JointStateSample | None = None
        self.published = 0
        self._subscribers: list[Callable[[JointStateSample], None]] = []

    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        return ()

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        self.hardware = hardware
        self.period_s = 1.0 / self.publish_rate_hz

    def subscribe(self, callback: Callable[[JointStateSample], None]) -> None:
        self._subscribers.append(callback)

    def start(self, time_s: float) -> None:
        # The first publication is at the first multiple of the period at or after time_s.
        self._next_k = math.ceil(time_s / self.period_s - 1e-9)

    def update(self, time_s: float, period_s: float) -> None:
        # Publish on the k-th multiple of the period; integer counting keeps it drift-free.
        if time_s + 1e-9 < self._next_k * self.period_s:
            return
        self._next_k += 1
        hw = self.hardware
        sample = JointStateSample(time_s, hw.joint_names, tuple(hw.position),
                                  tuple(hw.velocity), tuple(hw.effort))
        self.latest = sample
        self.published += 1
        for callback in self._subscribers:
            callback(sample)

"""The deterministic control loop and its clocks."""

from jointctl.runtime.clock import SimulatedClock, WallClockPacer
from jointctl.runtime.loop import ControlLoop

__all__ = ["ControlLoop", "SimulatedClock", "WallClockPacer"]

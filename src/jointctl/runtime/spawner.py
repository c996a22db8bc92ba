"""A loop input that puts objects into a simulated world at their times, through the hardware's simulation door."""

from __future__ import annotations

from collections.abc import Iterable

from jointctl.runtime.loop import first_cycle_at


class ObjectSpawner:
    """Spawns each object (an ``ObjectSpec``: ``spawn_at_s`` [s] loop time) at the first cycle whose loop time
    reaches its time; ``pending`` are those still to come, in time order."""

    def __init__(self, simulation, objects: Iterable) -> None:
        self.simulation = simulation
        self.pending = sorted(objects, key=lambda o: o.spawn_at_s)

    def __call__(self, time_s: float) -> None:
        pending = self.pending
        while pending and time_s + 1e-9 >= pending[0].spawn_at_s:
            self.simulation.spawn(pending.pop(0))

    def next_cycle(self, cycle: int, period_s: float) -> int | None:
        """The first cycle from ``cycle`` on (loop time ``k * period_s``) at which it spawns, or None."""
        if not self.pending:
            return None
        return first_cycle_at(self.pending[0].spawn_at_s, cycle, period_s)

"""A loop input that submits trajectory goals to their executors at their times (a scenario's ``goals``)."""

from __future__ import annotations

from collections.abc import Callable, Iterable

from jointctl.runtime.loop import first_cycle_at
from jointctl.trajectory.errors import InvalidTrajectory


class GoalSender:
    """Submits each goal ``(at_s, executor, make)`` (``make(executor)``: its trajectory) to its executor at the
    first cycle whose loop time reaches ``at_s`` [s]; the handles go to ``accepted``, a refusal to ``rejected`` as
    (loop time [s], the refusal), not raised into the loop."""

    def __init__(self, goals: Iterable[tuple[float, object, Callable]], accepted: list, rejected: list) -> None:
        self.pending = sorted(goals, key=lambda g: g[0])
        self.accepted = accepted
        self.rejected = rejected

    @property
    def executors(self) -> tuple:
        """The executors still to be sent a goal."""
        return tuple(executor for _, executor, _ in self.pending)

    def __call__(self, time_s: float) -> None:
        pending = self.pending
        while pending and time_s + 1e-9 >= pending[0][0]:
            _, executor, make = pending.pop(0)
            try:
                self.accepted.append(executor.submit(make(executor), now_s=time_s))
            except InvalidTrajectory as exc:
                self.rejected.append((time_s, exc))

    def next_cycle(self, cycle: int, period_s: float) -> int | None:
        """The first cycle from ``cycle`` on (loop time ``k * period_s``) at which it sends a goal, or None."""
        if not self.pending:
            return None
        return first_cycle_at(self.pending[0][0], cycle, period_s)

"""One loop, one thread: read -> update controllers -> write -> step.

Each cycle ``k`` runs at loop time ``t = k * period_s``:

1. *inputs* ``(t)``: command sources and edge doors hand their values to controllers;
2. ``hardware.read()``: joint state and sensors at time ``t``;
3. every running controller's ``update(t, period_s)``; a controller that raises, or leaves a
   non-finite command, is deactivated with its chain and its joints get their safe action
   (:meth:`~jointctl.control.manager.ControllerManager.fail`), within this cycle; the others run on;
4. ``hardware.write()``: efforts (or other commands) go out;
5. *observers* ``(t)``: recorders and publishers see the state and commands of this cycle;
6. ``hardware.advance(period_s)``: the physics steps (or real time passes);
7. the clock waits for the wall clock when pacing.

Inputs and observers are plain callables taking the loop time in seconds. With
simulated time and the same inputs the loop produces the same trace, bit for bit.

*The compiled path.* A loop given a ``compiler`` (the scenario's session gives
:func:`jointctl.compiled.plan.compile_loop`) asks it, at the start of each :meth:`ControlLoop.run`, for a compiled
run of the same cycles: when every part of the cycle has a compiled form, stretches of cycles run in machine code
with the same numbers and the same events at the same cycles; otherwise the compiler says why not and the loop
runs in Python. :attr:`ControlLoop.mode` says which (``compiled`` or ``python``) and
:attr:`ControlLoop.mode_reason` why Python. A compiled run is stopped by :meth:`~ControlLoop.request_stop` at the
end of a stretch, and a cycle whose commands are not finite is finished, and the run continued, in Python.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from jointctl.control.manager import ControllerManager
from jointctl.hardware.interface import HardwareInterface
from jointctl.runtime.clock import SimulatedClock, WallClockPacer

CycleHook = Callable[[float], None]
#: ``compiler(loop)``: a compiled run of ``loop`` (``run(k, end) -> (next cycle, half done)``), or the reason
#: (text) the loop runs in Python.
Compiler = Callable[["ControlLoop"], object]


def first_cycle_at(time_s: float, cycle: int, period_s: float) -> int:
    """The first cycle from ``cycle`` on whose loop time ``k * period_s`` reaches ``time_s`` [s] (to 1e-9 s, as
    the loop's inputs compare it): where a timed input (an object's spawn, a goal sent) acts."""
    k = max(cycle, int((time_s - 1e-9) / period_s) - 1)
    while k * period_s + 1e-9 < time_s:
        k += 1
    return k


class ControlLoop:
    """Runs the controllers of ``manager`` against ``hardware`` every ``period_s`` seconds."""

    def __init__(
        self,
        hardware: HardwareInterface,
        manager: ControllerManager,
        *,
        period_s: float = 0.001,
        clock: SimulatedClock | WallClockPacer | None = None,
    ) -> None:
        if not period_s > 0:
            raise ValueError(f"period_s must be positive, got {period_s}")
        self.hardware = hardware
        self.manager = manager
        self.period_s = period_s
        self.clock = clock or SimulatedClock()
        self.cycle = 0
        #: Hooks run at the start (inputs) and end (observers) of every cycle, in order. Tuples,
        #: replaced whole by add_*/remove_*: a thread may change them while the loop runs, and
        #: each cycle runs the hooks as they were when it began.
        self.inputs: tuple[CycleHook, ...] = ()
        self.observers: tuple[CycleHook, ...] = ()
        self.wall_time_s = 0.0
        self._stop_requested = False
        #: Offers each run a compiled path (see the module docstring); None: always Python.
        self.compiler: Compiler | None = None
        #: The path of the last (or running) :meth:`run`: ``compiled`` or ``python``; and why ``python``.
        self.mode = "python"
        self.mode_reason = "no compiled path was offered"

    @property
    def time_s(self) -> float:
        """Loop time [s] of the cycle running (updated as each cycle ends), or of the next to run."""
        return self.cycle * self.period_s

    def add_input(self, hook: CycleHook, *, first: bool = False) -> None:
        """Run ``hook(t)`` at the start of every cycle, after the inputs added before it (or before
        them all, with ``first``)."""
        self.inputs = (hook, *self.inputs) if first else (*self.inputs, hook)

    def remove_input(self, hook: CycleHook) -> None:
        self.inputs = tuple(h for h in self.inputs if h is not hook)

    def add_observer(self, hook: CycleHook) -> None:
        """Run ``hook(t)`` at the end of every cycle, after the hardware was written."""
        self.observers = (*self.observers, hook)

    def remove_observer(self, hook: CycleHook) -> None:
        self.observers = tuple(h for h in self.observers if h is not hook)

    def request_stop(self) -> None:
        """Ask a running :meth:`run` to return after the current cycle (thread-safe)."""
        self._stop_requested = True

    def run(self, duration_s: float | None = None, *, cycles: int | None = None) -> int:
        """Run for ``duration_s`` seconds of loop time, or ``cycles`` cycles, or until stopped.

        Returns the number of cycles run.
        """
        if duration_s is not None and duration_s < 0:
            raise ValueError(f"duration_s must not be negative, got {duration_s}")
        if cycles is None:
            cycles = -1 if duration_s is None else round(duration_s / self.period_s)
        elif cycles < 0:
            raise ValueError(f"cycles must not be negative, got {cycles}")
        period = self.period_s
        wait = self.clock.wait_for
        realtime = self.clock.realtime
        start_cycle = self.cycle
        k = start_cycle
        end = start_cycle + cycles if cycles >= 0 else -1
        self._stop_requested = False
        compiled = self._compiled_run()
        self.clock.start()
        wall_start = time.perf_counter()
        try:
            if compiled is not None:
                try:
                    k, half_done = compiled.run(k, end)
                finally:
                    k = self.cycle  # where the compiled stretches stopped (also when a warning raised)
                if half_done:  # cycle k updated, a command not finite: finished here, the run goes on in Python
                    self.run_cycle(k, from_update=len(self.manager.update_calls))
                    k += 1
            cycle = self.run_cycle
            while k != end and not self._stop_requested:
                cycle(k)
                k += 1
                if realtime:
                    wait((k - start_cycle) * period)
        finally:
            self.cycle = k
            self.wall_time_s += time.perf_counter() - wall_start
        return k - start_cycle

    def run_cycle(self, k: int, *, from_update: int | None = None) -> None:
        """Cycle ``k`` in Python (see the module docstring): inputs, read, the updates under the failure policy,
        the check for non-finite commands, write, observers, advance; then :attr:`cycle` is ``k + 1``.
        ``from_update``: the cycle was made up to that update (an index of the manager's updates) elsewhere (the compiled cycle's inputs, read and
        earlier updates); the updates from it on, and what follows, are made here."""
        t = k * self.period_s
        hw, manager = self.hardware, self.manager
        if from_update is None:
            for hook in self.inputs:
                hook(t)
            hw.read()
        failed = False
        for update in manager.update_calls if from_update is None else manager.update_calls[from_update:]:
            try:
                update(t, self.period_s)
            except Exception as exc:  # noqa: BLE001  (the failure policy: see ControllerManager)
                manager.fail_update(update, exc, t)
                failed = True
        for buf in hw.command_buffers:  # the command lists controllers were configured with
            total = sum(buf)
            if total - total:  # NaN: a non-finite command somewhere in the list
                failed = True
        if failed:
            manager.check_outputs(t)
        hw.write()
        for hook in self.observers:
            hook(t)
        hw.advance(self.period_s)
        self.cycle = k + 1  # edges read loop time (time_s) while the loop runs

    def _compiled_run(self):
        """The compiled run the compiler offers for this run, or None (with :attr:`mode_reason` set)."""
        if self.compiler is None:  # (mode_reason: whoever left it out may say why)
            self.mode = "python"
            return None
        offer = self.compiler(self)
        if isinstance(offer, str):
            self.mode, self.mode_reason = "python", offer
            return None
        self.mode, self.mode_reason = "compiled", None
        return offer

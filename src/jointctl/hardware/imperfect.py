"""A hardware interface seen through what a real robot's loop adds: late commands and noisy sensors.

:class:`ImperfectHardware` wraps another :class:`~jointctl.hardware.interface.HardwareInterface` (the
MuJoCo world, usually) and offers the same handles to the controllers:

- **latency**: the commands the controllers write in cycle ``k`` reach the wrapped hardware in cycle
  ``k + latency_cycles`` (a bus, a driver's buffer, a network hop). Until then the wrapped hardware
  keeps the commands it had when the wrapper was made (zero effort, usually).
- **sensor noise**: each measured position and velocity gets white Gaussian noise of standard deviation
  ``position_noise`` (m or rad) and ``velocity_noise`` (m/s or rad/s), drawn from a generator seeded
  with ``seed``, so the same seed gives the same run, bit for bit. Efforts and wrenches are passed as
  measured.

With no latency and no noise the wrapper changes nothing: the run is the wrapped hardware's own.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from jointctl.errors import ConfigError
from jointctl.hardware.interface import HardwareInterface

#: Cycles of noise drawn at once (drawing per cycle would cost more than the rest of a 1-DOF cycle).
NOISE_BLOCK_CYCLES = 1024


class ImperfectHardware(HardwareInterface):
    """``inner`` with commands ``latency_cycles`` control cycles late and noisy position and velocity
    (standard deviations ``position_noise`` [m or rad], ``velocity_noise`` [m/s or rad/s]; ``seed``)."""

    def __init__(self, inner: HardwareInterface, *, latency_cycles: int = 0, position_noise: float = 0.0,
                 velocity_noise: float = 0.0, seed: int | tuple[int, ...] = 0) -> None:
        if isinstance(latency_cycles, bool) or not isinstance(latency_cycles, int) or latency_cycles < 0:
            raise ConfigError("must be a whole number of control cycles, 0 or more", field="latency_cycles",
                              value=latency_cycles)
        for field, sigma in (("noise.position", position_noise), ("noise.velocity", velocity_noise)):
            if not (isinstance(sigma, (int, float)) and math.isfinite(sigma) and sigma >= 0):
                raise ConfigError("must be a standard deviation, 0 or more", field=field, value=sigma)
        if inner.takes_trajectories:
            raise ConfigError("this hardware executes whole trajectories itself: its latency is its own",
                              field="latency_cycles", value=latency_cycles)
        super().__init__(inner.joint_names, inner.sensor_names)
        self.inner = inner
        self.latency_cycles = latency_cycles
        self.position_noise = float(position_noise)
        self.velocity_noise = float(velocity_noise)
        self.simulation = inner.simulation
        self.wrenches = inner.wrenches  # the wrapped hardware's lists, refreshed in place by its read
        #: (own command list, the wrapped hardware's, the commands on their way: oldest first).
        self._paths: list[tuple[list[float], list[float], deque]] = []
        self._rng = np.random.default_rng(seed)
        self._noisy = self.position_noise > 0 or self.velocity_noise > 0
        self._noise_rows: list[tuple[list[float], list[float]]] = []
        self._noise_next = 0
        for interface in ("effort", "velocity", "position"):
            if interface in inner._commands:
                self.command_buffer(interface)

    # -- what the wrapped hardware says ------------------------------------------------------------------
    @property
    def fault(self) -> str | None:  # type: ignore[override]
        return self.inner.fault

    @property
    def in_motion(self) -> bool | None:  # type: ignore[override]
        return self.inner.in_motion

    def command_interfaces(self, joint: str) -> frozenset[str]:
        return self.inner.command_interfaces(joint)

    def command_buffer(self, interface: str) -> list[float]:
        """The list controllers write ``interface`` commands into; it reaches the wrapped hardware's
        list ``latency_cycles`` writes later."""
        buf = self._commands.get(interface)
        if buf is None:
            buf = super().command_buffer(interface)
            inner = self.inner.command_buffer(interface)
            buf[:] = inner
            on_the_way = deque(list(inner) for _ in range(self.latency_cycles))
            self._paths.append((buf, inner, on_the_way))
        return buf

    # -- the cycle -----------------------------------------------------------------------------------------
    def read(self) -> None:
        inner = self.inner
        inner.read()
        if self._noisy:
            if self._noise_next == len(self._noise_rows):
                self._draw_noise()
            dq, dv = self._noise_rows[self._noise_next]
            self._noise_next += 1
            self.position[:] = [q + e for q, e in zip(inner.position, dq)]
            self.velocity[:] = [v + e for v, e in zip(inner.velocity, dv)]
        else:
            self.position[:] = inner.position
            self.velocity[:] = inner.velocity
        self.effort[:] = inner.effort

    def _draw_noise(self) -> None:
        n = len(self.joint_names)
        dq = self._rng.standard_normal((NOISE_BLOCK_CYCLES, n)) * self.position_noise
        dv = self._rng.standard_normal((NOISE_BLOCK_CYCLES, n)) * self.velocity_noise
        self._noise_rows = list(zip(dq.tolist(), dv.tolist()))
        self._noise_next = 0

    def write(self) -> None:
        for own, inner, on_the_way in self._paths:
            if on_the_way:
                on_the_way.append(list(own))
                inner[:] = on_the_way.popleft()
            else:
                inner[:] = own
        self.inner.write()

    def advance(self, period_s: float) -> None:
        self.inner.advance(period_s)

    def reset(self) -> None:
        """The wrapped hardware's reset; the commands on their way are dropped (zero, as at the start)."""
        self.inner.reset()
        for own, inner, on_the_way in self._paths:
            own[:] = inner
            for pending in on_the_way:
                pending[:] = inner
        self.read()


__all__ = ["ImperfectHardware", "NOISE_BLOCK_CYCLES"]

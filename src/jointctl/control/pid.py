"""A PID with integral clamping and output limits, in the manner of ROS control_toolbox.

The command is ``u = p*e + i_term + d*e_dot``, clamped to ``[-output_limit,
output_limit]``. ``i_term`` accumulates ``i*e*dt`` and its contribution is
clamped to ``[i_clamp_min, i_clamp_max]``; with ``antiwindup`` the
accumulated state itself is clamped, so it never winds up beyond the clamp.

One deliberate difference from control_toolbox: when a YAML file gives no
``i_clamp`` the clamp defaults to the joint's effort limit (unbounded for a
joint without one), not to zero (control_toolbox's zero silently disables an
``i`` gain). Clamps given in YAML must be finite.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from jointctl.control.params import Params
from jointctl.errors import ConfigError


@dataclass(frozen=True)
class PidGains:
    """Gains in effort units per error unit (N/m, N·s/m, N/(m·s) for a prismatic position loop)."""

    p: float = 0.0
    i: float = 0.0
    d: float = 0.0
    i_clamp_min: float = 0.0
    i_clamp_max: float = 0.0
    antiwindup: bool = False

    def __post_init__(self) -> None:
        for name in ("p", "i", "d", "i_clamp_min", "i_clamp_max"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
                raise ConfigError("must be a number", field=f"pid.{name}", value=value)
        for name in ("p", "i", "d"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigError("must be finite", field=f"pid.{name}", value=getattr(self, name))
        for name in ("p", "i", "d"):
            if getattr(self, name) < 0:
                raise ConfigError("must not be negative", field=f"pid.{name}", value=getattr(self, name))
        if self.i_clamp_min > self.i_clamp_max:
            raise ConfigError("i_clamp_min is above i_clamp_max", field="pid.i_clamp_min",
                              value=self.i_clamp_min)

    @classmethod
    def from_params(cls, params: Params, *, default_i_clamp: float) -> PidGains:
        """Read ros_control ``pid: {p, i, d, i_clamp, i_clamp_min, i_clamp_max, antiwindup}``."""
        p = params.number("p", 0.0, minimum=0)
        i = params.number("i", 0.0, minimum=0)
        d = params.number("d", 0.0, minimum=0)
        clamp = params.number("i_clamp", None, minimum=0)
        if clamp is None:
            clamp = default_i_clamp
        i_max = params.number("i_clamp_max") if params.has("i_clamp_max") else clamp
        i_min = params.number("i_clamp_min") if params.has("i_clamp_min") else -clamp
        if i_min > i_max:
            raise params.error("is above i_clamp_max", "i_clamp_min", i_min)
        antiwindup = params.boolean("antiwindup", False)
        params.reject_unknown({"publish_state", "i_clamp_min", "i_clamp_max"})
        return cls(p, i, d, i_min, i_max, antiwindup)


class Pid:
    """One PID loop. Gains may be replaced while running (:meth:`set_gains`)."""

    def __init__(self, gains: PidGains, output_limit: float = math.inf) -> None:
        self.output_limit = float(output_limit)
        self.set_gains(gains)
        self.reset()

    def set_gains(self, gains: PidGains) -> None:
        """Replace the gains; takes effect at the next :meth:`compute` (one atomic store)."""
        self.gains = gains
        self._g = (gains.p, gains.i, gains.d, gains.i_clamp_min, gains.i_clamp_max, gains.antiwindup)

    def reset(self) -> None:
        self.i_state = 0.0

    def compute(self, error: float, error_rate: float, dt: float) -> float:
        """Effort for ``error`` and its rate ``error_rate`` [error/s] over ``dt`` seconds."""
        p, i, d, i_min, i_max, antiwindup = self._g
        i_state = self.i_state + i * dt * error
        if antiwindup:
            i_state = i_min if i_state < i_min else i_max if i_state > i_max else i_state
        self.i_state = i_state
        i_term = i_min if i_state < i_min else i_max if i_state > i_max else i_state
        u = p * error + i_term + d * error_rate
        limit = self.output_limit
        return limit if u > limit else -limit if u < -limit else u

"""control_toolbox 3.4.0's ``Pid`` (ROS 2 Jazzy), computing as its ``src/pid.cpp`` does, step for step.

ros2_controllers' controllers (pid_controller, joint_trajectory_controller) run this PID, which differs
from jointctl's own :class:`~jointctl.control.pid.Pid`:

- ``compute(error, dt_ns)`` (``computeCommand(error, dt)``) differentiates the **error**:
  ``error_dot = (error - p_error_last) / dt`` with ``p_error_last`` 0 after a reset, so the first call
  gives ``d·error/dt`` (a derivative kick even for a constant error); ``compute_with_rate(error,
  error_dot, dt_ns)`` takes the rate as given;
- the integral accumulates the error, ``i_error += dt·error``; without ``antiwindup`` the term
  ``i·i_error`` is clamped to ``[i_min, i_max]`` (so with the default clamps 0/0 the integral does
  nothing), with it (and ``i`` non-zero) ``i_error`` itself is clamped to ``[i_min/i, i_max/i]`` and
  the term is not;
- no output limit; ``dt`` is whole nanoseconds (``rclcpp::Duration``), ``dt = 0`` or a non-finite error
  (or rate) gives 0 and changes nothing but the last error and rate seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from jointctl.errors import ConfigError


@dataclass(frozen=True)
class ToolboxGains:
    """``control_toolbox::Pid::Gains``: p, i, d, the integral clamps i_max/i_min and antiwindup."""

    p: float = 0.0
    i: float = 0.0
    d: float = 0.0
    i_max: float = 0.0
    i_min: float = 0.0
    antiwindup: bool = False

    def __post_init__(self) -> None:
        if self.i_min > self.i_max:  # Pid's constructor throws, setGains skips the new gains
            raise ConfigError("i_clamp_min is above i_clamp_max", field="i_clamp_min", value=self.i_min)


def period_ns(period_s: float) -> int:
    """A period [s] as ``rclcpp::Duration::nanoseconds()``: whole nanoseconds."""
    return int(round(period_s * 1e9))


class ToolboxPid:
    """One control_toolbox PID; :meth:`set_gains` takes effect at the next compute (one atomic store)."""

    def __init__(self, gains: ToolboxGains = ToolboxGains()) -> None:
        self.gains = gains
        self.reset()

    def set_gains(self, gains: ToolboxGains) -> None:
        self.gains = gains

    def reset(self) -> None:
        """``Pid::reset()``: the last error, the errors and the command back to 0."""
        self.p_error_last = 0.0
        self.p_error = 0.0
        self.i_error = 0.0
        self.d_error = 0.0
        self.cmd = 0.0

    def compute(self, error: float, dt_ns: int) -> float:
        """``computeCommand(error, dt)``: the rate is the error's backward difference."""
        if dt_ns == 0 or not math.isfinite(error):
            return 0.0
        error_dot = (error - self.p_error_last) / (dt_ns / 1e9)
        self.p_error_last = error
        return self.compute_with_rate(error, error_dot, dt_ns)

    def compute_with_rate(self, error: float, error_dot: float, dt_ns: int) -> float:
        """``computeCommand(error, error_dot, dt)``."""
        g = self.gains
        self.p_error = error
        self.d_error = error_dot
        if dt_ns == 0 or not math.isfinite(error) or not math.isfinite(error_dot):
            return 0.0
        p_term = g.p * error
        self.i_error += (dt_ns / 1e9) * error
        if g.antiwindup and g.i != 0:
            low, high = sorted((g.i_min / g.i, g.i_max / g.i))
            self.i_error = min(max(self.i_error, low), high)
        i_term = g.i * self.i_error
        if not g.antiwindup:
            i_term = min(max(i_term, g.i_min), g.i_max)
        d_term = g.d * error_dot
        self.cmd = p_term + i_term + d_term
        return self.cmd


def shortest_angular_distance(from_angle: float, to_angle: float) -> float:
    """ROS ``angles::shortest_angular_distance``: ``to - from`` brought into (-π, π] [rad]."""
    result = math.fmod(to_angle - from_angle + math.pi, 2.0 * math.pi)
    return result + math.pi if result <= 0.0 else result - math.pi


__all__ = ["ToolboxGains", "ToolboxPid", "period_ns", "shortest_angular_distance"]

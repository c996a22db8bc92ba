"""How many physics steps make one control period."""

from __future__ import annotations

from jointctl.errors import ConfigError


def physics_steps(period_s: float, timestep_s: float, *, source: str | None = None, field: str = "period_s",
                  value: object = None) -> int:
    """The whole number of ``timestep_s`` physics steps in one ``period_s`` control period [s];
    ConfigError naming ``field`` (and ``value``, default the period) when it is not whole."""
    steps = round(period_s / timestep_s)
    if steps < 1 or abs(steps * timestep_s - period_s) > 1e-9 * max(1.0, period_s):
        raise ConfigError(f"the loop period must be a whole number of physics steps of {timestep_s} s",
                          source=source, field=field, value=period_s if value is None else value)
    return steps

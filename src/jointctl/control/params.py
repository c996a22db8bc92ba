"""Reading controller parameters from a YAML mapping, with errors that name the field.

:class:`Params` wraps one controller's mapping and remembers where it came
from (file and dotted field path) so every refusal reads like
``config/gains.yaml: one_DOF_robot.joint1_position_controller.pid.p: must not
be negative (got -5.0)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from jointctl.errors import ConfigError
from jointctl.validate import checked_number, real_number

_MISSING = object()


class Params:
    """A mapping of parameters at ``field`` in ``source``."""

    def __init__(self, values: Any, *, source: str | None, field: str) -> None:
        if not isinstance(values, Mapping):
            raise ConfigError("must be a mapping of parameters", source=source, field=field,
                              value=values)
        self.values = dict(values)
        self.source = source
        self.field = field
        self._used: set[str] = set()

    def path(self, key: str) -> str:
        return f"{self.field}.{key}" if self.field else key

    def error(self, message: str, key: str, value: Any = _MISSING) -> ConfigError:
        if value is _MISSING:
            return ConfigError(message, source=self.source, field=self.path(key))
        return ConfigError(message, source=self.source, field=self.path(key), value=value)

    def has(self, key: str) -> bool:
        return key in self.values

    def raw(self, key: str, default: Any = _MISSING) -> Any:
        self._used.add(key)
        if key not in self.values:
            if default is _MISSING:
                raise self.error("is required", key)
            return default
        return self.values[key]

    def string(self, key: str, default: Any = _MISSING) -> str:
        value = self.raw(key, default)
        if not isinstance(value, str) or not value:
            raise self.error("must be a non-empty string", key, value)
        return value

    def number(self, key: str, default: Any = _MISSING, *, minimum: float | None = None,
               positive: bool = False) -> float:
        value = self.raw(key, default)
        if value is None and default is None:
            return None  # type: ignore[return-value]
        shown = value if real_number(value) is None else real_number(value)  # the number as read: 5 -> 5.0
        return checked_number(value, lambda message: self.error(message, key, shown), positive=positive,
                              minimum=minimum)

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        value = self.raw(key, default)
        if not isinstance(value, bool):
            raise self.error("must be true or false", key, value)
        return value

    def child(self, key: str) -> Params:
        return Params(self.raw(key), source=self.source, field=self.path(key))

    def reject_unknown(self, allowed: set[str] | None = None) -> None:
        """Refuse keys that were neither read nor listed in ``allowed`` (catches typos)."""
        known = self._used | (allowed or set())
        for key in self.values:
            if key not in known:
                raise self.error(f"unknown parameter (known: {', '.join(sorted(known))})", key,
                                 self.values[key])

"""Reading controller parameters from a YAML mapping, with errors that name the field.

:class:`Params` wraps one controller's mapping and remembers where it came
from (file and dotted field path) so every refusal reads like
``config/gains.yaml: one_DOF_robot.joint1_position_controller.pid.p: must not
be negative (got -5.0)``.

A key the controller does not know is reported before anything else it would say about the
entry: ``...joint1_position_controller.jont: unknown field (did you mean 'joint'?)`` rather than
``joint: is required``. The keys a controller knows are the ones it asks about (read, or asked
after with :meth:`Params.has`, such as an optional ``feedforward`` block) plus those it lists in
:meth:`Params.reject_unknown`, so the list in the message is what that controller accepts.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping
from typing import Any

from jointctl.errors import ConfigError
from jointctl.validate import checked_number, real_number

_MISSING = object()
#: How alike (difflib's ratio) a given key and a missing required key must be for the given one to be
#: reported as its misspelling: one dropped, doubled, swapped or wrong letter in a name of 4 letters or
#: more is 0.75 or above; distinct names that share a word (``joint_damping``/``damping``, 0.7) are below.
MISSPELLING_RATIO = 0.75


class Params:
    """A mapping of parameters at ``field`` in ``source``."""

    def __init__(self, values: Any, *, source: str | None, field: str) -> None:
        if not isinstance(values, Mapping):
            raise ConfigError("must be a mapping of parameters", source=source, field=field,
                              value=values)
        self.values = dict(values)
        self.source = source
        self.field = field
        #: Every key the controller asked about (read or :meth:`has`): the keys it accepts.
        self._used: set[str] = set()

    def path(self, key: str) -> str:
        return f"{self.field}.{key}" if self.field else key

    def error(self, message: str, key: str, value: Any = _MISSING) -> ConfigError:
        if value is _MISSING:
            return ConfigError(message, source=self.source, field=self.path(key))
        return ConfigError(message, source=self.source, field=self.path(key), value=value)

    def has(self, key: str) -> bool:
        """Whether ``key`` is given; asking makes it a known key (an optional block the controller accepts)."""
        self._used.add(key)
        return key in self.values

    def raw(self, key: str, default: Any = _MISSING) -> Any:
        self._used.add(key)
        if key not in self.values:
            if default is _MISSING:
                self._reject_misspelling_of(key)
                raise self.error("is required", key)
            return default
        return self.values[key]

    def _reject_misspelling_of(self, key: str) -> None:
        """Before saying the required ``key`` is missing: a given key not asked about yet that reads
        like ``key`` (``jont`` or ``jiont`` for ``joint``: a difflib ratio of at least
        :data:`MISSPELLING_RATIO`, about one slip of the keyboard) is the user's spelling of it,
        reported as unknown. Names that only share a word (``wrist_joints`` beside a missing
        ``joints``, 0.67) are other fields the controller may read later, not misspellings."""
        for given in self.values:
            if (isinstance(given, str) and given not in self._used
                    and difflib.get_close_matches(given, [key], cutoff=MISSPELLING_RATIO)):
                raise self.error(f"unknown field (did you mean {key!r}?)", given, self.values[given])

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

    def reject_unknown(self, allowed: Iterable[str] | None = None) -> None:
        """Refuse keys that were neither asked about nor listed in ``allowed`` (catches typos),
        naming the nearest known key and listing them all."""
        known = self._used | set(allowed or ())
        for key in self.values:
            if key not in known:
                raise self.error(unknown_field_message(str(key), known), str(key), self.values[key])


def unknown_field_message(key: str, known: Iterable[str]) -> str:
    """``unknown field (did you mean 'joint'? known: joint, pid, type)``: the nearest known key
    (difflib) when one is close, and the known keys."""
    known = sorted(known)
    nearest = difflib.get_close_matches(key, known, n=1)
    hint = f"did you mean {nearest[0]!r}? " if nearest else ""
    return f"unknown field ({hint}known: {', '.join(known)})"

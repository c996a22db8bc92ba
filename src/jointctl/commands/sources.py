"""Command signals a scenario feeds to a joint controller's command.

The control loop samples a source once per cycle with :meth:`CommandSource.sample`
at the loop time ``t`` (seconds, starting at 0). The unit of the returned value
is the unit of the command it feeds (rad for a position command, rad/s for a
velocity command, N·m for an effort command). Every source is deterministic.

Rate-limited sources (:class:`SineSource`, :class:`ExpressionSource`) behave
like a ROS node publishing at ``rate_hz``: message ``k`` is published at
``t_k = k / rate_hz`` and its value holds until the next message. ``sample``
works out ``k = floor(t * rate_hz + 1e-9)`` and only computes a new value when
``k`` changes; :meth:`CommandSource.reset` forgets the cached message.

Scenario files describe a source as a mapping, read by
:func:`command_source_from_config`::

    {type: constant, value: -0.3}
    {type: step, from: -0.2, to: -0.5, at: 0.5}
    {type: step, from: -0.2, to: -0.5, at: 0.5, ramp_s: 0.05}   (a ramp from at to at + ramp_s)
    {type: sine, amplitude: 0.1, frequency_hz: 3, offset: -0.5, rate_hz: 100, derivative: false}
    {type: expression, expression: "0.1*sin(i/5)-0.5", rate_hz: 100}
    {type: chirp, amplitude: 0.05, f_start_hz: 0.5, f_end_hz: 10, duration_s: 8, offset: -0.5, at: 1.0}
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field as dataclass_field
from typing import Any

from jointctl.errors import ConfigError, ExpressionError
from jointctl.commands.expression import Expression, parse_expression

__all__ = [
    "ChirpSource",
    "CommandSource",
    "ConstantSource",
    "ExpressionSource",
    "SineSource",
    "SourceFeed",
    "StepSource",
    "command_source_from_config",
]

_EPSILON = 1e-9
"""Added to ``t * rate_hz`` so a loop time a rounding error short of ``t_k`` still counts as message ``k``."""


def _number(value: Any, field: str, source: str | None) -> float:
    """``value`` as a finite float, or a :class:`ConfigError` naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        hint = ""
        if isinstance(value, str):
            try:
                float(value)
                hint = " (write it as a YAML number, e.g. 1.0e-3 rather than 1e-3)"
            except ValueError:
                pass
        raise ConfigError(f"must be a number{hint}", source=source, field=field, value=value)
    number = float(value)
    if not math.isfinite(number):
        raise ConfigError("must be a finite number", source=source, field=field, value=value)
    return number


def _rate(value: Any, field: str, source: str | None) -> float:
    rate = _number(value, field, source)
    if rate <= 0.0:
        raise ConfigError("rate must be above 0 Hz", source=source, field=field, value=value)
    return rate


class _Hold:
    """Mutable cache of a rate-limited source: the last message and its value."""

    __slots__ = ("k", "value", "has_value", "rejected", "first_error")

    def __init__(self) -> None:
        self.clear()

    def clear(self) -> None:
        self.k: int | None = None
        self.value = 0.0
        self.has_value = False
        self.rejected = 0
        self.first_error: str | None = None


class CommandSource:
    """Base class of command signals: ``sample(t)`` gives the command at loop time ``t`` (s)."""

    __slots__ = ()

    def sample(self, t: float) -> float:
        """Command value at loop time ``t`` (seconds, from 0), in the command's unit."""
        raise NotImplementedError

    def reset(self) -> None:
        """Forget cached messages and error counts, as before the first sample."""

    def extremes(self) -> tuple[tuple[str, float], ...]:
        """The values that bound every value the source sends, each with the key of its mapping that sets it
        (``("to", -0.5)``); empty when they are known only as it runs (an expression)."""
        return ()

    @property
    def rejected_samples(self) -> int:
        """Messages whose evaluation failed and were replaced by the last good value."""
        return 0

    @property
    def last_error(self) -> str | None:
        """Message of the first evaluation error since the last reset, or ``None``."""
        return None


@dataclass(frozen=True)
class ConstantSource(CommandSource):
    """The same ``value`` at every time."""

    value: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _number(self.value, "value", None))

    def sample(self, t: float) -> float:
        return self.value

    def extremes(self) -> tuple[tuple[str, float], ...]:
        return (("value", self.value),)


@dataclass(frozen=True)
class StepSource(CommandSource):
    """``initial`` for ``t < at_s``, ``final`` from ``at_s + ramp_s`` (seconds) on, and between the two a
    straight ramp (``ramp_s`` 0, the default: a step). A ramp is what a control engineer puts before a loop
    whose derivative acts on the error: a step's first cycle asks ``d·Δ/period`` (the derivative kick), a
    ramp's only ``d·Δ/ramp_s``."""

    initial: float
    final: float
    at_s: float
    ramp_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("initial", "final", "at_s", "ramp_s"):
            object.__setattr__(self, name, _number(getattr(self, name), name, None))
        if self.ramp_s < 0.0:
            raise ConfigError("must be 0 s or more", field="ramp_s", value=self.ramp_s)

    def sample(self, t: float) -> float:
        if t < self.at_s:
            return self.initial
        if t >= self.at_s + self.ramp_s:
            return self.final
        return self.initial + (self.final - self.initial) * (t - self.at_s) / self.ramp_s

    def extremes(self) -> tuple[tuple[str, float], ...]:
        return (("from", self.initial), ("to", self.final))


@dataclass(frozen=True)
class SineSource(CommandSource):
    """A sine published at ``rate_hz`` like the chapter's sine commander node.

    Message ``k`` is published at ``t_k = k / rate_hz`` (s) and holds until the
    next one. Its value is ``offset + amplitude * sin(2*pi*frequency_hz*t_k)``,
    or with ``derivative=True`` the velocity
    ``2*pi*frequency_hz*amplitude * cos(2*pi*frequency_hz*t_k)`` (command
    unit per second; no offset).
    """

    amplitude: float
    frequency_hz: float
    offset: float = 0.0
    rate_hz: float = 100.0
    derivative: bool = False
    _hold: _Hold = dataclass_field(default_factory=_Hold, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("amplitude", "frequency_hz", "offset"):
            object.__setattr__(self, name, _number(getattr(self, name), name, None))
        if self.frequency_hz < 0.0:
            raise ConfigError("frequency must be 0 Hz or more", field="frequency_hz", value=self.frequency_hz)
        object.__setattr__(self, "rate_hz", _rate(self.rate_hz, "rate_hz", None))
        if not isinstance(self.derivative, bool):
            raise ConfigError("must be true or false", field="derivative", value=self.derivative)

    def sample(self, t: float) -> float:
        k = math.floor(t * self.rate_hz + _EPSILON)
        hold = self._hold
        if k != hold.k:
            omega = 2.0 * math.pi * self.frequency_hz
            t_k = k / self.rate_hz
            if self.derivative:
                hold.value = omega * self.amplitude * math.cos(omega * t_k)
            else:
                hold.value = self.offset + self.amplitude * math.sin(omega * t_k)
            hold.k = k
        return hold.value

    def reset(self) -> None:
        self._hold.clear()

    def extremes(self) -> tuple[tuple[str, float], ...]:
        """The offset and the crests offset ± |amplitude| (a velocity sine: ± 2π·f·|amplitude|), which the
        messages reach to within their sampling."""
        if self.derivative:
            crest = 2.0 * math.pi * self.frequency_hz * abs(self.amplitude)
            return (("amplitude", crest), ("amplitude", -crest))
        return (("offset", self.offset), ("amplitude", self.offset + abs(self.amplitude)),
                ("amplitude", self.offset - abs(self.amplitude)))


@dataclass(frozen=True)
class ChirpSource(CommandSource):
    """A linear chirp: from ``at_s`` for ``duration_s`` (seconds), ``offset + amplitude·sin(φ(τ))`` with
    ``τ = t - at_s`` and ``φ(τ) = 2π·(f_start_hz·τ + ½·(f_end_hz - f_start_hz)·τ²/duration_s)``: its frequency
    sweeps in a straight line from ``f_start_hz`` to ``f_end_hz``; ``offset`` before and after. Sampled at
    every loop time (no publishing rate: a chirp aliases at a rate below twice its end frequency), the
    signal of a frequency-response measurement fed to a loop by hand."""

    amplitude: float
    f_start_hz: float
    f_end_hz: float
    duration_s: float
    offset: float = 0.0
    at_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("amplitude", "f_start_hz", "f_end_hz", "duration_s", "offset", "at_s"):
            object.__setattr__(self, name, _number(getattr(self, name), name, None))
        for name in ("f_start_hz", "f_end_hz"):
            if getattr(self, name) < 0.0:
                raise ConfigError("frequency must be 0 Hz or more", field=name, value=getattr(self, name))
        if self.duration_s <= 0.0:
            raise ConfigError("must be above 0 s", field="duration_s", value=self.duration_s)

    def sample(self, t: float) -> float:
        tau = t - self.at_s
        if tau < 0.0 or tau > self.duration_s:
            return self.offset
        phase = 2.0 * math.pi * (self.f_start_hz * tau
                                 + 0.5 * (self.f_end_hz - self.f_start_hz) * tau * tau / self.duration_s)
        return self.offset + self.amplitude * math.sin(phase)

    def extremes(self) -> tuple[tuple[str, float], ...]:
        """The offset and the crests offset ± |amplitude|."""
        return (("offset", self.offset), ("amplitude", self.offset + abs(self.amplitude)),
                ("amplitude", self.offset - abs(self.amplitude)))


class ExpressionSource(CommandSource):
    """An expression (see :mod:`jointctl.commands.expression`) published at ``rate_hz``.

    Message ``k`` is published at ``t_k = k / rate_hz`` (s) with ``i = k`` and
    ``t = t_k`` and holds until the next one. A message whose evaluation fails
    (``log(t)`` at ``t = 0``, ``1/(i-3)`` at ``i = 3``...) is rejected: the last
    good value holds, :attr:`rejected_samples` counts it and :attr:`last_error`
    keeps the first such error message. If no message has succeeded yet,
    ``sample`` raises the :class:`ExpressionError` so the run refuses to start.
    ``field`` and ``source`` name the expression in error messages.
    """

    __slots__ = ("expression", "rate_hz", "_hold")

    def __init__(
        self,
        expression_text: str,
        rate_hz: float = 100.0,
        *,
        field: str = "expression",
        source: str | None = None,
    ) -> None:
        self.expression: Expression = parse_expression(expression_text, field=field, source=source)
        self.rate_hz: float = _rate(rate_hz, "rate_hz", source)
        self._hold = _Hold()

    @property
    def expression_text(self) -> str:
        return self.expression.text

    def sample(self, t: float) -> float:
        k = math.floor(t * self.rate_hz + _EPSILON)
        hold = self._hold
        if k == hold.k:
            return hold.value
        hold.k = k
        try:
            hold.value = self.expression.evaluate(k, k / self.rate_hz)
        except ExpressionError as exc:
            hold.rejected += 1
            if hold.first_error is None:
                hold.first_error = str(exc)
            if not hold.has_value:
                hold.k = None  # nothing to hold: evaluate again next time
                raise
            return hold.value
        hold.has_value = True
        return hold.value

    def reset(self) -> None:
        self._hold.clear()

    @property
    def rejected_samples(self) -> int:
        return self._hold.rejected

    @property
    def last_error(self) -> str | None:
        return self._hold.first_error

    def __repr__(self) -> str:
        return f"ExpressionSource({self.expression.text!r}, rate_hz={self.rate_hz!r})"


class SourceFeed:
    """A loop input handing ``source``'s value at loop time t to ``controller``'s edge door,
    ``set_reference`` (the run's compiled cycle, :mod:`jointctl.compiled`, knows it by this type)."""

    __slots__ = ("source", "controller", "_sample", "_set_reference")

    def __init__(self, source: CommandSource, controller) -> None:
        self.source = source
        self.controller = controller
        self._sample = source.sample
        self._set_reference = controller.set_reference

    def __call__(self, time_s: float) -> None:
        self._set_reference(self._sample(time_s))


_KEYS: dict[str, tuple[frozenset[str], frozenset[str]]] = {
    # type: (required keys, optional keys), besides "type"
    "constant": (frozenset({"value"}), frozenset()),
    "step": (frozenset({"from", "to", "at"}), frozenset({"ramp_s"})),
    "sine": (frozenset({"amplitude", "frequency_hz"}), frozenset({"offset", "rate_hz", "derivative"})),
    "expression": (frozenset({"expression"}), frozenset({"rate_hz"})),
    "chirp": (frozenset({"amplitude", "f_start_hz", "f_end_hz", "duration_s"}), frozenset({"offset", "at"})),
}


def command_source_from_config(config: Mapping[str, Any], *, field: str, source: str | None) -> CommandSource:
    """Build a source from its scenario mapping (see the module docstring).

    ``field`` is the dotted path of the mapping in its file and ``source``
    the file; errors are :class:`ConfigError` (or :class:`ExpressionError`
    for a bad expression) naming ``f"{field}.<key>"`` and the bad value.
    """
    if not isinstance(config, Mapping):
        raise ConfigError("a command source must be a mapping with a 'type' key", source=source, field=field, value=config)
    if "type" not in config:
        raise ConfigError(
            f"missing key 'type' (one of: {', '.join(_KEYS)})", source=source, field=f"{field}.type"
        )
    kind = config["type"]
    if not isinstance(kind, str) or kind not in _KEYS:
        raise ConfigError(
            f"unknown command source type (known: {', '.join(_KEYS)})",
            source=source,
            field=f"{field}.type",
            value=kind,
        )
    required, optional = _KEYS[kind]
    for key in config:
        if key != "type" and key not in required and key not in optional:
            known = ", ".join(sorted(required | optional))
            raise ConfigError(
                f"unknown key for a {kind} source (known: type, {known})",
                source=source,
                field=f"{field}.{key}",
                value=config[key],
            )
    for key in sorted(required):
        if key not in config:
            raise ConfigError(f"missing key for a {kind} source", source=source, field=f"{field}.{key}")

    def number(key: str, default: float | None = None) -> float:
        if key not in config and default is not None:
            return default
        return _number(config[key], f"{field}.{key}", source)

    if kind == "constant":
        return ConstantSource(number("value"))
    if kind == "step":
        ramp_s = number("ramp_s", 0.0)
        if ramp_s < 0.0:
            raise ConfigError("must be 0 s or more", source=source, field=f"{field}.ramp_s", value=config["ramp_s"])
        return StepSource(number("from"), number("to"), number("at"), ramp_s)
    if kind == "chirp":
        for key in ("f_start_hz", "f_end_hz"):
            if number(key) < 0.0:
                raise ConfigError("frequency must be 0 Hz or more", source=source, field=f"{field}.{key}",
                                  value=config[key])
        if number("duration_s") <= 0.0:
            raise ConfigError("must be above 0 s", source=source, field=f"{field}.duration_s",
                              value=config["duration_s"])
        return ChirpSource(number("amplitude"), number("f_start_hz"), number("f_end_hz"), number("duration_s"),
                           number("offset", 0.0), number("at", 0.0))
    rate_hz = number("rate_hz", 100.0)
    if rate_hz <= 0.0:
        raise ConfigError("rate must be above 0 Hz", source=source, field=f"{field}.rate_hz", value=config["rate_hz"])
    if kind == "sine":
        frequency_hz = number("frequency_hz")
        if frequency_hz < 0.0:
            raise ConfigError(
                "frequency must be 0 Hz or more",
                source=source,
                field=f"{field}.frequency_hz",
                value=config["frequency_hz"],
            )
        derivative = config.get("derivative", False)
        if not isinstance(derivative, bool):
            raise ConfigError("must be true or false", source=source, field=f"{field}.derivative", value=derivative)
        return SineSource(number("amplitude"), frequency_hz, number("offset", 0.0), rate_hz, derivative)
    text = config["expression"]
    if not isinstance(text, str):
        raise ConfigError("must be a string", source=source, field=f"{field}.expression", value=text)
    return ExpressionSource(text, rate_hz, field=f"{field}.expression", source=source)

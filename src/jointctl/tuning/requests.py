"""What the tuning page may ask, read from the JSON text of one websocket message.

Client text is only ever parsed as JSON and checked field by field; it is never evaluated
(an expression source is parsed by :mod:`jointctl.commands.expression`, which accepts
arithmetic on ``i`` and ``t`` and a list of math functions, nothing else). Every refusal is a
:class:`RequestError` naming the field and the value. The requests::

    {"type": "gain", "controller": C, "name": "p", "value": 1600}
    {"type": "source", "controller": C, "source": {"type": "constant", "value": -0.3}}
        source types: hold, constant {value}, step {from, to, at} (at: seconds after it is applied),
        sine {amplitude, frequency_hz, offset, rate_hz}, expression {expression, rate_hz}
    {"type": "joint", "joint": J}          the joint the page plots and measures
    {"type": "gravity", "value": -9.81}    gravity along the world z axis [m/s²]
    {"type": "pause"} {"type": "resume"} {"type": "reset"} {"type": "drop_weight"} {"type": "save_gains"}
    {"type": "identify", "controller": C[, "live": true]}          fit the plant of C's joint
    {"type": "bode", "controller": C[, "live": true]}              C's closed-loop frequency response
    {"type": "autotune", "controller": C, "zeta": 0.7, "bandwidth_hz": 5, "step": 0.1}   gains for a spec
        (analyses: run on a simulated copy of the robot with the live gains and pose, changing nothing
        live; with "live": true, identify and bode excite the running robot itself, in its loop time)
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, ClassVar

from jointctl.errors import JointCtlError
from jointctl.commands.sources import CommandSource, command_source_from_config
from jointctl.validate import finite_number

MAX_REQUEST_CHARS = 16 * 1024 * 1024
"""Longer messages are refused before parsing. Below it a long field is parsed and refused by its own
check, which names it (an expression has a length limit of its own)."""

CONTROLS = ("pause", "resume", "reset", "drop_weight", "save_gains")


class RequestError(JointCtlError):
    """A request from the page was refused; nothing changed."""

    code = "request"


@dataclass(frozen=True)
class SetGain:
    kind: ClassVar[str] = "gain"  # the request's "type"
    controller: str
    name: str
    value: Any  # checked against the gain's bounds by the gain group


@dataclass(frozen=True)
class SetSource:
    kind: ClassVar[str] = "source"  # the request's "type"
    controller: str
    source: CommandSource | None  # None: stop commanding, the controller holds its last command
    description: dict[str, Any]


@dataclass(frozen=True)
class SelectJoint:
    kind: ClassVar[str] = "joint"  # the request's "type"
    joint: str


@dataclass(frozen=True)
class SetGravity:
    kind: ClassVar[str] = "gravity"  # the request's "type"
    z_m_s2: float


@dataclass(frozen=True)
class Control:
    action: str

    @property
    def kind(self) -> str:
        return self.action


@dataclass(frozen=True)
class Analyse:
    """An analysis of ``controller``'s joint or loop: ``kind`` identify, bode or autotune; ``spec``
    the autotune's ``zeta``, ``bandwidth_hz`` and ``step``; ``live``: on the running robot itself
    (identify and bode) rather than on a simulated copy."""

    kind: str
    controller: str
    spec: dict[str, float]
    live: bool = False


ANALYSES = ("identify", "bode", "autotune")

Request = SetGain | SetSource | SelectJoint | SetGravity | Control | Analyse

_FIELDS = {
    "gain": ({"controller", "name", "value"}, set()),
    "source": ({"controller", "source"}, set()),
    "joint": ({"joint"}, set()),
    "gravity": ({"value"}, set()),
    **{action: (set(), set()) for action in CONTROLS},
    "identify": ({"controller"}, {"live"}),
    "bode": ({"controller"}, {"live"}),
    "autotune": ({"controller", "bandwidth_hz"}, {"zeta", "step"}),
}


def _refuse_constant(name: str) -> Any:
    raise RequestError("not a JSON number", field="message", value=name)


def _string(message: dict, key: str) -> str:
    value = message[key]
    if not isinstance(value, str):
        raise RequestError("must be a string", field=key, value=value)
    return value


def parse_request(text: Any) -> Request:
    """The request in one websocket text message, or a :class:`RequestError`."""
    if not isinstance(text, str):
        raise RequestError("must be a JSON text message", field="message", value=type(text).__name__)
    if len(text) > MAX_REQUEST_CHARS:
        raise RequestError(f"too long ({len(text)} characters, limit {MAX_REQUEST_CHARS})", field="message")
    try:
        message = json.loads(text, parse_constant=_refuse_constant)
    except json.JSONDecodeError as exc:
        raise RequestError(f"not JSON: {exc.msg} at character {exc.pos}", field="message") from None
    if not isinstance(message, dict):
        raise RequestError("must be a JSON object", field="message", value=message)
    kind = message.get("type")
    if not isinstance(kind, str) or kind not in _FIELDS:
        raise RequestError(f"unknown request (known: {', '.join(_FIELDS)})", field="type", value=kind)
    required, optional = _FIELDS[kind]
    for key in message:
        if key != "type" and key not in required | optional:
            raise RequestError(f"unknown key for a {kind} request", field=key, value=message[key])
    for key in sorted(required):
        if key not in message:
            raise RequestError(f"missing for a {kind} request", field=key)
    if kind == "gain":
        return SetGain(_string(message, "controller"), _string(message, "name"), message["value"])
    if kind == "source":
        return _source_request(_string(message, "controller"), message["source"])
    if kind == "joint":
        return SelectJoint(_string(message, "joint"))
    if kind == "gravity":
        value = message["value"]
        if finite_number(value) is None:
            raise RequestError("must be a finite number [m/s²]", field="gravity", value=value)
        return SetGravity(float(value))
    if kind in ANALYSES:
        spec = {}
        for key, default in (("bandwidth_hz", None), ("zeta", 0.7), ("step", 0.1)):
            if key in required | optional:
                value = message.get(key, default)
                if finite_number(value) is None or not value > 0:
                    raise RequestError("must be a positive number", field=key, value=value)
                spec[key] = float(value)
        live = message.get("live", False)
        if not isinstance(live, bool):
            raise RequestError("must be true (on the live robot) or false (on a simulated copy)", field="live",
                               value=live)
        return Analyse(kind, _string(message, "controller"), spec, live)
    return Control(kind)


def _source_request(controller: str, config: Any) -> SetSource:
    if isinstance(config, dict) and config.get("type") == "hold":
        if len(config) != 1:
            raise RequestError("a hold source takes no parameters", field="source", value=config)
        return SetSource(controller, None, {"type": "hold"})
    # The scenario files' reader: the same checks, and errors naming source.<key>.
    source = command_source_from_config(config, field="source", source=None)
    source.sample(0.0)  # an expression that fails at its first message is refused now
    source.reset()
    return SetSource(controller, source, dict(config))

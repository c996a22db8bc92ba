"""One exception hierarchy for jointctl.

Every error a user can cause is a :class:`JointCtlError`. Each carries the
place it comes from (``source``: a file path or a command name), the
``field`` inside it (a dotted path such as
``one_DOF_robot.joint1_position_controller.pid.p``) and the offending
``value``, so the command-line interface can print one clear line and exit
with status 2 instead of a traceback.
"""

from __future__ import annotations

from typing import Any

_UNSET = object()


class JointCtlError(Exception):
    """Base class of every error jointctl raises on bad input or bad state.

    ``code`` is a short machine-readable identifier (``"config"``,
    ``"model"``, ``"expression"``...); subclasses set a default.
    """

    code: str = "error"

    def __init__(
        self,
        message: str,
        *,
        source: str | None = None,
        field: str | None = None,
        value: Any = _UNSET,
        code: str | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.source = source
        self.field = field
        self.value = value
        if code is not None:
            self.code = code

    @property
    def has_value(self) -> bool:
        return self.value is not _UNSET

    def __str__(self) -> str:
        parts = []
        if self.source:
            parts.append(str(self.source))
        if self.field:
            parts.append(self.field)
        where = ": ".join(parts)
        text = self.message
        if self.has_value:
            text = f"{text} (got {_short_repr(self.value)})"
        return f"{where}: {text}" if where else text


class ConfigError(JointCtlError):
    """A configuration file (controller YAML, scenario YAML) is missing or malformed."""

    code = "config"


class ModelError(JointCtlError):
    """A robot description (URDF / xacro) is missing, malformed or unsupported."""

    code = "model"


class ExpressionError(JointCtlError):
    """A command expression is malformed, unsafe or cannot be evaluated."""

    code = "expression"


class InvalidCommand(JointCtlError):
    """A command handed to a running controller was refused (not finite, unknown joint...)."""

    code = "command"


class ControllerError(JointCtlError):
    """Controllers cannot be loaded or started as asked (unknown type, conflicting claims...)."""

    code = "controller"


class ControllerFailed(JointCtlError):
    """A running controller raised or produced a non-finite output: it was deactivated with its
    chain and its joints were put in their safe action (see ``docs/architecture.md``)."""

    code = "controller_failed"


class PhysicsError(JointCtlError):
    """The physics engine warned that the simulation is no longer valid (``field`` names the
    warning, e.g. ``mjWARN_BADQVEL``)."""

    code = "physics"


class MalformedPacket(JointCtlError):
    """A ROS-Industrial ``simple_message`` packet is malformed (length prefix, header or body) or a
    message cannot be encoded; ``field`` names the part (``"length"``, ``"msg_type"``,
    ``"positions"``...)."""

    code = "packet"


def _short_repr(value: Any, limit: int = 80) -> str:
    """``repr(value)`` within ``limit`` characters; a long one keeps its start and its end (a path's
    file name, a list's last items), joined by "..."."""
    text = repr(value)
    if len(text) > limit:
        head = (limit - 3) // 2
        text = text[:head] + "..." + text[len(text) - (limit - 3 - head):]
    return text

"""A design's gains as the fields of the controller file that runs it, ros_control's or ROS 2's.

autotune (and ``--robust``) design one loop, :class:`~jointctl.identification.step_loop.JointLoop` naming its gains
as ros_control does (``p``, ``i``, ``d``, ``i_clamp``, ``antiwindup``), and write them where the controller reads
them:

- ros_controllers' ``effort_controllers/JointPositionController`` (law "ros_control"), a ros_control file
  (``NAMESPACE: {CONTROLLER: {pid: {...}}}``): ``pid.p|i|d``, with an integral ``pid.i_clamp`` and
  ``pid.antiwindup``; a remedy's ``derivative: measurement`` and ``feedforward: {gravity: true}``;
- ros2_controllers' ``pid_controller/PidController`` (law "control_toolbox"), a ROS 2 parameters file
  (``CONTROLLER: {ros__parameters: {gains: {DOF: {...}}}}``): ``gains.<joint>.p|i|d``, with an integral
  ``i_clamp_max`` (the clamp), ``i_clamp_min`` (minus it) and ``antiwindup``; every number a double (ROS 2
  refuses an integer for a parameter it declares a double). It has neither a derivative law nor a model
  feed-forward of its own to write.

Numbers are rounded to 6 decimals. :func:`fields_of` gives the fields, relative to the controller's entry (its
``ros__parameters`` for a ROS 2 file); :func:`setting_overrides` the scenario overrides that run them;
:func:`tuned_document` a copy of the file's tree with them in.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

from jointctl.control.manager import set_dotted
from jointctl.control.ros2_parameters import ROS_PARAMETERS, is_ros2_parameters, node_name
from jointctl.errors import ConfigError

#: The JointLoop laws (:data:`jointctl.metrics.step_loop.LAWS`): ros_controllers' and pid_controller's.
ROS_CONTROL, CONTROL_TOOLBOX = "ros_control", "control_toolbox"


def _number(value: float, law: str) -> float:
    return float(round(float(value), 6)) if law == CONTROL_TOOLBOX else round(value, 6)


def fields_of(gains: Mapping[str, Any], *, law: str = ROS_CONTROL, joint: str | None = None,
              derivative: str | None = None, feedforward: bool = False) -> dict[str, Any]:
    """``{dotted field: value}`` of a design (``gains`` as JointLoop names them; ``derivative`` and
    ``feedforward`` what a remedy changed) for the controller of ``law`` commanding ``joint`` (see the module
    docstring)."""
    if law == CONTROL_TOOLBOX:
        if derivative == "measurement" or feedforward:
            raise ConfigError("pid_controller has no derivative law or model feed-forward to write",
                              field="--remedy", value="measurement" if derivative == "measurement" else "feedforward")
        prefix = f"gains.{joint}."
        out = {f"{prefix}{k}": _number(gains[k], law) for k in ("p", "i", "d") if k in gains}
        if gains.get("i"):
            clamp = float(gains["i_clamp"])
            out[f"{prefix}i_clamp_max"] = _number(clamp, law)
            out[f"{prefix}i_clamp_min"] = _number(gains.get("i_clamp_min", -clamp), law)
            out[f"{prefix}antiwindup"] = bool(gains.get("antiwindup", False))
        return out
    out = {f"pid.{k}": (v if isinstance(v, bool) else _number(v, law)) for k, v in gains.items()}
    if derivative == "measurement":
        out["derivative"] = "measurement"
    if feedforward:
        out["feedforward.gravity"] = True
    return out


def setting_overrides(controller_name: str, fields: Mapping[str, Any]) -> list[str]:
    """The scenario overrides (``controllers.NAME.FIELD=VALUE``) that run ``fields``."""
    return [f"controllers.{controller_name}.{key}={value!r}" for key, value in fields.items()]


def controller_entry(document: dict, controller_name: str, source: str) -> dict:
    """The mapping of ``document`` (a controller file's tree, changed in place) holding ``controller_name``'s
    parameters: its ``ros__parameters`` in a ROS 2 file (the section made when the file has none), its entry in
    a ros_control one (under its namespace); ConfigError when the file does not declare it."""
    if is_ros2_parameters(document):
        manager = next((v for k, v in document.items() if node_name(k) == "controller_manager"), None)
        declared = (manager or {}).get(ROS_PARAMETERS) or {}
        if not isinstance(declared.get(controller_name), dict):
            raise ConfigError("the controller is not in its file", source=source, field=controller_name)
        key = next((k for k in document if node_name(k) == controller_name), controller_name)
        section = document.setdefault(key, {})
        if section.get(ROS_PARAMETERS) is None:
            section[ROS_PARAMETERS] = {}
        return section[ROS_PARAMETERS]
    for body in (document, *document.values()):
        if isinstance(body, dict) and isinstance(body.get(controller_name), dict):
            return body[controller_name]
    raise ConfigError("the controller is not in its file", source=source, field=controller_name)


def tuned_document(document: dict, controller_name: str, fields: Mapping[str, Any], source: str, *,
                   overrides: Mapping[str, Any] | None = None) -> dict:
    """A copy of ``document`` with ``overrides`` (a scenario's ``controller_overrides``: ``NAME.FIELD`` ->
    value; those of ``controller_name`` applied) and then ``fields`` set in ``controller_name``'s entry."""
    tuned = copy.deepcopy(document)
    entry = controller_entry(tuned, controller_name, source)
    for key, value in (overrides or {}).items():
        if key.startswith(f"{controller_name}."):
            set_dotted(entry, key[len(controller_name) + 1:], value, source="--set")
    for key, value in fields.items():
        set_dotted(entry, key, value, source=source)
    return tuned


__all__ = ["CONTROL_TOOLBOX", "ROS_CONTROL", "controller_entry", "fields_of", "setting_overrides", "tuned_document"]

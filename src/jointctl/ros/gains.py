"""PID gains changed while running, through dynamic_reconfigure (what rqt_reconfigure talks to).

For every running joint controller with a PID (``JointPositionController``,
``JointVelocityController``) a dynamic_reconfigure server is started at
``/<namespace>/<controller>/pid``, where ros_control's controllers put theirs, with the parameters
``p``, ``i``, ``d`` (double, minimum 0), ``i_clamp_min``, ``i_clamp_max`` (double) and
``antiwindup`` (bool), initialised from the gains the controller was configured with (the YAML).

A change is validated by :class:`~jointctl.control.pid.PidGains` (finite, non-negative ``p``,
``i``, ``d``; ``i_clamp_min`` not above ``i_clamp_max``) and handed to the controller's
``set_gains``: one atomic store, used from the next control cycle. A refused change is logged and
answered with the previous configuration, so the gains stay and the caller sees that they did.

The config type. dynamic_reconfigure's ``Server`` wants the module catkin generates from a ``.cfg``
file (``<Name>Config.py``). Only its data is used (``config_description``, ``defaults``, ``min``,
``max``, ``level``, ``type``, ``all_level``; see ``encoding.encode_description`` and
``Server._clamp``), so :func:`pid_config_type` builds the same object at run time, in the same
shape ``parameter_generator_catkin`` writes: no build step, no generated files.

One deliberate difference from a generated server: the ``Server`` clamps values to ``min``/``max``
before the callback runs (so ``p: -5`` would silently become ``p: 0``). Here the range is still
advertised (rqt's sliders start at 0) but not clamped: out-of-range values reach the callback and
are refused whole, as the issue asks.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import rospy
from dynamic_reconfigure.encoding import extract_params
from dynamic_reconfigure.server import Server

from jointctl.control.pid import PidGains
from jointctl.errors import JointCtlError

GAIN_NAMES = ("p", "i", "d", "i_clamp_min", "i_clamp_max", "antiwindup")
_LEVEL = 1  # every parameter at one level: any change is a gain change

_DESCRIPTIONS = {
    "p": "Proportional gain",
    "i": "Integral gain",
    "d": "Derivative gain",
    "i_clamp_min": "Lower bound of the integral term",
    "i_clamp_max": "Upper bound of the integral term",
    "antiwindup": "Clamp the integral state itself, not only its contribution",
}


def _param(name: str, kind: str, default, minimum, maximum) -> dict:
    ctype = {"double": "double", "bool": "bool"}[kind]
    return {"name": name, "type": kind, "default": default, "level": _LEVEL,
            "description": _DESCRIPTIONS[name], "min": minimum, "max": maximum,
            "srcline": 0, "srcfile": __file__, "edit_method": "",
            "ctype": ctype, "cconsttype": f"const {ctype}"}


def pid_config_type(gains: PidGains) -> SimpleNamespace:
    """The equivalent of a catkin-generated ``PidConfig`` module, with ``gains`` as defaults."""
    inf = math.inf
    parameters = [
        _param("p", "double", float(gains.p), 0.0, inf),
        _param("i", "double", float(gains.i), 0.0, inf),
        _param("d", "double", float(gains.d), 0.0, inf),
        _param("i_clamp_min", "double", float(gains.i_clamp_min), -inf, inf),
        _param("i_clamp_max", "double", float(gains.i_clamp_max), -inf, inf),
        _param("antiwindup", "bool", bool(gains.antiwindup), False, True),
    ]
    description = {"name": "Default", "type": "", "state": True, "cstate": "true", "id": 0, "parent": 0,
                   "parameters": parameters, "groups": [], "srcline": 0, "srcfile": __file__,
                   "class": "DEFAULT", "parentclass": "", "parentname": "Default", "field": "default",
                   "upper": "DEFAULT", "lower": "groups"}
    t = SimpleNamespace(config_description=description, min={}, max={}, defaults={}, level={}, type={},
                        all_level=0)
    for p in extract_params(description):
        t.min[p["name"]] = p["min"]
        t.max[p["name"]] = p["max"]
        t.defaults[p["name"]] = p["default"]
        t.level[p["name"]] = p["level"]
        t.type[p["name"]] = p["type"]
        t.all_level |= p["level"]
    return t


class GainServer(Server):
    """A dynamic_reconfigure server that leaves range checks to the callback (see the module doc)."""

    def _clamp(self, config) -> None:
        pass


def _gains_from(config) -> PidGains:
    """PidGains from a reconfigure config; raises JointCtlError (ConfigError) when invalid."""
    values = {}
    for name in GAIN_NAMES[:-1]:
        value = config[name]
        # Numbers only (a bool is not a gain); ints from a YAML ``p: 400`` are widened to float.
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise JointCtlError("must be a number", field=f"pid.{name}", value=value)
        values[name] = float(value)
    antiwindup = config["antiwindup"]
    if not isinstance(antiwindup, bool):
        raise JointCtlError("must be true or false", field="pid.antiwindup", value=antiwindup)
    return PidGains(antiwindup=antiwindup, **values)


def _as_config(config, gains: PidGains):
    """``config`` with the gain entries replaced by ``gains`` (floats, so they encode as doubles)."""
    out = config.copy()
    for name in GAIN_NAMES:
        value = getattr(gains, name)
        out[name] = bool(value) if name == "antiwindup" else float(value)
    return out


def _callback(controller, server_name: str):
    def reconfigure(config, level):
        current = controller.pid.gains
        try:
            gains = _gains_from(config)
        except JointCtlError as exc:
            changed = {n: config[n] for n in GAIN_NAMES if config[n] != getattr(current, n)}
            rospy.logwarn("jointctl: refused gains %s for %s: %s; keeping %s", changed, server_name, exc, current)
            return _as_config(config, current)
        if gains != current:
            controller.set_gains(gains)
            rospy.loginfo("jointctl: %s gains now p=%g i=%g d=%g i_clamp=[%g, %g] antiwindup=%s", server_name,
                          gains.p, gains.i, gains.d, gains.i_clamp_min, gains.i_clamp_max, gains.antiwindup)
        return _as_config(config, gains)
    return reconfigure


def _has_pid(controller) -> bool:
    pid = getattr(controller, "pid", None)
    return isinstance(getattr(pid, "gains", None), PidGains) and callable(getattr(controller, "set_gains", None))


def attach_gain_servers(node) -> list:
    """Start a reconfigure server at ``/<namespace>/<controller>/pid`` for every running controller
    with a PID; returns the servers (keep them for the node's life)."""
    servers = []
    for controller in node.session.manager.active:
        if not _has_pid(controller):
            continue
        name = f"/{node.namespace}/{controller.name}/pid"
        gains = controller.pid.gains
        # The server starts from the parameter server (the YAML rosparam-loaded under .../pid), then
        # from the type's defaults; both are the configured gains, so the first callback (level ~0)
        # only confirms them (and writes the full set, i_clamp_min/max included, back to .../pid).
        servers.append(GainServer(pid_config_type(gains), _callback(controller, name), namespace=name))
    return servers


__all__ = ["GainServer", "attach_gain_servers", "pid_config_type"]

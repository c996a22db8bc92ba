"""The gains a tuning page can change: every PID of every running joint controller, and the
parameters of admittance controllers, each as a named number with bounds.

A :class:`GainGroup` describes one controller's tunable numbers (``describe``), checks a new
value for one of them without touching the controller (``prepare`` returns the change as a
function to run at the start of a cycle, or raises a :class:`~jointctl.errors.ConfigError`
naming the field and value), and gives its entry for a controller YAML file in the chapter's
format (:func:`gains_yaml`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from jointctl.control.admittance_controller import AdmittanceController
from jointctl.control.cartesian_admittance_controller import CartesianAdmittanceController
from jointctl.control.manager import ControllerManager, read_yaml
from jointctl.control.pid import PidGains
from jointctl.errors import ConfigError
from jointctl.model.robot_model import RobotModel
from jointctl.validate import real_number

Change = Callable[[], None]


@dataclasses.dataclass(frozen=True)
class GainSpec:
    """One tunable number: its key, unit, lower bound (inclusive unless ``positive``)."""

    name: str
    unit: str
    positive: bool = False  # strictly above zero (a virtual mass)
    minimum: float | None = 0.0  # None: any finite value


def _check(controller: str, spec: GainSpec, value: Any) -> float:
    field = f"{controller}.{spec.name}"
    number = real_number(value)
    if number is None:
        raise ConfigError("must be a number", field=field, value=value)
    if not math.isfinite(number):
        raise ConfigError("must be a finite number", field=field, value=value)
    if spec.positive and number <= 0:
        raise ConfigError("must be above zero", field=field, value=value)
    if spec.minimum is not None and number < spec.minimum:
        raise ConfigError(f"must not be below {spec.minimum:g}", field=field, value=value)
    return number


class GainGroup:
    """The tunable numbers of one controller."""

    kind = ""
    specs: tuple[GainSpec, ...] = ()

    def __init__(self, controller) -> None:
        self.controller = controller
        self.name: str = controller.name

    def values(self) -> dict[str, float]:
        raise NotImplementedError

    def _change(self, name: str, value: float) -> Change:
        raise NotImplementedError

    def prepare(self, name: Any, value: Any) -> Change:
        """Check ``value`` for gain ``name``; the returned function applies it (at a cycle start)."""
        spec = next((s for s in self.specs if s.name == name), None)
        if spec is None:
            known = ", ".join(s.name for s in self.specs)
            raise ConfigError(f"no such gain (this controller has: {known})", field=f"{self.name}.name",
                              value=name)
        return self._change(spec.name, _check(self.name, spec, value))

    def describe(self) -> dict[str, Any]:
        values = self.values()
        return {"controller": self.name, "kind": self.kind,
                "joints": list(getattr(self.controller, "joints", ()) or [getattr(self.controller, "joint", "")]),
                "gains": [{"name": s.name, "unit": s.unit, "value": values[s.name],
                           "minimum": s.minimum, "positive": s.positive} for s in self.specs]}

    def yaml_update(self, entry: dict) -> None:
        """Write the current values into this controller's entry of the controller YAML tree."""
        entry.update(self.values())


def _pid_units(controlled: str, prismatic: bool) -> tuple[str, str, str, str]:
    """Units of p, i, d and i_clamp: effort per error, per error·s, per error/s; effort."""
    effort, error = ("N", "m") if prismatic else ("N·m", "rad")
    if controlled == "velocity":
        return (f"{effort}·s/{error}", f"{effort}/{error}", f"{effort}·s²/{error}", effort)
    return (f"{effort}/{error}", f"{effort}/({error}·s)", f"{effort}·s/{error}", effort)


class PidGroup(GainGroup):
    """``pid: {p, i, d, i_clamp}`` of a joint position or velocity controller (i_clamp symmetric)."""

    kind = "pid"

    def __init__(self, controller, *, prismatic: bool) -> None:
        super().__init__(controller)
        p, i, d, effort = _pid_units(controller.controlled, prismatic)
        self.specs = (GainSpec("p", p), GainSpec("i", i), GainSpec("d", d), GainSpec("i_clamp", effort))

    def values(self) -> dict[str, float]:
        g = self.controller.pid.gains
        return {"p": g.p, "i": g.i, "d": g.d, "i_clamp": max(abs(g.i_clamp_min), abs(g.i_clamp_max))}

    def _change(self, name: str, value: float) -> Change:
        controller = self.controller
        if name == "i_clamp":
            fields = {"i_clamp_min": -value, "i_clamp_max": value}
        else:
            fields = {name: value}
        dataclasses.replace(controller.pid.gains, **fields)  # refuses now what would fail later

        def apply() -> None:
            controller.set_gains(dataclasses.replace(controller.pid.gains, **fields))

        return apply

    def yaml_update(self, entry: dict) -> None:
        pid = entry.get("pid")
        pid = dict(pid) if isinstance(pid, dict) else {}
        g: PidGains = self.controller.pid.gains
        pid.update(p=g.p, i=g.i, d=g.d)
        had_clamp = any(k in pid for k in ("i_clamp", "i_clamp_min", "i_clamp_max"))
        default = self.controller.effort_limit
        if had_clamp or g.i_clamp_max != default or g.i_clamp_min != -default:
            for key in ("i_clamp_min", "i_clamp_max"):
                pid.pop(key, None)
            if g.i_clamp_min == -g.i_clamp_max:
                pid["i_clamp"] = g.i_clamp_max
            else:
                pid.update(i_clamp_min=g.i_clamp_min, i_clamp_max=g.i_clamp_max)
        entry["pid"] = _FlowMap(pid)


class AdmittanceGroup(GainGroup):
    """``mass``, ``stiffness`` and ``damping`` of the 1-DOF natural admittance controller."""

    kind = "admittance"
    specs = (GainSpec("mass", "kg", positive=True), GainSpec("stiffness", "N/m"),
             GainSpec("damping", "N·s/m"))

    def values(self) -> dict[str, float]:
        c = self.controller
        return {"mass": c.mass, "stiffness": c.stiffness, "damping": c.damping}

    def _change(self, name: str, value: float) -> Change:
        controller = self.controller
        return lambda: controller.set_gains(**{name: value})


_AXES = ("x", "y", "z")


class CartesianAdmittanceGroup(GainGroup):
    """Per-axis ``stiffness`` and ``damping`` of the Cartesian admittance controller."""

    kind = "admittance"
    specs = tuple(GainSpec(f"{what}_{axis}", unit) for what, unit in (("stiffness", "N/m"), ("damping", "N·s/m"))
                  for axis in _AXES)

    def values(self) -> dict[str, float]:
        c = self.controller
        return {f"{what}_{axis}": float(getattr(c, what)[k]) for what in ("stiffness", "damping")
                for k, axis in enumerate(_AXES)}

    def _change(self, name: str, value: float) -> Change:
        controller = self.controller
        what, axis = name.rsplit("_", 1)
        k = _AXES.index(axis)

        def apply() -> None:
            vector = [float(v) for v in getattr(controller, what)]
            vector[k] = value
            controller.set_gains(**{what: vector})

        return apply

    def yaml_update(self, entry: dict) -> None:
        c = self.controller
        entry["stiffness"] = [float(v) for v in c.stiffness]
        entry["damping"] = [float(v) for v in c.damping]


def gain_groups(manager: ControllerManager, robot: RobotModel) -> list[GainGroup]:
    """A group for every running controller that has tunable gains, in start order."""
    groups: list[GainGroup] = []
    for c in manager.active:
        if isinstance(c, AdmittanceController):
            groups.append(AdmittanceGroup(c))
        elif isinstance(c, CartesianAdmittanceController):
            groups.append(CartesianAdmittanceGroup(c))
        elif getattr(c, "pid", None) is not None and hasattr(c, "set_gains"):
            groups.append(PidGroup(c, prismatic=robot.joint(c.joint).is_prismatic))
    return groups


def gains_yaml(controller_file: str | Path, groups: list[GainGroup], header: str = "") -> str:
    """The controller YAML file with the groups' current values written in: the chapter's format
    (namespace, then one entry per controller, ``pid: {p: ..., i: ..., d: ...}``)."""
    tree = read_yaml(controller_file)
    entries = tree
    if isinstance(tree, dict) and len(tree) == 1:
        (only,) = tree.values()
        if isinstance(only, dict) and all(isinstance(v, dict) for v in only.values()) and "type" not in only:
            entries = only
    for group in groups:
        entry = entries.get(group.name)
        if not isinstance(entry, dict):
            continue
        group.yaml_update(entry)
    body = yaml.dump(tree, Dumper=_ChapterDumper, sort_keys=False, default_flow_style=False, allow_unicode=True,
                     width=100)
    return header + body


class _FlowMap(dict):
    """A mapping written on one line, as the chapter writes ``pid: {p: 400.0, i: 0.0, d: 0.0}``."""


class _ChapterDumper(yaml.SafeDumper):
    pass


_ChapterDumper.add_representer(  # lists of numbers or names on one line: joints: [joint0, joint1]
    list, lambda dumper, data: dumper.represent_sequence(
        "tag:yaml.org,2002:seq", data, flow_style=all(not isinstance(v, (dict, list)) for v in data)))
_ChapterDumper.add_representer(
    _FlowMap, lambda dumper, data: dumper.represent_mapping("tag:yaml.org,2002:map", data, flow_style=True))

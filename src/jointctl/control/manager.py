"""Load controllers from ros_control YAML and run the active ones in order.

A controller file is the chapter's format: a robot namespace whose entries
are controllers, each with a ros_control ``type``::

    one_DOF_robot:
      joint1_position_controller:
        type: effort_controllers/JointPositionController
        joint: joint1
        pid: {p: 400.0, i: 0.0, d: 0.0}

A file without the namespace level (controllers at the top) loads too.
Loading builds and configures a controller; starting it checks that no
running controller claims the same ``(joint, interface)``.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from jointctl.control.context import ControlContext
from jointctl.control.controller import Controller, controller_types
from jointctl.control.params import Params
from jointctl.errors import ConfigError, ControllerError
from jointctl.hardware.interface import HardwareInterface
from jointctl.model.robot_model import RobotModel


def read_yaml(path: str | Path) -> Any:
    """Parse a YAML file; ConfigError naming the file and line when it cannot."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError("file not found", source=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read: {exc}", source=str(path)) from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"not valid YAML: {where}{problem}", source=str(path)) from None


def set_dotted(tree: dict, dotted: str, value: Any, *, source: str | None, field_prefix: str = "") -> None:
    """Set ``tree[a][b][c] = value`` for ``dotted = "a.b.c"``, creating mappings on the way."""
    keys = dotted.split(".")
    node = tree
    for depth, key in enumerate(keys[:-1]):
        nxt = node.get(key)
        if nxt is None:
            nxt = node[key] = {}
        if not isinstance(nxt, dict):
            where = ".".join(filter(None, [field_prefix, *keys[: depth + 1]]))
            raise ConfigError("cannot set a field inside a value that is not a mapping",
                              source=source, field=where, value=nxt)
        node = nxt
    node[keys[-1]] = value


class ControllerManager:
    """Loads, starts, stops and updates controllers against one hardware interface."""

    def __init__(self, hardware: HardwareInterface, robot: RobotModel,
                 gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)) -> None:
        self.hardware = hardware
        self.robot = robot
        self.context = ControlContext(hardware, robot, gravity_m_s2)
        self._definitions: dict[str, Params] = {}
        self._loaded: dict[str, Controller] = {}
        self._active: list[Controller] = []
        #: The running controllers' update methods, in start order (read by the loop every cycle).
        self.update_calls: tuple = ()
        self.namespace: str | None = None
        #: Per hardware joint, the reference of the controller commanding it (NaN when none).
        self.references: list[float] = self.context.references

    # -- definitions -------------------------------------------------------------
    def load_file(self, path: str | Path, overrides: Mapping[str, Any] | None = None) -> str | None:
        """Read controller definitions from ``path``; returns the namespace found.

        ``overrides`` maps dotted fields relative to the namespace
        (``joint1_position_controller.pid.p``) to values applied before anything
        is built, with the same validation as the file.
        """
        source = str(path)
        tree = read_yaml(path)
        if not isinstance(tree, dict) or not tree:
            raise ConfigError("must be a mapping of controllers (under a robot namespace)",
                              source=source, value=tree)
        namespace, controllers = self._split_namespace(tree, source)
        controllers = copy.deepcopy(controllers)
        prefix = namespace or ""
        for dotted, value in (overrides or {}).items():
            name = dotted.split(".", 1)[0]
            if name not in controllers:
                raise ConfigError(f"no controller of that name in the file (controllers: "
                                  f"{', '.join(controllers)})", source=source,
                                  field=".".join(filter(None, [prefix, dotted])), value=name)
            set_dotted(controllers, dotted, value, source=source, field_prefix=prefix)
        for name, definition in controllers.items():
            field = f"{prefix}.{name}" if prefix else name
            self._definitions[name] = Params(definition, source=source, field=field)
        self.namespace = namespace
        return namespace

    def _split_namespace(self, tree: dict, source: str) -> tuple[str | None, dict]:
        def is_controller(value: Any) -> bool:
            return isinstance(value, dict) and "type" in value

        if all(is_controller(v) for v in tree.values()):
            return None, tree
        namespaces = {k: v for k, v in tree.items() if isinstance(v, dict)}
        wanted = self.robot.namespace
        if wanted in namespaces:
            key = wanted
        elif len(namespaces) == 1:
            key = next(iter(namespaces))
        else:
            raise ConfigError(f"cannot tell which namespace holds the controllers "
                              f"(robot namespace {wanted!r})", source=source, value=sorted(tree))
        body = namespaces[key]
        if not body:
            raise ConfigError("the namespace defines no controllers", source=source, field=key,
                              value=body)
        for name, value in body.items():
            if not is_controller(value):
                raise ConfigError("a controller needs a mapping with a 'type'", source=source,
                                  field=f"{key}.{name}", value=value)
        return key, body

    @property
    def defined(self) -> tuple[str, ...]:
        return tuple(self._definitions)

    # -- lifecycle ---------------------------------------------------------------
    def load(self, name: str) -> Controller:
        """Build and configure controller ``name`` from its definition."""
        if name in self._loaded:
            return self._loaded[name]
        params = self._definitions.get(name)
        if params is None:
            raise ControllerError(f"no controller of that name is defined (defined: "
                                  f"{', '.join(self._definitions) or 'none'})", field="controller",
                                  value=name)
        params = Params(params.values, source=params.source, field=params.field)
        type_name = params.string("type")
        cls = controller_types().get(type_name)
        if cls is None:
            raise params.error(f"unknown controller type (known: {', '.join(sorted(controller_types()))})",
                               "type", type_name)
        controller = cls(name, params)
        controller.context = self.context
        controller.configure(self.hardware, self.robot)
        self._loaded[name] = controller
        return controller

    def start(self, names: Iterable[str], time_s: float = 0.0) -> None:
        """Load (if needed) and start ``names``, refusing conflicting claims; all or nothing."""
        names = list(dict.fromkeys(names))  # a name listed twice starts once
        controllers = [self.load(n) for n in names]
        claims = {c: self._active_claim(c) for c in self._active}
        owner: dict[tuple[str, str], str] = {}
        for c, claimed in claims.items():
            for claim in claimed:
                owner[claim] = c.name
        for c in controllers:
            if c in self._active:
                continue
            for claim in c.claimed_interfaces():
                joint, interface = claim
                if claim in owner:
                    raise ControllerError(
                        f"joint {joint!r} {interface} interface is already claimed by controller "
                        f"{owner[claim]!r}", field="controller", value=c.name)
                owner[claim] = c.name
        running = {c.name for c in self._active} | {c.name for c in controllers}
        for c in controllers:
            missing = [n for n in c.downstream if n not in running]
            if missing:
                raise ControllerError(f"a chained controller needs {', '.join(missing)} running with it",
                                      field="controller", value=c.name)
            c.bind_downstream({n: self.load(n) for n in c.downstream})
        new = [c for c in controllers if c not in self._active]
        _upstream_first(self._active + new)  # refuses a chain loop before anything starts
        for c in controllers:
            if c not in self._active:
                c.start(time_s)
                self._active.append(c)
        self._refresh()

    def stop(self, names: Iterable[str], time_s: float = 0.0) -> None:
        names = list(names)
        for c in self._active:
            fed = [n for n in c.downstream if n in names]
            if fed and c.name not in names:
                raise ControllerError(f"controller {c.name!r} feeds it: stop both together",
                                      field="controller", value=fed[0])
        for name in names:
            c = self._loaded.get(name)
            if c is not None and c in self._active:
                c.stop(time_s)
                self._active.remove(c)
                for joint in c.joints:
                    index = self.hardware.joint_index(joint)
                    self.references[index] = math.nan
                    self.context.acceleration_references[index] = 0.0
        self._refresh()

    @staticmethod
    def _active_claim(c: Controller) -> tuple[tuple[str, str], ...]:
        return c.claimed_interfaces()

    def _refresh(self) -> None:
        self._active = _upstream_first(self._active)
        calls = [c.update for c in self._active]
        users = [k for k, c in enumerate(self._active) if getattr(c, "uses_model", False)]
        if users:  # the model feed-forward runs once, just before its first user
            calls.insert(users[0], self.context.feedforward.update)
        self.update_calls = tuple(calls)

    @property
    def active(self) -> tuple[Controller, ...]:
        return tuple(self._active)

    def controller(self, name: str) -> Controller:
        try:
            return self._loaded[name]
        except KeyError:
            raise ControllerError("no loaded controller of that name", field="controller",
                                  value=name) from None

    def command_owner(self, controller_name: str) -> Controller | None:
        """The running controller that writes ``controller_name``'s command (chaining), if any."""
        return next((c for c in self._active if controller_name in c.downstream), None)

    def commanding(self, joint: str) -> Controller | None:
        """The running controller that commands ``joint``, if any."""
        return next((c for c in self._active if joint in c.joints), None)

    def update(self, time_s: float, period_s: float) -> None:
        """Update every running controller, in start order."""
        for call in self.update_calls:
            call(time_s, period_s)


def _upstream_first(controllers: list[Controller]) -> list[Controller]:
    """Order so every controller runs before the ones it feeds; otherwise keep start order."""
    ordered: list[Controller] = []
    by_name = {c.name: c for c in controllers}

    def place(c: Controller, trail: tuple[str, ...]) -> None:
        if c in ordered:
            return
        if c.name in trail:
            raise ControllerError("chained controllers feed each other in a loop", field="controller",
                                  value=" -> ".join(trail + (c.name,)))
        for upstream in controllers:
            if c.name in upstream.downstream:
                place(upstream, trail + (c.name,))
        ordered.append(c)

    for c in controllers:
        place(by_name[c.name], ())
    return ordered


__all__ = ["ControllerManager", "read_yaml", "set_dotted"]

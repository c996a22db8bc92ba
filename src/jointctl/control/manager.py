"""Load controllers from ros_control YAML and run the active ones in order.

A controller file is the chapter's format: a robot namespace whose entries
are controllers, each with a ros_control ``type``::

    one_DOF_robot:
      joint1_position_controller:
        type: effort_controllers/JointPositionController
        joint: joint1
        pid: {p: 400.0, i: 0.0, d: 0.0}

A file without the namespace level (controllers at the top) loads too, and so does a ROS 2
controller_manager parameters file (``controller_manager: ros__parameters: {update_rate, NAME: {type}}``
and ``NAME: ros__parameters: {...}``, told apart by its ``ros__parameters``; read by
:mod:`jointctl.control.ros2_parameters`).
Loading builds and configures a controller; starting it checks that no
running controller claims the same ``(joint, interface)``.
"""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from jointctl.control.context import ControlContext
from jointctl.control.controller import Controller
from jointctl.control.params import Params
from jointctl.control.registry import controller_types
from jointctl.control.ros2_parameters import is_ros2_parameters, read_ros2_controllers
from jointctl.errors import ConfigError, ControllerError, ControllerFailed
from jointctl.hardware.interface import HardwareInterface
from jointctl.hardware.loan import HardwareLoan
from jointctl.model.robot_model import RobotModel


class YamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader, reading numbers as YAML 1.2 (and every user) does.

    YAML 1.1, which PyYAML implements, wants a dot in a float and a sign in its exponent, so
    ``1e3``, ``1E-3``, ``5e+2`` and ``-.5`` come back as strings and a gain ``p: 1e3`` is refused
    as "must be a number". Here a plain scalar is a float when it reads as one: digits with an
    optional sign, an optional fraction (``1.5``, ``1.``, ``.5``) and an optional exponent with an
    optional sign (``1e3``, ``2.5E-3``, ``-2.5e+2``); ``_`` may group digits (``1_000.5``), as YAML
    1.1 allows; ``.inf``, ``-.inf`` and ``.nan`` stay floats (the number checks then refuse them).
    Whole numbers stay integers (``1_000`` is 1000), quoted values stay strings (``"1e3"``), and
    everything else is YAML 1.1 as before. Every YAML jointctl reads (controller files, scenarios,
    robot manifests, trajectories, ``--set`` values) goes through this loader.
    """


_FLOAT_TAG = "tag:yaml.org,2002:float"
_DIGITS = r"[0-9][0-9_]*"
_EXPONENT = r"[eE][-+]?[0-9]+"
YamlLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag != _FLOAT_TAG]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
YamlLoader.add_implicit_resolver(
    _FLOAT_TAG,
    re.compile(rf"""^(?:[-+]?{_DIGITS}\.[0-9_]*(?:{_EXPONENT})?
                    |[-+]?{_DIGITS}{_EXPONENT}
                    |[-+]?\.[0-9][0-9_]*(?:{_EXPONENT})?
                    |[-+]?{_DIGITS}(?::[0-5]?[0-9])+\.[0-9_]*
                    |[-+]?\.(?:inf|Inf|INF)
                    |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def load_yaml_text(text: str) -> Any:
    """Parse YAML ``text`` with :class:`YamlLoader` (raises ``yaml.YAMLError`` when it cannot)."""
    return yaml.load(text, Loader=YamlLoader)  # noqa: S506 - a SafeLoader subclass


def read_yaml(path: str | Path) -> Any:
    """Parse a YAML file (numbers read as in :class:`YamlLoader`); ConfigError naming the file and
    line when it cannot."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError("file not found", source=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read: {exc}", source=str(path)) from None
    parsed = _PARSED.get(text)
    if parsed is not None:  # the same text parsed before (a sweep reads its files for every run): a copy of it
        return copy.deepcopy(parsed)
    try:
        parsed = load_yaml_text(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"not valid YAML: {where}{problem}", source=str(path)) from None
    if len(_PARSED) >= PARSED_FILES:
        _PARSED.pop(next(iter(_PARSED)), None)  # the first kept
    _PARSED[text] = parsed
    return copy.deepcopy(parsed)


#: Files' texts parsed by :func:`read_yaml` kept with what they gave (keyed by the text itself: an edited file is
#: parsed again), the last ones parsed.
PARSED_FILES = 32
_PARSED: dict[str, Any] = {}


def ros2_update_rate(path: str | Path) -> tuple[int, str] | None:
    """(the controller_manager's ``update_rate`` [Hz], its field) of a ROS 2 controller file; None for a
    ros_control file."""
    tree = read_yaml(path)
    if not is_ros2_parameters(tree):
        return None
    ros2 = read_ros2_controllers(tree, str(path), base_dir=Path(path).parent, read=read_yaml)
    return ros2.update_rate_hz, ros2.update_rate_field


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


@dataclass(frozen=True)
class ControllerFailure:
    """A controller that failed at ``time_s`` and what was done: ``chain`` (the controllers
    deactivated with it, itself included) and ``joints`` (put in their safe action)."""

    controller: str
    reason: str
    time_s: float
    chain: tuple[str, ...]
    joints: tuple[str, ...]

    def error(self) -> ControllerFailed:
        return ControllerFailed(
            f"failed at t = {self.time_s:.3f} s: {self.reason}; deactivated {', '.join(self.chain)}, "
            f"joints {', '.join(self.joints) or 'none'} in their safe action (zero effort)",
            field="controller", value=self.controller)


class ControllerManager:
    """Loads, starts, stops and updates controllers against one hardware interface.

    Failure policy (ros2_control's ``return_type::ERROR``, made concrete): a controller whose
    ``update`` raises, or that leaves a non-finite value in a command list, is deactivated with
    its whole chain (:meth:`fail`); their joints get the hardware's safe action; the other
    controllers keep running; the failure is kept in :attr:`failures` and handed to every
    listener (:meth:`add_failure_listener`: the ROS node logs it, the page shows it, the CLI exits
    non-zero).
    """

    def __init__(self, hardware: HardwareInterface, robot: RobotModel,
                 gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81),
                 types: Mapping[str, type[Controller]] | None = None) -> None:
        self.hardware = hardware
        self.robot = robot
        #: The controller types this manager loads, by their YAML ``type`` name (default: the
        #: registry, jointctl.control.registry).
        self.types = controller_types() if types is None else dict(types)
        self.context = ControlContext(hardware, robot, gravity_m_s2)
        self._definitions: dict[str, Params] = {}
        #: Where a ROS 2 file declares each controller's type (its controller_manager's parameters).
        self._type_fields: dict[str, str] = {}
        self._loaded: dict[str, Controller] = {}
        self._active: list[Controller] = []
        #: The running controllers' update methods, in start order (read by the loop every cycle).
        self.update_calls: tuple = ()
        self.namespace: str | None = None
        #: A ROS 2 file's controller_manager ``update_rate`` [Hz] (None for a ros_control file).
        self.update_rate_hz: int | None = None
        #: Per hardware joint, the reference of the controller commanding it (NaN when none).
        self.references: list[float] = self.context.references
        #: Every controller failure so far, in order.
        self.failures: list[ControllerFailure] = []
        self._failure_listeners: list[Callable[[ControllerFailure], None]] = []
        self._safe_indices: tuple[int, ...] = ()

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
        if is_ros2_parameters(tree):
            ros2 = read_ros2_controllers(tree, source, base_dir=Path(path).parent, read=read_yaml)
            self._type_fields.update(ros2.type_fields)
            namespace, controllers, fields = None, copy.deepcopy(ros2.controllers), ros2.fields
            self.update_rate_hz = ros2.update_rate_hz
        else:
            namespace, controllers = self._split_namespace(tree, source)
            controllers = copy.deepcopy(controllers)
            fields = {name: f"{namespace}.{name}" if namespace else name for name in controllers}
        prefix = namespace or ""
        for dotted, value in (overrides or {}).items():
            name = dotted.split(".", 1)[0]
            if name not in controllers:
                raise ConfigError(f"no controller of that name in the file (controllers: "
                                  f"{', '.join(controllers)})", source=source,
                                  field=".".join(filter(None, [prefix, dotted])), value=name)
            set_dotted(controllers, dotted, value, source=source, field_prefix=prefix)
        for name, definition in controllers.items():
            self._definitions[name] = Params(definition, source=source, field=fields[name])
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

    def type_of(self, name: str) -> str:
        """The YAML ``type`` of defined controller ``name`` (ControllerError when none is defined)."""
        params = self._definitions.get(name)
        if params is None:
            raise ControllerError("no controller of that name is defined", field="controller", value=name)
        return str(params.values.get("type", ""))

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
        cls = self.types.get(type_name)
        if cls is None:
            raise ConfigError(f"unknown controller type (known: {', '.join(sorted(self.types))})",
                              source=params.source, field=self._type_fields.get(name, params.path("type")),
                              value=type_name)
        controller = cls(name, params)
        controller.context = self.context
        # Loaned: every state handle, and the command handles of the interfaces it claims.
        loan = HardwareLoan(self.hardware, controller.claimed_interfaces(), borrower=name, source=params.source)
        controller.configure(loan, self.robot)
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
                target, interface = claim
                if claim in owner:
                    what = "controller" if target in c.downstream else "joint"
                    raise ControllerError(
                        f"{what} {target!r} {interface} interface is already claimed by controller "
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
                    self.context.reference_accelerations[index] = 0.0
        self._refresh()

    # -- failures (the loop thread) ---------------------------------------------------
    def add_failure_listener(self, listener: Callable[[ControllerFailure], None]) -> None:
        """``listener(failure)`` is called in the loop thread for every failure: it must only queue."""
        self._failure_listeners.append(listener)

    def fail(self, controller: Controller, reason: str, time_s: float) -> ControllerFailure | None:
        """Deactivate ``controller`` with its chain and put their joints in the safe action."""
        if controller not in self._active:
            return None  # already deactivated (with another member of its chain)
        chain = self._chain_of(controller)
        for c in chain:
            try:
                c.fail(time_s, reason)
            except Exception:  # noqa: BLE001  (a failing controller's clean-up must not stop the loop)
                pass
            self._active.remove(c)
        joints = tuple(dict.fromkeys(j for c in chain for j in c.joints))
        indices = tuple(self.hardware.joint_index(j) for j in joints)
        for index in indices:
            self.references[index] = math.nan
            self.context.reference_accelerations[index] = 0.0
        self._safe_indices = tuple(dict.fromkeys(self._safe_indices + indices))
        self.apply_safe_actions()
        self._refresh()
        failure = ControllerFailure(controller.name, reason, time_s, tuple(c.name for c in chain), joints)
        self.failures.append(failure)
        for listener in self._failure_listeners:
            listener(failure)
        return failure

    def fail_update(self, call: Callable, exc: BaseException, time_s: float) -> None:
        """An update call of :attr:`update_calls` raised ``exc``: fail its controller (for the model
        feed-forward, every controller that uses it)."""
        owner = getattr(call, "__self__", None)
        reason = f"{type(exc).__name__} in update: {exc}"
        if self.context.has_feedforward and owner is self.context.feedforward:  # (never built just to ask)
            for c in [c for c in self._active if c.uses_model]:
                self.fail(c, f"model feed-forward {reason}", time_s)
        elif isinstance(owner, Controller):
            self.fail(owner, reason, time_s)
        else:  # not a controller's: nothing to deactivate, the loop cannot go on safely
            raise exc

    def check_outputs(self, time_s: float) -> None:
        """Fail the controllers that left a non-finite value in a command list; then make sure
        every failed joint is in its safe action (a downstream controller updated after its
        upstream failed, in the same cycle, may have written it)."""
        for buf in self.hardware.command_buffers:
            for index, value in enumerate(buf):
                if not math.isfinite(value):
                    joint = self.hardware.joint_names[index]
                    owner = self.commanding(joint)
                    if owner is None:  # nobody's: zero (failed joints get their safe action below)
                        buf[index] = 0.0
                        continue
                    top = self._chain_of(owner)[0]
                    self.fail(owner, f"non-finite command {value!r} for joint {joint!r} "
                                     f"(chain from {top.name!r})", time_s)
        self.apply_safe_actions()

    def apply_safe_actions(self) -> None:
        for index in self._safe_indices:
            if self.commanding(self.hardware.joint_names[index]) is None:
                self.hardware.command_safe(index)

    def raise_failures(self) -> None:
        """Raise :class:`ControllerFailed` for the first failure, if any."""
        if self.failures:
            raise self.failures[0].error()

    def _chain_of(self, controller: Controller) -> list[Controller]:
        """``controller`` and every running controller chained to it (upstream or downstream),
        upstream first."""
        members = {controller}
        grew = True
        while grew:
            grew = False
            for c in self._active:
                if c in members:
                    continue
                if any(c.name in m.downstream or m.name in c.downstream for m in members):
                    members.add(c)
                    grew = True
        return [c for c in self._active if c in members]

    @staticmethod
    def _active_claim(c: Controller) -> tuple[tuple[str, str], ...]:
        return c.claimed_interfaces()

    def _refresh(self) -> None:
        self._active = _upstream_first(self._active)
        calls = [c.update for c in self._active]
        users = [k for k, c in enumerate(self._active) if c.uses_model]
        if users:  # the model feed-forward runs once, just before its first user
            calls.insert(users[0], self.context.feedforward.update)
        if self.context.has_feedforward:
            # M(q) is worth its cost only while a running controller reads the inertia term.
            self.context.feedforward.wants_inertia = any(c.uses_model_inertia for c in self._active)
        self.update_calls = tuple(calls)
        # Chained mode (ros2_control's): a controller whose reference interfaces a running
        # upstream controller writes takes its reference from that controller alone.
        for c in self._loaded.values():
            c.upstream = None
        for c in self._active:
            for name in c.downstream:
                self._loaded[name].upstream = c.name

    @property
    def active(self) -> tuple[Controller, ...]:
        return tuple(self._active)

    def loaded(self) -> tuple[Controller, ...]:
        """Every controller loaded so far, running or not, in the order loaded."""
        return tuple(self._loaded.values())

    def controller(self, name: str) -> Controller:
        try:
            return self._loaded[name]
        except KeyError:
            raise ControllerError("no loaded controller of that name", field="controller",
                                  value=name) from None

    def command_owner(self, controller_name: str) -> Controller | None:
        """The running controller that writes ``controller_name``'s reference (chaining), if any."""
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


__all__ = ["ControllerFailure", "ControllerManager", "YamlLoader", "load_yaml_text", "read_yaml", "ros2_update_rate",
           "set_dotted"]

"""ROS 2 controller_manager parameter files, read as jointctl's controller definitions.

A ROS 2 file is a ROS 2 parameters file: one section per node, its parameters under ``ros__parameters``.
The controller manager's section declares the controllers and its ``update_rate``; each controller's own
section holds its parameters::

    controller_manager:
      ros__parameters:
        update_rate: 100                      # Hz, an integer (ROS 2 declares it int64)
        joint_state_broadcaster:
          type: joint_state_broadcaster/JointStateBroadcaster
        pid_controller:
          type: pid_controller/PidController

    pid_controller:
      ros__parameters:
        dof_names: [joint1]
        ...

A file is read this way when one of its top-level sections has ``ros__parameters``
(:func:`is_ros2_parameters`); :func:`read_ros2_controllers` turns it into the ``{name: {type, ...}}``
definitions :class:`~jointctl.control.manager.ControllerManager` loads, each remembering where its
parameters are in the file (``pid_controller.ros__parameters.gains.joint1.p``) for error messages.

- A section key may carry a namespace (``/arm/controller_manager``): its last part names the node.
  Sections of other nodes (robot_state_publisher...) are skipped; one whose name is a misspelling of a
  declared controller's is refused, naming the controller it reads like.
- The manager's parameters besides the controllers (``hardware_components_initial_state``,
  ``diagnostics``, ``thread_priority``, ``cpu_affinity``, ``lock_memory``, ``use_sim_time``,
  ``enforce_command_limits``, ``robot_description``) are accepted and have no effect; an unknown one is
  refused. A controller's ``params_file`` (a path, or a list, relative to the file's folder) is read
  first and its own section applied over it; ``fallback_controllers`` is refused (jointctl's failure
  policy deactivates a failing controller's chain, it starts nothing in its place).
- ROS 2 refuses an integer for a parameter it declares a double (``p: 400`` for ``p: 400.0``: "parameter
  'gains.joint1.p' has invalid type ... setting it to {integer} is not allowed", seen with Jazzy's
  ros2_control_node); so does jointctl, in the file, for the double parameters of the types in
  :data:`DOUBLE_PARAMETERS`. (Values given with ``--set`` are jointctl's and are not checked so.)
- Every controller's parameters of ROS 2's controller_interface are taken out before the controller
  reads its own: ``update_rate`` (0, or the manager's: jointctl runs every controller at the manager's
  rate), ``is_async`` (false: one loop, one thread), ``thread_priority`` and ``use_sim_time`` (no effect).

The manager's ``update_rate`` is the loop's rate: a scenario that names this file and gives no
``loop_rate_hz`` runs its controllers at ``update_rate`` with the physics at the scenario's
``timestep_s``, ``1 / (update_rate · timestep_s)`` steps per cycle; a rate that does not divide into
whole steps is refused (:func:`jointctl.sim.steps.physics_steps`).
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from jointctl.control.params import unknown_field_message
from jointctl.errors import ConfigError

ROS_PARAMETERS = "ros__parameters"
MANAGER_NODE = "controller_manager"
#: controller_manager's parameters other than the controllers: read (``update_rate``) or accepted without effect.
MANAGER_PARAMETERS = ("update_rate", "hardware_components_initial_state", "diagnostics", "thread_priority",
                      "cpu_affinity", "lock_memory", "use_sim_time", "enforce_command_limits", "robot_description")
#: ros2_control's default ``update_rate`` [Hz] (controller_manager_parameters).
DEFAULT_UPDATE_RATE_HZ = 100
#: Keys of a controller's declaration in the manager's parameters.
DECLARATION_KEYS = ("type", "params_file", "fallback_controllers")
#: The parameters ros2_controllers declares doubles, by controller type, as dotted patterns (``*``: one name).
DOUBLE_PARAMETERS: Mapping[str, tuple[str, ...]] = {
    "pid_controller/PidController": tuple(f"gains.*.{k}" for k in ("p", "i", "d", "i_clamp_max", "i_clamp_min",
                                                                   "feedforward_gain")),
    "joint_trajectory_controller/JointTrajectoryController": (
        *(f"gains.*.{k}" for k in ("p", "i", "d", "i_clamp", "ff_velocity_scale")), "constraints.goal_time",
        "constraints.stopped_velocity_tolerance", "constraints.*.trajectory", "constraints.*.goal",
        "action_monitor_rate", "cmd_timeout"),
}
#: Parameters every ROS 2 controller has (controller_interface), taken out before the controller reads its own.
GENERIC_PARAMETERS = ("update_rate", "is_async", "thread_priority", "use_sim_time")


@dataclass(frozen=True)
class Ros2ControllerFile:
    """A ROS 2 controller file read: the manager's ``update_rate_hz`` [Hz], the controllers' definitions
    (``{name: {"type": ..., **parameters}}``, in the manager's order), where each one's parameters are
    (``fields``, e.g. ``pid_controller.ros__parameters``) and where its type is (``type_fields``)."""

    source: str | None
    manager_key: str
    update_rate_hz: int
    controllers: dict[str, dict[str, Any]]
    fields: dict[str, str]
    type_fields: dict[str, str]

    @property
    def update_rate_field(self) -> str:
        return f"{self.manager_key}.{ROS_PARAMETERS}.update_rate"


def node_name(key: Any) -> str:
    """A section key's node name: its last ``/`` part (``/arm/controller_manager`` -> ``controller_manager``)."""
    return str(key).rstrip("/").rsplit("/", 1)[-1]


def is_ros2_parameters(tree: Any) -> bool:
    """Whether a YAML tree is a ROS 2 parameters file (a top-level section with ``ros__parameters``)."""
    return isinstance(tree, Mapping) and any(isinstance(v, Mapping) and ROS_PARAMETERS in v for v in tree.values())


def _integer(value: Any, source: str | None, field: str, *, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError("must be a whole number (ROS 2 declares it an integer)", source=source, field=field,
                          value=value)
    if value < minimum:
        raise ConfigError("must be positive" if minimum > 0 else "must not be negative", source=source, field=field,
                          value=value)
    return value


def _parameters(section: Any, source: str | None, key: str) -> dict[str, Any]:
    """The ``ros__parameters`` mapping of a node's section; ConfigError when the section is not one."""
    if not isinstance(section, Mapping) or ROS_PARAMETERS not in section:
        raise ConfigError(f"a node's parameters go under {ROS_PARAMETERS}", source=source, field=key, value=section)
    extra = [k for k in section if k != ROS_PARAMETERS]
    if extra:
        raise ConfigError(f"a node's section holds {ROS_PARAMETERS} only", source=source, field=f"{key}.{extra[0]}",
                          value=section[extra[0]])
    parameters = section[ROS_PARAMETERS]
    if parameters is None:
        return {}
    if not isinstance(parameters, Mapping):
        raise ConfigError("must be a mapping of parameters", source=source, field=f"{key}.{ROS_PARAMETERS}",
                          value=parameters)
    return dict(parameters)


def read_ros2_controllers(tree: Mapping[str, Any], source: str | None = None, *, base_dir: Path | None = None,
                          read: Callable[[Path], Any] | None = None) -> Ros2ControllerFile:
    """Read a ROS 2 controller file's tree (see the module docstring); ConfigError naming the field and value.
    ``read`` parses a ``params_file`` (:func:`jointctl.control.manager.read_yaml`); without it one is refused."""
    managers = [k for k in tree if node_name(k) == MANAGER_NODE]
    if len(managers) != 1:
        raise ConfigError(f"needs one {MANAGER_NODE} section declaring the controllers (found {len(managers)})",
                          source=source, value=sorted(map(str, tree)))
    manager_key = str(managers[0])
    manager = _parameters(tree[managers[0]], source, manager_key)
    where = f"{manager_key}.{ROS_PARAMETERS}"
    rate = _integer(manager.get("update_rate", DEFAULT_UPDATE_RATE_HZ), source, f"{where}.update_rate", minimum=1)
    declared: dict[str, Any] = {}
    for key, value in manager.items():
        if key in MANAGER_PARAMETERS:
            continue
        if isinstance(value, Mapping) and "type" in value:
            declared[str(key)] = value
            continue
        raise ConfigError(unknown_field_message(str(key), MANAGER_PARAMETERS) + "; a controller is declared with a "
                          "mapping holding its type", source=source, field=f"{where}.{key}", value=value)
    if not declared:
        raise ConfigError("declares no controller (a controller is NAME: {type: ...})", source=source, field=where)
    sections = {node_name(k): k for k in tree if k not in managers}
    for name, key in sections.items():
        if name not in declared:
            near = difflib.get_close_matches(name, list(declared), n=1, cutoff=0.8)
            if near:
                raise ConfigError(f"no controller of that name is declared (did you mean {near[0]!r}?)",
                                  source=source, field=str(key), value=name)
    controllers: dict[str, dict[str, Any]] = {}
    fields, type_fields = {}, {}
    for name, declaration in declared.items():
        dwhere = f"{where}.{name}"
        for key in declaration:
            if key not in DECLARATION_KEYS:
                raise ConfigError(unknown_field_message(str(key), DECLARATION_KEYS), source=source,
                                  field=f"{dwhere}.{key}", value=declaration[key])
        type_name = declaration["type"]
        if not isinstance(type_name, str) or not type_name:
            raise ConfigError("must name a controller type", source=source, field=f"{dwhere}.type", value=type_name)
        if declaration.get("fallback_controllers"):
            raise ConfigError("jointctl starts no fallback controllers: a failing controller's chain is deactivated "
                              "and its joints put in their safe action", source=source,
                              field=f"{dwhere}.fallback_controllers", value=declaration["fallback_controllers"])
        parameters: dict[str, Any] = {}
        for path in _params_files(declaration.get("params_file"), source, f"{dwhere}.params_file", base_dir):
            if read is None:
                raise ConfigError("params files are read when the controllers are loaded", source=source,
                                  field=f"{dwhere}.params_file", value=str(path))
            parameters.update(_from_params_file(read(path), path, name))
        key = sections.get(name)
        fields[name] = f"{key if key is not None else name}.{ROS_PARAMETERS}"
        if key is not None:
            parameters.update(_parameters(tree[key], source, str(key)))
        if "type" in parameters:
            raise ConfigError(f"the type is declared in {where}", source=source, field=f"{fields[name]}.type",
                              value=parameters["type"])
        _take_generic(parameters, rate, source, fields[name])
        _check_doubles(parameters, DOUBLE_PARAMETERS.get(type_name, ()), source, fields[name])
        controllers[name] = {"type": type_name, **parameters}
        type_fields[name] = f"{dwhere}.type"
    return Ros2ControllerFile(source, manager_key, rate, controllers, fields, type_fields)


def _check_doubles(parameters: Mapping[str, Any], patterns: tuple[str, ...], source: str | None, where: str,
                   prefix: tuple[str, ...] = ()) -> None:
    """Refuse an integer where ``patterns`` name a double (ROS 2 refuses it when the controller loads)."""
    for key, value in parameters.items():
        path = (*prefix, str(key))
        if isinstance(value, Mapping):
            _check_doubles(value, patterns, source, where, path)
        elif isinstance(value, int) and not isinstance(value, bool) and any(
                len(path) == len(parts) and all(p in ("*", k) for p, k in zip(parts, path))
                for parts in (pattern.split(".") for pattern in patterns)):
            raise ConfigError(f"ROS 2 declares it a double and refuses an integer: write {value}.0", source=source,
                              field=".".join((where, *path)), value=value)


def _take_generic(parameters: dict[str, Any], rate: int, source: str | None, where: str) -> None:
    """Take controller_interface's parameters out of ``parameters``, refusing what jointctl cannot do."""
    if "update_rate" in parameters:
        own = _integer(parameters.pop("update_rate"), source, f"{where}.update_rate", minimum=0)
        if own not in (0, rate):
            raise ConfigError(f"jointctl runs every controller at the controller manager's update_rate ({rate} Hz)",
                              source=source, field=f"{where}.update_rate", value=own)
    if "is_async" in parameters:
        value = parameters.pop("is_async")
        if value is not False:
            raise ConfigError("jointctl runs every controller synchronously, in its one loop", source=source,
                              field=f"{where}.is_async", value=value)
    parameters.pop("thread_priority", None)
    parameters.pop("use_sim_time", None)


def _params_files(value: Any, source: str | None, field: str, base_dir: Path | None) -> list[Path]:
    if value is None:
        return []
    names = value if isinstance(value, list) else [value]
    paths = []
    for name in names:
        if not isinstance(name, str) or not name:
            raise ConfigError("must be a path or a list of paths", source=source, field=field, value=value)
        path = Path(name)
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        if not path.is_file():
            raise ConfigError("file not found", source=source, field=field, value=name)
        paths.append(path)
    return paths


def _from_params_file(tree: Any, path: Path, name: str) -> dict[str, Any]:
    """The parameters a params file (``tree`` read from ``path``) gives controller ``name``: its ``/**`` section's,
    then its own section's."""
    if not isinstance(tree, Mapping):
        raise ConfigError("must be a ROS 2 parameters file", source=str(path), value=tree)
    parameters: dict[str, Any] = {}
    for key in [k for k in tree if str(k) == "/**"] + [k for k in tree if node_name(k) == name]:
        parameters.update(_parameters(tree[key], str(path), str(key)))
    return parameters


def controller_entries(tree: Any) -> dict[str, str]:
    """Controller name -> type of a controller file's tree, ROS 1 (ros_control: under one namespace or at the top)
    or ROS 2, in the file's order; {} when the tree declares none."""
    if not isinstance(tree, Mapping):
        return {}
    if is_ros2_parameters(tree):
        managers = [k for k in tree if node_name(k) == MANAGER_NODE]
        manager = tree[managers[0]].get(ROS_PARAMETERS) if len(managers) == 1 else None
        if not isinstance(manager, Mapping):
            return {}
        return {str(k): v["type"] for k, v in manager.items() if isinstance(v, Mapping) and "type" in v}
    body = tree
    if len(tree) == 1 and all(isinstance(v, Mapping) and "type" not in v for v in tree.values()):
        body = next(iter(tree.values()))
    return {str(k): v["type"] for k, v in body.items() if isinstance(v, Mapping) and "type" in v}


__all__ = ["DEFAULT_UPDATE_RATE_HZ", "DOUBLE_PARAMETERS", "MANAGER_NODE", "ROS_PARAMETERS", "Ros2ControllerFile",
           "controller_entries",
           "is_ros2_parameters", "node_name", "read_ros2_controllers"]

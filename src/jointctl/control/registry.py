"""Every controller type jointctl loads from a ros_control YAML ``type``, in one table.

Like pluginlib's plugin descriptions (and dm_control's suite, which lists its tasks in one
place), the table names each type and where its class lives; the class is imported the first time
it is asked for. So the table can list the trajectory executor, which builds on control/, without
control/ importing the layer above it, and nothing registers by the side effect of an import.

Types from outside jointctl (a test double, a user's controller) are added with
:func:`register_controller`; the built-in names cannot be taken.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator, Mapping

from jointctl.control.controller import Controller

#: YAML ``type`` -> ``"module:Class"``.
BUILTIN_TYPES: Mapping[str, str] = {
    "joint_state_controller/JointStateController": "jointctl.control.joint_state_controller:JointStateController",
    "joint_state_broadcaster/JointStateBroadcaster": "jointctl.control.joint_state_controller:JointStateBroadcaster",
    "effort_controllers/JointPositionController": "jointctl.control.joint_controllers:JointPositionController",
    "effort_controllers/JointVelocityController": "jointctl.control.joint_controllers:JointVelocityController",
    "admittance_controllers/AdmittanceController": "jointctl.control.admittance_controller:AdmittanceController",
    "admittance_controllers/CartesianAdmittanceController":
        "jointctl.control.cartesian_admittance_controller:CartesianAdmittanceController",
    "trajectory_controllers/JointTrajectoryExecutor": "jointctl.trajectory.executor:TrajectoryExecutor",
    # ros2_controllers' types, computing as they do (docs/ros2_control_files.md).
    "pid_controller/PidController": "jointctl.control.pid_controller:PidController",
    "forward_command_controller/ForwardCommandController":
        "jointctl.control.forward_command_controller:ForwardCommandController",
    "effort_controllers/JointGroupEffortController":
        "jointctl.control.forward_command_controller:JointGroupEffortController",
    "joint_trajectory_controller/JointTrajectoryController":
        "jointctl.trajectory.joint_trajectory_controller:JointTrajectoryController",
}

_PLUGINS: dict[str, type[Controller]] = {}


def register_controller(type_name: str) -> Callable[[type[Controller]], type[Controller]]:
    """Class decorator for a controller type from outside jointctl: loadable as ``type_name``."""

    def register(cls: type[Controller]) -> type[Controller]:
        if type_name in BUILTIN_TYPES:
            raise ValueError(f"{type_name!r} is a built-in controller type")
        _PLUGINS[type_name] = cls
        return cls

    return register


class ControllerTypes(Mapping[str, type[Controller]]):
    """The built-in types and the registered plugins, by YAML ``type`` name (classes imported on
    first use)."""

    def __init__(self) -> None:
        self._loaded: dict[str, type[Controller]] = {}

    def __getitem__(self, name: str) -> type[Controller]:
        if name in _PLUGINS:
            return _PLUGINS[name]
        if name not in self._loaded:
            module, _, attribute = BUILTIN_TYPES[name].partition(":")
            self._loaded[name] = getattr(importlib.import_module(module), attribute)
        return self._loaded[name]

    def __iter__(self) -> Iterator[str]:
        return iter([*BUILTIN_TYPES, *_PLUGINS])

    def __len__(self) -> int:
        return len(BUILTIN_TYPES) + len(_PLUGINS)

    def __contains__(self, name: object) -> bool:
        return name in BUILTIN_TYPES or name in _PLUGINS


def controller_types() -> ControllerTypes:
    """Every loadable controller type, by its YAML ``type`` name."""
    return ControllerTypes()


__all__ = ["BUILTIN_TYPES", "ControllerTypes", "controller_types", "register_controller"]

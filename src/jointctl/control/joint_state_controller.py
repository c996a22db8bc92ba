"""``joint_state_controller/JointStateController``: joint states at ``publish_rate``; and ROS 2's
``joint_state_broadcaster/JointStateBroadcaster``: joint states every cycle.

Every ``1/publish_rate`` seconds of loop time it takes a
:class:`JointStateSample` (sensor_msgs/JointState semantics), stores it in
:attr:`JointStateController.latest` (a single-slot door edges read) and hands
it to each subscriber. Subscribers run inside the loop: they must only queue.

:class:`JointStateBroadcaster` reads ros2_controllers' parameters instead (``joints``, ``interfaces``,
``extra_joints``, ``use_local_topics``, ``use_urdf_to_filter``, ``map_interface_to_joint_state``) and
publishes at the controller manager's rate, every cycle, as it does.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from jointctl.control.controller import Controller
from jointctl.control.params import Params
from jointctl.errors import ConfigError
from jointctl.hardware.interface import HardwareInterface
from jointctl.model.robot_model import RobotModel


@dataclass(frozen=True)
class JointStateSample:
    """Joint names and their position, velocity and effort at ``time_s`` (SI units)."""

    time_s: float
    name: tuple[str, ...]
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    effort: tuple[float, ...]


class JointStateController(Controller):
    """Publishes every joint's state; claims no command interface."""

    def __init__(self, name: str, params: Params) -> None:
        super().__init__(name, params)
        self.publish_rate_hz = params.number("publish_rate", 50.0, positive=True)
        params.reject_unknown({"type"})
        self.latest: JointStateSample | None = None
        self.published = 0
        self._subscribers: list[Callable[[JointStateSample], None]] = []

    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        return ()

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        self.hardware = hardware
        self.period_s = 1.0 / self.publish_rate_hz

    def subscribe(self, callback: Callable[[JointStateSample], None]) -> None:
        self._subscribers.append(callback)

    def start(self, time_s: float) -> None:
        # The first publication is at the first multiple of the period at or after time_s.
        self._next_k = math.ceil(time_s / self.period_s - 1e-9)

    def update(self, time_s: float, period_s: float) -> None:
        # Publish on the k-th multiple of the period; integer counting keeps it drift-free.
        if time_s + 1e-9 < self._next_k * self.period_s:
            return
        self._next_k += 1
        hw = self.hardware
        sample = JointStateSample(time_s, hw.joint_names, tuple(hw.position),
                                  tuple(hw.velocity), tuple(hw.effort))
        self.latest = sample
        self.published += 1
        for callback in self._subscribers:
            callback(sample)


#: The joint-state fields of sensor_msgs/JointState, which JointStateBroadcaster fills.
JOINT_STATE_INTERFACES = ("position", "velocity", "effort")


class JointStateBroadcaster(JointStateController):
    """ros2_controllers' ``joint_state_broadcaster/JointStateBroadcaster``: a :class:`JointStateSample` every cycle.

    Parameters (all optional, ros2_controllers' defaults): ``joints`` and ``interfaces`` (both given: only
    those joints, and of their position, velocity and effort only those interfaces, the others NaN; either
    empty: every joint, every interface), ``extra_joints`` (published with 0 position, velocity and effort),
    ``use_local_topics`` (false; kept for the edge: ``~/joint_states`` instead of ``/joint_states``),
    ``use_urdf_to_filter`` (true; jointctl's joints are the URDF's), ``map_interface_to_joint_state``
    (jointctl's hardware has the standard names only: each must map to itself).
    """

    def __init__(self, name: str, params: Params) -> None:
        Controller.__init__(self, name, params)
        self.selected_joints = self._names(params, "joints")
        self.interfaces = self._names(params, "interfaces")
        for k, interface in enumerate(self.interfaces):
            if interface not in JOINT_STATE_INTERFACES:
                raise params.error(f"jointctl publishes {', '.join(JOINT_STATE_INTERFACES)} (a joint state's fields)",
                                   f"interfaces[{k}]", interface)
        self.extra_joints = self._names(params, "extra_joints")
        self.use_local_topics = params.boolean("use_local_topics", False)
        self.use_urdf_to_filter = params.boolean("use_urdf_to_filter", True)
        if params.has("map_interface_to_joint_state"):
            mapping = params.child("map_interface_to_joint_state")
            for field in JOINT_STATE_INTERFACES:
                if mapping.string(field, field) != field:
                    raise mapping.error("jointctl's hardware has the standard interface names only", field,
                                        mapping.values[field])
            mapping.reject_unknown()
        params.reject_unknown({"type"})
        self.latest = None
        self.published = 0
        self._subscribers = []

    @staticmethod
    def _names(params: Params, key: str) -> tuple[str, ...]:
        value = params.raw(key, [])
        if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
            raise params.error("must be a list of names", key, value)
        return tuple(value)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        self.hardware = hardware
        filtered = bool(self.selected_joints) and bool(self.interfaces)
        joints = self.selected_joints if filtered else hardware.joint_names
        self._index = [hardware.joint_index(j, source=self.source, field=f"{self.field}.joints[{k}]")
                       for k, j in enumerate(joints)]
        clash = [j for j in self.extra_joints if j in joints]
        if clash:
            raise ConfigError("is already published", source=self.source, field=f"{self.field}.extra_joints",
                              value=clash[0])
        self._names_out = tuple(joints) + self.extra_joints
        wanted = self.interfaces if filtered else JOINT_STATE_INTERFACES
        self._fields = tuple(field in wanted for field in JOINT_STATE_INTERFACES)
        self._extra = (0.0,) * len(self.extra_joints)

    def start(self, time_s: float) -> None:
        pass

    def update(self, time_s: float, period_s: float) -> None:
        hw, index, extra = self.hardware, self._index, self._extra
        rows = []
        for wanted, values in zip(self._fields, (hw.position, hw.velocity, hw.effort)):
            rows.append(tuple(values[i] for i in index) + extra if wanted else (math.nan,) * len(self._names_out))
        sample = JointStateSample(time_s, self._names_out, *rows)
        self.latest = sample
        self.published += 1
        for callback in self._subscribers:
            callback(sample)

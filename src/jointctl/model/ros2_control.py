"""A URDF's ``<ros2_control>`` tags: the hardware components ROS 2's controller_manager would load.

ros2_control describes the hardware inside the URDF (hardware_interface's ``component_parser``)::

    <ros2_control name="MockSystem" type="system">
      <hardware>
        <plugin>mock_components/GenericSystem</plugin>
        <param name="calculate_dynamics">true</param>
      </hardware>
      <joint name="joint1">
        <command_interface name="effort"><param name="min">-100</param><param name="max">100</param></command_interface>
        <state_interface name="position"><param name="initial_value">0.3</param></state_interface>
        <state_interface name="velocity"/>
      </joint>
      <sensor name="ft"> <state_interface name="force.z"/> ... </sensor>
      <gpio name="io"> ... </gpio>
    </ros2_control>

:func:`parse_ros2_control` reads one such element into a :class:`Ros2ControlComponent` and refuses
what the reference refuses (a missing ``name`` or ``type``, a ``<hardware>`` without ``<plugin>``, a
``<param>`` or interface without a name, an unknown child tag, a joint the URDF lacks or a fixed one,
a mimic joint with command interfaces), plus what jointctl cannot read: an ``initial_value`` that is
not a finite number, or a position outside the joint's limits. Errors are
:class:`~jointctl.errors.ModelError` naming the element (``ros2_control[MockSystem].joint[joint1]
.state_interface[position].initial_value``) and the value.

When jointctl simulates the robot its MuJoCo world stands in for the hardware plugin (whatever it
is: ``mock_components/GenericSystem``, ``gz_ros2_control/GazeboSimSystem``, a real robot's driver):
a joint with an ``effort`` command interface gets an effort actuator (as a ``<transmission>`` with an
``EffortJointInterface`` would), and the ``initial_value`` of its ``position`` state interface is
where it starts. Velocity and position command interfaces are read and kept; the simulated robot
refuses a joint that has no effort one (``jointctl.model.mjcf``), because it simulates effort-driven
joints only (see docs/ros2_control_files.md).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from jointctl.errors import ModelError

#: ``<ros2_control type=...>``: the component kinds hardware_interface's resource manager loads.
COMPONENT_TYPES = ("system", "actuator", "sensor")
#: hardware_interface's standard interface names (``hardware_interface_type_values.hpp``).
POSITION, VELOCITY, ACCELERATION, EFFORT = "position", "velocity", "acceleration", "effort"
STANDARD_INTERFACES = (POSITION, VELOCITY, ACCELERATION, EFFORT)
#: The children ``component_parser`` accepts in a ``<ros2_control>`` element.
_CHILDREN = ("hardware", "joint", "sensor", "gpio", "transmission")
_TRUE = ("true", "True", "1")
_FALSE = ("false", "False", "0")

Params = tuple[tuple[str, str], ...]


@dataclass(frozen=True)
class InterfaceSpec:
    """One ``<command_interface>`` or ``<state_interface>``: its ``name`` and ``<param>`` values (text, as
    ros2_control keeps them). ``initial_value`` is the ``initial_value`` param as a number (None when not
    given); ``minimum``/``maximum`` the ``min``/``max`` params (None when not given)."""

    name: str
    params: Params = ()
    initial_value: float | None = None
    minimum: float | None = None
    maximum: float | None = None

    def param(self, key: str, default: str | None = None) -> str | None:
        return dict(self.params).get(key, default)


@dataclass(frozen=True)
class Ros2ControlJoint:
    """A ``<joint>`` of a component: the URDF joint it names, its interfaces in document order, its params
    and its ``mimic`` attribute (None when not set)."""

    name: str
    command_interfaces: tuple[InterfaceSpec, ...] = ()
    state_interfaces: tuple[InterfaceSpec, ...] = ()
    params: Params = ()
    mimic: bool | None = None

    @property
    def command_names(self) -> tuple[str, ...]:
        return tuple(i.name for i in self.command_interfaces)

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(i.name for i in self.state_interfaces)

    def state_interface(self, name: str) -> InterfaceSpec | None:
        return next((i for i in self.state_interfaces if i.name == name), None)

    @property
    def initial_position(self) -> float | None:
        """The ``initial_value`` of its ``position`` state interface [m or rad], None when not given."""
        spec = self.state_interface(POSITION)
        return None if spec is None else spec.initial_value


@dataclass(frozen=True)
class Ros2ControlDevice:
    """A ``<sensor>`` or ``<gpio>`` of a component: noted (name, interfaces, params), not simulated."""

    kind: str
    name: str
    command_interfaces: tuple[InterfaceSpec, ...] = ()
    state_interfaces: tuple[InterfaceSpec, ...] = ()
    params: Params = ()


@dataclass(frozen=True)
class Ros2ControlComponent:
    """One ``<ros2_control>`` element: a hardware component (``type`` system, actuator or sensor) with its
    hardware ``plugin`` and ``<hardware>`` params, its joints, sensors and GPIOs, and the names of the
    transmissions it declares (noted only)."""

    name: str
    type: str
    plugin: str
    hardware_params: Params = ()
    joints: tuple[Ros2ControlJoint, ...] = ()
    sensors: tuple[Ros2ControlDevice, ...] = ()
    gpios: tuple[Ros2ControlDevice, ...] = ()
    transmissions: tuple[str, ...] = ()

    def joint(self, name: str) -> Ros2ControlJoint | None:
        return next((j for j in self.joints if j.name == name), None)

    def stand_in(self) -> str:
        """One line saying what jointctl's simulation stands in for."""
        joints = ", ".join(f"{j.name} ({'/'.join(j.command_names) or 'no command'})" for j in self.joints)
        return (f"ros2_control {self.type} {self.name!r}: jointctl's simulated robot stands in for the hardware "
                f"plugin {self.plugin} (joints {joints or 'none'})")


def parse_ros2_control(element: ET.Element, joints: dict, source: str | None = None) -> Ros2ControlComponent:
    """Read a ``<ros2_control>`` element; ``joints`` maps the URDF's joint names to its
    :class:`~jointctl.model.robot_model.Joint` (their type and limits are checked)."""
    return _Reader(source, joints).component(element)


class _Reader:
    def __init__(self, source: str | None, joints: dict) -> None:
        self.source = source
        self.joints = joints

    def error(self, message: str, where: str, value=None, *, has_value: bool = True) -> ModelError:
        if has_value:
            return ModelError(message, source=self.source, field=where, value=value)
        return ModelError(message, source=self.source, field=where)

    def component(self, el: ET.Element) -> Ros2ControlComponent:
        name = el.get("name")
        if not name:
            raise self.error("<ros2_control> needs a name", "ros2_control", has_value=False)
        where = f"ros2_control[{name}]"
        ctype = el.get("type")
        if ctype is None:
            raise self.error("<ros2_control> needs a type (system, actuator or sensor)", f"{where}.type",
                             has_value=False)
        if ctype.lower() not in COMPONENT_TYPES:
            raise self.error(f"unknown component type (one of {', '.join(COMPONENT_TYPES)})", f"{where}.type", ctype)
        plugin, hardware_params = None, ()
        joints, sensors, gpios, transmissions = [], [], [], []
        for child in el:
            if not isinstance(child.tag, str):  # comments
                continue
            if child.tag not in _CHILDREN:
                raise self.error(f"unknown tag (a <ros2_control> holds {', '.join(_CHILDREN)})", where, child.tag)
            if child.tag == "hardware":
                pel = child.find("plugin")
                plugin = (pel.text or "").strip() if pel is not None else ""
                if not plugin:
                    raise self.error("<hardware> needs a <plugin> naming the hardware plugin",
                                     f"{where}.hardware.plugin", has_value=False)
                hardware_params = self.params(child, f"{where}.hardware")
            elif child.tag == "joint":
                joints.append(self.joint(child, where))
            elif child.tag in ("sensor", "gpio"):
                device = self.device(child, where)
                (sensors if child.tag == "sensor" else gpios).append(device)
            else:
                tname = child.get("name")
                if not tname:
                    raise self.error("<transmission> needs a name", f"{where}.transmission", has_value=False)
                transmissions.append(tname)
        if plugin is None:
            raise self.error("needs a <hardware> with a <plugin>", f"{where}.hardware", has_value=False)
        names = [j.name for j in joints]
        for k, joint_name in enumerate(names):
            if joint_name in names[:k]:
                raise self.error("the joint is listed twice", f"{where}.joint", joint_name)
        return Ros2ControlComponent(name, ctype.lower(), plugin, hardware_params, tuple(joints), tuple(sensors),
                                    tuple(gpios), tuple(transmissions))

    def params(self, el: ET.Element, where: str) -> Params:
        out = []
        for pel in el.findall("param"):
            pname = pel.get("name")
            if not pname:
                raise self.error("<param> needs a name", f"{where}.param", has_value=False)
            out.append((pname, (pel.text or "").strip()))
        return tuple(out)

    def number(self, text: str | None, where: str) -> float | None:
        if text is None:
            return None
        try:
            value = float(text)
        except ValueError:
            raise self.error("is not a number", where, text) from None
        if not math.isfinite(value):
            raise self.error("must be finite", where, text)
        return value

    def interface(self, el: ET.Element, where: str) -> InterfaceSpec:
        iname = el.get("name")
        if not iname:
            raise self.error(f"<{el.tag}> needs a name", f"{where}.{el.tag}", has_value=False)
        iwhere = f"{where}.{el.tag}[{iname}]"
        params = self.params(el, iwhere)
        values = dict(params)
        spec = InterfaceSpec(iname, params,
                             self.number(values.get("initial_value"), f"{iwhere}.initial_value"),
                             self.number(values.get("min"), f"{iwhere}.min"),
                             self.number(values.get("max"), f"{iwhere}.max"))
        if spec.minimum is not None and spec.maximum is not None and spec.minimum > spec.maximum:
            raise self.error("min is above max", f"{iwhere}.min", values["min"])
        return spec

    def interfaces(self, el: ET.Element, where: str) -> tuple[tuple[InterfaceSpec, ...], tuple[InterfaceSpec, ...]]:
        commands = tuple(self.interface(c, where) for c in el.findall("command_interface"))
        states = tuple(self.interface(s, where) for s in el.findall("state_interface"))
        for kind, specs in (("command_interface", commands), ("state_interface", states)):
            names = [s.name for s in specs]
            for k, n in enumerate(names):
                if n in names[:k]:
                    raise self.error("the interface is listed twice", f"{where}.{kind}", n)
        return commands, states

    def joint(self, el: ET.Element, parent: str) -> Ros2ControlJoint:
        name = el.get("name")
        if not name:
            raise self.error("<joint> needs a name", f"{parent}.joint", has_value=False)
        where = f"{parent}.joint[{name}]"
        urdf_joint = self.joints.get(name)
        if urdf_joint is None:
            raise self.error("the URDF has no joint of that name", f"{parent}.joint", name)
        if urdf_joint.type == "fixed":
            raise self.error("is a fixed joint: fixed joints do not make sense in ros2_control", where,
                             urdf_joint.type)
        if urdf_joint.type not in ("revolute", "continuous", "prismatic"):
            raise self.error("jointctl drives revolute, continuous and prismatic joints only", where, urdf_joint.type)
        if urdf_joint.is_locked:
            raise self.error("its lower and upper limits are equal: jointctl treats the joint as fixed", where,
                             urdf_joint.limits.lower)
        mimic_text = el.get("mimic")
        mimic = None
        if mimic_text is not None:
            if mimic_text not in _TRUE + _FALSE:
                raise self.error("mimic must be true or false", f"{where}.mimic", mimic_text)
            mimic = mimic_text in _TRUE
        commands, states = self.interfaces(el, where)
        if mimic and commands:
            raise self.error("a mimic joint cannot have command interfaces", f"{where}.command_interface",
                             commands[0].name)
        joint = Ros2ControlJoint(name, commands, states, self.params(el, where), mimic)
        initial = joint.initial_position
        if initial is not None:
            lim = urdf_joint.limits
            if (urdf_joint.type != "continuous" and lim is not None and lim.lower is not None
                    and not lim.lower <= initial <= lim.upper):
                raise self.error(f"outside the joint's limits [{lim.lower}, {lim.upper}]",
                                 f"{where}.state_interface[position].initial_value", initial)
        return joint

    def device(self, el: ET.Element, parent: str) -> Ros2ControlDevice:
        name = el.get("name")
        if not name:
            raise self.error(f"<{el.tag}> needs a name", f"{parent}.{el.tag}", has_value=False)
        where = f"{parent}.{el.tag}[{name}]"
        commands, states = self.interfaces(el, where)
        return Ros2ControlDevice(el.tag, name, commands, states, self.params(el, where))


__all__ = ["ACCELERATION", "COMPONENT_TYPES", "EFFORT", "POSITION", "STANDARD_INTERFACES", "VELOCITY",
           "InterfaceSpec", "Ros2ControlComponent", "Ros2ControlDevice", "Ros2ControlJoint", "parse_ros2_control"]

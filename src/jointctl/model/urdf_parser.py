"""Parse URDF XML into a validated :class:`RobotModel`.

Errors name the file, the element (``joint[joint1].limit``) and the attribute
with its value. Besides the URDF core (links, joints, limits, dynamics) this
reads ros_control ``<transmission>`` elements and two Gazebo plugins the
chapter's robots use: ``gazebo_ros_control`` (for the robot namespace) and
``gazebo_ros_ft_sensor`` (a force-torque sensor on a joint); and ROS 2's ``<ros2_control>``
elements (:mod:`jointctl.model.ros2_control`).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

from jointctl.errors import ModelError
from jointctl.model.ros2_control import EFFORT, Ros2ControlComponent, parse_ros2_control
from jointctl.model.robot_model import (
    JOINT_TYPES,
    Geometry,
    Inertial,
    Joint,
    JointLimits,
    Link,
    Pose,
    RobotModel,
    SensorSpec,
    Shape,
    Transmission,
)

_FT_PLUGIN = "libgazebo_ros_ft_sensor.so"
_CONTROL_PLUGIN = "libgazebo_ros_control.so"


def parse_urdf(text: str, *, source: str | None = None) -> RobotModel:
    """Parse URDF ``text``; ``source`` names the file in error messages."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ModelError(f"not well-formed XML: {exc}", source=source) from None
    return _Parser(source).robot(root)


class _Parser:
    def __init__(self, source: str | None) -> None:
        self.source = source

    def error(self, message: str, where: str, value=None, *, has_value: bool = True) -> ModelError:
        if has_value:
            return ModelError(message, source=self.source, field=where, value=value)
        return ModelError(message, source=self.source, field=where)

    # -- numbers ---------------------------------------------------------------
    def number(self, el: ET.Element, attr: str, where: str, default: float | None = None) -> float:
        raw = el.get(attr)
        if raw is None:
            if default is None:
                raise self.error(f"missing attribute '{attr}'", where, has_value=False)
            return default
        try:
            value = float(raw)
        except ValueError:
            raise self.error(f"attribute '{attr}' is not a number", where, raw) from None
        if not math.isfinite(value):
            raise self.error(f"attribute '{attr}' is not finite", where, raw)
        return value

    def vector(self, el: ET.Element | None, attr: str, where: str, default, n: int = 3):
        if el is None or el.get(attr) is None:
            return default
        raw = el.get(attr)
        parts = raw.split()
        if len(parts) != n:
            raise self.error(f"attribute '{attr}' needs {n} numbers", where, raw)
        try:
            values = tuple(float(p) for p in parts)
        except ValueError:
            raise self.error(f"attribute '{attr}' is not a list of numbers", where, raw) from None
        if not all(math.isfinite(v) for v in values):
            raise self.error(f"attribute '{attr}' is not finite", where, raw)
        return values

    def pose(self, el: ET.Element | None, where: str) -> Pose:
        if el is None:
            return Pose()
        return Pose(
            xyz=self.vector(el, "xyz", f"{where}.origin", (0.0, 0.0, 0.0)),
            rpy=self.vector(el, "rpy", f"{where}.origin", (0.0, 0.0, 0.0)),
        )

    # -- elements --------------------------------------------------------------
    def robot(self, root: ET.Element) -> RobotModel:
        if root.tag != "robot":
            raise self.error("the root element must be <robot>", "robot", root.tag)
        name = root.get("name")
        if not name:
            raise self.error("<robot> needs a name", "robot", has_value=False)
        # Named colours defined at the top level, which visuals may refer to by name.
        self.materials = {}
        for k, mel in enumerate(root.findall("material")):
            rgba = self.color(mel, f"material[{mel.get('name') or k}]")
            if mel.get("name") and rgba is not None:
                self.materials[mel.get("name")] = rgba
        links = tuple(self.link(el) for el in root.findall("link"))
        if not links:
            raise self.error("the robot has no <link>", "robot", has_value=False)
        self.unique([lk.name for lk in links], "link")
        joints = tuple(self.joint(el) for el in root.findall("joint"))
        self.unique([j.name for j in joints], "joint")
        self.check_tree(links, joints)
        transmissions = tuple(self.transmission(el) for el in root.findall("transmission"))
        joint_names = {j.name for j in joints}
        for tr in transmissions:
            if tr.joint not in joint_names:
                raise self.error("transmission names a joint that does not exist",
                                 f"transmission[{tr.name}].joint", tr.joint)
        namespace, sensors = self.gazebo(root, joints)
        components = self.ros2_control(root, joints)
        return RobotModel(
            name=name,
            links=links,
            joints=joints,
            transmissions=transmissions + self.effort_transmissions(components, transmissions),
            sensors=sensors,
            namespace=namespace,
            source=self.source,
            ros2_control=components,
        )

    def ros2_control(self, root: ET.Element, joints: tuple[Joint, ...]) -> tuple[Ros2ControlComponent, ...]:
        by_name = {j.name: j for j in joints}
        components = tuple(parse_ros2_control(el, by_name, self.source) for el in root.findall("ros2_control"))
        self.unique([c.name for c in components], "ros2_control")
        owner: dict[str, str] = {}
        for c in components:
            for j in c.joints:
                if j.name in owner:
                    raise self.error(f"the joint is already in ros2_control[{owner[j.name]}]",
                                     f"ros2_control[{c.name}].joint", j.name)
                owner[j.name] = c.name
        return components

    @staticmethod
    def effort_transmissions(components: tuple[Ros2ControlComponent, ...],
                             transmissions: tuple[Transmission, ...]) -> tuple[Transmission, ...]:
        """A transmission with an EffortJointInterface for every ros2_control joint with an ``effort``
        command interface that no ``<transmission>`` drives yet: how the simulated robot knows to actuate it."""
        driven = {t.joint for t in transmissions}
        return tuple(Transmission(f"{c.name}/{j.name}", "transmission_interface/SimpleTransmission", j.name,
                                  ("EffortJointInterface",), ros2_control=c.name)
                     for c in components for j in c.joints if EFFORT in j.command_names and j.name not in driven)

    def unique(self, names: list[str], kind: str) -> None:
        seen: set[str] = set()
        for n in names:
            if n in seen:
                raise self.error(f"duplicate {kind} name", kind, n)
            seen.add(n)

    def link(self, el: ET.Element) -> Link:
        name = el.get("name")
        if not name:
            raise self.error("<link> needs a name", "link", has_value=False)
        where = f"link[{name}]"
        inertial = None
        iel = el.find("inertial")
        if iel is not None:
            mel = iel.find("mass")
            if mel is None:
                raise self.error("<inertial> needs <mass>", f"{where}.inertial", has_value=False)
            mass = self.number(mel, "value", f"{where}.inertial.mass")
            if mass <= 0:
                raise self.error("mass must be positive", f"{where}.inertial.mass", mass)
            tel = iel.find("inertia")
            if tel is None:
                raise self.error("<inertial> needs <inertia>", f"{where}.inertial", has_value=False)
            w = f"{where}.inertial.inertia"
            ixx, iyy, izz = (self.number(tel, a, w) for a in ("ixx", "iyy", "izz"))
            ixy, ixz, iyz = (self.number(tel, a, w, 0.0) for a in ("ixy", "ixz", "iyz"))
            for attr, v in (("ixx", ixx), ("iyy", iyy), ("izz", izz)):
                if v < 0:
                    raise self.error(f"{attr} must not be negative", w, v)
            inertial = Inertial(mass, self.pose(iel.find("origin"), f"{where}.inertial"),
                                (ixx, iyy, izz, ixy, ixz, iyz))
        visuals = tuple(self.shape(s, f"{where}.visual", with_color=True) for s in el.findall("visual"))
        collisions = tuple(self.shape(s, f"{where}.collision") for s in el.findall("collision"))
        return Link(name, inertial, visuals, collisions)

    def color(self, mel: ET.Element, where: str) -> tuple[float, float, float, float] | None:
        """The ``<color rgba="r g b a">`` of a ``<material>`` (0..1 each), or None when it has none."""
        cel = mel.find("color")
        if cel is None:
            return None
        rgba = self.vector(cel, "rgba", f"{where}.color", None, n=4)
        if rgba is None or any(not 0.0 <= v <= 1.0 for v in rgba):
            raise self.error("rgba must be four numbers from 0 to 1", f"{where}.color.rgba", cel.get("rgba"))
        return tuple(rgba)

    def material(self, el: ET.Element, where: str) -> tuple[float, float, float, float] | None:
        """A visual's colour: its material's own ``<color>``, or the named top-level material's."""
        mel = el.find("material")
        if mel is None:
            return None
        rgba = self.color(mel, f"{where}.material")
        if rgba is None and mel.get("name"):
            rgba = getattr(self, "materials", {}).get(mel.get("name"))
        return rgba

    def shape(self, el: ET.Element, where: str, *, with_color: bool = False) -> Shape:
        gel = el.find("geometry")
        if gel is None or len(gel) == 0:
            raise self.error("needs a <geometry> with a shape", where, has_value=False)
        g = gel[0]
        w = f"{where}.geometry.{g.tag}"
        if g.tag == "box":
            size = self.vector(g, "size", w, None)
            if size is None:
                raise self.error("<box> needs size", w, has_value=False)
            self.positive(size, w, "size")
            geom = Geometry("box", size_m=size)
        elif g.tag == "cylinder":
            r, length = self.number(g, "radius", w), self.number(g, "length", w)
            self.positive((r, length), w, "radius/length")
            geom = Geometry("cylinder", radius_m=r, length_m=length)
        elif g.tag == "sphere":
            r = self.number(g, "radius", w)
            self.positive((r,), w, "radius")
            geom = Geometry("sphere", radius_m=r)
        elif g.tag == "mesh":
            filename = g.get("filename")
            if not filename:
                raise self.error("<mesh> needs filename", w, has_value=False)
            geom = Geometry("mesh", mesh_path=filename,
                            scale=self.vector(g, "scale", w, (1.0, 1.0, 1.0)))
        else:
            raise self.error("unsupported geometry", f"{where}.geometry", g.tag)
        return Shape(self.pose(el.find("origin"), where), geom, self.material(el, where) if with_color else None)

    def positive(self, values, where: str, what: str) -> None:
        if any(v <= 0 for v in values):
            raise self.error(f"{what} must be positive", where, values if len(values) > 1 else values[0])

    def joint(self, el: ET.Element) -> Joint:
        name = el.get("name")
        if not name:
            raise self.error("<joint> needs a name", "joint", has_value=False)
        where = f"joint[{name}]"
        jtype = el.get("type")
        if jtype not in JOINT_TYPES:
            raise self.error(f"unknown joint type (one of {', '.join(sorted(JOINT_TYPES))})",
                             f"{where}.type", jtype)
        parent, child = el.find("parent"), el.find("child")
        if parent is None or not parent.get("link"):
            raise self.error("needs <parent link=...>", where, has_value=False)
        if child is None or not child.get("link"):
            raise self.error("needs <child link=...>", where, has_value=False)
        axis = self.vector(el.find("axis"), "xyz", f"{where}.axis", (1.0, 0.0, 0.0))
        norm = math.sqrt(sum(a * a for a in axis))
        if norm == 0 and jtype != "fixed":
            raise self.error("axis must not be zero", f"{where}.axis", el.find("axis").get("xyz"))
        axis = tuple(a / norm for a in axis) if norm else axis
        limits = None
        lel = el.find("limit")
        if jtype in ("revolute", "prismatic") and lel is None:
            raise self.error(f"a {jtype} joint needs <limit>", where, has_value=False)
        if lel is not None and jtype in ("revolute", "prismatic", "continuous"):
            lw = f"{where}.limit"
            effort = self.number(lel, "effort", lw)
            velocity = self.number(lel, "velocity", lw)
            if effort < 0:
                raise self.error("effort must not be negative", f"{lw}.effort", effort)
            if velocity < 0:
                raise self.error("velocity must not be negative", f"{lw}.velocity", velocity)
            lower = upper = None
            if jtype != "continuous":
                lower = self.number(lel, "lower", lw, 0.0)
                upper = self.number(lel, "upper", lw, 0.0)
                if lower > upper:
                    raise self.error("lower is above upper", f"{lw}.lower", lower)
            limits = JointLimits(lower, upper, effort, velocity)
        dyn = el.find("dynamics")
        damping = friction = armature = 0.0
        if dyn is not None:
            damping = self.number(dyn, "damping", f"{where}.dynamics", 0.0)
            friction = self.number(dyn, "friction", f"{where}.dynamics", 0.0)
            armature = self.number(dyn, "armature", f"{where}.dynamics", 0.0)
            if armature < 0:
                raise self.error("armature must not be negative", f"{where}.dynamics.armature", armature)
            if damping < 0:
                raise self.error("damping must not be negative", f"{where}.dynamics.damping", damping)
            if friction < 0:
                raise self.error("friction must not be negative", f"{where}.dynamics.friction", friction)
        return Joint(name, jtype, parent.get("link"), child.get("link"),
                     self.pose(el.find("origin"), where), axis, limits, damping, friction, armature)

    def check_tree(self, links: tuple[Link, ...], joints: tuple[Joint, ...]) -> None:
        names = {lk.name for lk in links}
        parent_of: dict[str, str] = {}
        for j in joints:
            for role, link in (("parent", j.parent), ("child", j.child)):
                if link not in names:
                    raise self.error(f"{role} link does not exist", f"joint[{j.name}].{role}", link)
            if j.child in parent_of:
                raise self.error("link has two parent joints", f"joint[{j.name}].child", j.child)
            parent_of[j.child] = j.parent
        roots = [n for n in names if n not in parent_of]
        if len(roots) != 1:
            raise self.error("the links must form one tree with a single root", "robot",
                             sorted(roots))
        for start in names:
            seen, node = set(), start
            while node in parent_of:
                if node in seen:
                    raise self.error("the joints form a loop", "robot", node)
                seen.add(node)
                node = parent_of[node]

    def transmission(self, el: ET.Element) -> Transmission:
        name = el.get("name") or "?"
        where = f"transmission[{name}]"
        jel = el.find("joint")
        if jel is None or not jel.get("name"):
            raise self.error("needs <joint name=...>", where, has_value=False)
        interfaces = tuple(
            (h.text or "").strip().rsplit("/", 1)[-1]
            for h in jel.findall("hardwareInterface")
        )
        actuator = el.find("actuator")
        reduction = 1.0
        if actuator is not None:
            interfaces += tuple(
                (h.text or "").strip().rsplit("/", 1)[-1]
                for h in actuator.findall("hardwareInterface")
                if (h.text or "").strip().rsplit("/", 1)[-1] not in interfaces
            )
            red = actuator.find("mechanicalReduction")
            if red is not None:
                try:
                    reduction = float(red.text)
                except (TypeError, ValueError):
                    raise self.error("mechanicalReduction is not a number",
                                     f"{where}.actuator.mechanicalReduction", red.text) from None
                if not math.isfinite(reduction) or reduction == 0:
                    raise self.error("mechanicalReduction must be finite and non-zero",
                                     f"{where}.actuator.mechanicalReduction", reduction)
        if not interfaces:
            raise self.error("needs a <hardwareInterface>", f"{where}.joint", has_value=False)
        ttype = (el.findtext("type") or "transmission_interface/SimpleTransmission").strip()
        return Transmission(name, ttype, jel.get("name"), interfaces,
                            actuator.get("name") if actuator is not None else None, reduction)

    def gazebo(self, root: ET.Element, joints: tuple[Joint, ...]):
        namespace = None
        sensors: list[SensorSpec] = []
        by_name = {j.name: j for j in joints}
        for gz in root.findall("gazebo"):
            for plugin in gz.findall("plugin"):
                filename = plugin.get("filename", "")
                if filename == _CONTROL_PLUGIN:
                    ns = (plugin.findtext("robotNamespace") or "").strip().strip("/")
                    namespace = ns or namespace
                elif filename == _FT_PLUGIN:
                    pname = plugin.get("name") or "ft_sensor"
                    where = f"gazebo.plugin[{pname}]"
                    joint_name = (plugin.findtext("jointName") or "").strip()
                    if joint_name not in by_name:
                        raise self.error("force-torque sensor names a joint that does not exist",
                                         f"{where}.jointName", joint_name)
                    rate_text = (plugin.findtext("updateRate") or "").strip()
                    rate = None
                    if rate_text:
                        try:
                            rate = float(rate_text)
                        except ValueError:
                            raise self.error("updateRate is not a number",
                                             f"{where}.updateRate", rate_text) from None
                        if not math.isfinite(rate) or rate <= 0:
                            raise self.error("updateRate must be a positive number",
                                             f"{where}.updateRate", rate_text)
                    topic = (plugin.findtext("topicName") or "").strip() or None
                    sensors.append(SensorSpec(pname, "force_torque", joint_name,
                                              by_name[joint_name].child, topic, rate))
        return namespace, tuple(sensors)

"""The robot as jointctl sees it: links, joints, limits, transmissions, sensors.

A :class:`RobotModel` is an immutable, validated reading of a URDF. All
quantities are SI: metres, radians, kilograms, kg·m², newtons (or N·m for
revolute joints), N·s/m (or N·m·s/rad) for damping. Poses follow URDF: ``xyz``
in metres and ``rpy`` fixed-axis roll-pitch-yaw in radians, each relative to
the parent link's frame.
"""

from __future__ import annotations

import math

from dataclasses import dataclass, field

from jointctl.model.ros2_control import EFFORT, Ros2ControlComponent, Ros2ControlJoint

Vector3 = tuple[float, float, float]

MOVABLE_JOINT_TYPES = frozenset({"revolute", "continuous", "prismatic"})
JOINT_TYPES = MOVABLE_JOINT_TYPES | {"fixed", "floating", "planar"}


@dataclass(frozen=True)
class Pose:
    """A frame relative to its parent: translation ``xyz`` [m], fixed-axis ``rpy`` [rad]."""

    xyz: Vector3 = (0.0, 0.0, 0.0)
    rpy: Vector3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Inertial:
    """Mass [kg] and inertia tensor [kg·m²] about the centre of mass at ``origin``.

    ``inertia`` is (ixx, iyy, izz, ixy, ixz, iyz), MuJoCo's ``fullinertia`` order.
    """

    mass_kg: float
    origin: Pose
    inertia: tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class Geometry:
    """A primitive or mesh shape.

    ``kind`` is one of box (``size_m`` = full x, y, z lengths), cylinder
    (``radius_m``, ``length_m`` along local z), sphere (``radius_m``) or mesh
    (``mesh_path``, ``scale``).
    """

    kind: str
    size_m: Vector3 | None = None
    radius_m: float | None = None
    length_m: float | None = None
    mesh_path: str | None = None
    scale: Vector3 = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class Shape:
    """A visual or collision shape placed at ``origin`` in its link's frame; ``rgba`` the colour of a
    visual (its URDF ``<material><color rgba>``, 0..1), None when it names none."""

    origin: Pose
    geometry: Geometry
    rgba: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class Link:
    name: str
    inertial: Inertial | None = None
    visuals: tuple[Shape, ...] = ()
    collisions: tuple[Shape, ...] = ()


@dataclass(frozen=True)
class JointLimits:
    """Range of motion and actuator limits of one joint.

    ``lower``/``upper`` in m (prismatic) or rad (revolute), ``None`` when the
    joint is continuous; ``effort`` in N or N·m; ``velocity`` in m/s or rad/s.
    """

    lower: float | None
    upper: float | None
    effort: float
    velocity: float


@dataclass(frozen=True)
class Joint:
    """A URDF joint. ``axis`` is a unit vector in the child link's frame."""

    name: str
    type: str
    parent: str
    child: str
    origin: Pose = Pose()
    axis: Vector3 = (1.0, 0.0, 0.0)
    limits: JointLimits | None = None
    damping: float = 0.0
    friction: float = 0.0
    #: Reflected actuator (rotor) inertia about the axis [kg·m² or kg], from the jointctl
    #: extension ``<dynamics armature="..."/>`` (other URDF tools ignore it).
    armature: float = 0.0

    @property
    def is_locked(self) -> bool:
        """A revolute or prismatic joint whose range is a single value.

        Gazebo needed such "locked" joints where a fixed joint was meant (the
        chapter's force-sensor joint); jointctl treats them as fixed.
        """
        lim = self.limits
        return (
            self.type in ("revolute", "prismatic")
            and lim is not None
            and lim.lower is not None
            and lim.lower == lim.upper
        )

    @property
    def is_movable(self) -> bool:
        """True when the joint has one degree of freedom that moves."""
        return self.type in MOVABLE_JOINT_TYPES and not self.is_locked

    @property
    def is_prismatic(self) -> bool:
        return self.type == "prismatic"

    def range_and_speed(self) -> tuple[float, float, float]:
        """(lower, upper [m or rad], speed limit [m/s or rad/s]) from the URDF's ``<limit>``: a
        continuous joint has no range (±inf), a joint without a ``<limit>`` or with velocity 0 an
        unknown speed limit (inf)."""
        lim = self.limits
        lower = lim.lower if lim is not None and lim.lower is not None else -math.inf
        upper = lim.upper if lim is not None and lim.upper is not None else math.inf
        if self.type == "continuous":
            lower, upper = -math.inf, math.inf
        speed = lim.velocity if lim is not None and lim.velocity > 0 else math.inf
        return float(lower), float(upper), float(speed)


@dataclass(frozen=True)
class Transmission:
    """A ros_control transmission: which joint is actuated through which interface.

    ``hardware_interfaces`` holds the short names (``EffortJointInterface``,
    ``VelocityJointInterface``, ``PositionJointInterface``), with any
    ``hardware_interface/`` prefix removed.

    ``ros2_control`` names the ``<ros2_control>`` component when the transmission is not the URDF's
    own but says that a ros2_control joint with an ``effort`` command interface is driven through
    its effort (what the simulated robot's actuators are built from), None for a ``<transmission>``.
    """

    name: str
    type: str
    joint: str
    hardware_interfaces: tuple[str, ...]
    actuator: str | None = None
    mechanical_reduction: float = 1.0
    ros2_control: str | None = None


@dataclass(frozen=True)
class SensorSpec:
    """A force-torque sensor measuring the wrench across ``joint``.

    The measuring frame is the joint's child link (``link``). ``topic`` and
    ``update_rate_hz`` come from the description (Gazebo's ft_sensor plugin).
    """

    name: str
    kind: str
    joint: str
    link: str
    topic: str | None = None
    update_rate_hz: float | None = None


@dataclass(frozen=True)
class RobotModel:
    """A validated robot description. Joint order is the document order.

    ``ros2_control`` holds the URDF's ``<ros2_control>`` components (ROS 2's hardware description,
    :mod:`jointctl.model.ros2_control`); their effort-commanded joints also appear in ``transmissions``
    (with the component's name in ``Transmission.ros2_control``) unless a ``<transmission>`` already
    drives them.
    """

    name: str
    links: tuple[Link, ...]
    joints: tuple[Joint, ...]
    transmissions: tuple[Transmission, ...] = ()
    sensors: tuple[SensorSpec, ...] = ()
    namespace: str | None = None
    source: str | None = None
    ros2_control: tuple[Ros2ControlComponent, ...] = ()
    _links_by_name: dict[str, Link] = field(init=False, repr=False, compare=False)
    _joints_by_name: dict[str, Joint] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_links_by_name", {lk.name: lk for lk in self.links})
        object.__setattr__(self, "_joints_by_name", {j.name: j for j in self.joints})

    def link(self, name: str) -> Link:
        return self._links_by_name[name]

    def joint(self, name: str) -> Joint:
        return self._joints_by_name[name]

    def has_link(self, name: str) -> bool:
        return name in self._links_by_name

    def has_joint(self, name: str) -> bool:
        return name in self._joints_by_name

    @property
    def root_link(self) -> str:
        children = {j.child for j in self.joints}
        return next(lk.name for lk in self.links if lk.name not in children)

    @property
    def movable_joints(self) -> tuple[Joint, ...]:
        """Joints with one moving degree of freedom, in document order."""
        return tuple(j for j in self.joints if j.is_movable)

    def transmission_for(self, joint_name: str) -> Transmission | None:
        return next((t for t in self.transmissions if t.joint == joint_name), None)

    def child_joints(self, link_name: str) -> tuple[Joint, ...]:
        return tuple(j for j in self.joints if j.parent == link_name)

    def ros2_control_joint(self, joint_name: str) -> tuple[Ros2ControlComponent, Ros2ControlJoint] | None:
        """The ``<ros2_control>`` component listing ``joint_name`` and its entry there, or None."""
        for component in self.ros2_control:
            entry = component.joint(joint_name)
            if entry is not None:
                return component, entry
        return None

    @property
    def initial_positions(self) -> dict[str, float]:
        """The ``initial_value`` of each ros2_control joint's ``position`` state interface [m or rad], by joint
        (where a simulation starts them unless a scenario says otherwise)."""
        return {j.name: j.initial_position for c in self.ros2_control for j in c.joints
                if j.initial_position is not None}

    @property
    def effort_commanded(self) -> tuple[str, ...]:
        """The joints a ``<ros2_control>`` component gives an ``effort`` command interface, in component order."""
        return tuple(j.name for c in self.ros2_control for j in c.joints if EFFORT in j.command_names)

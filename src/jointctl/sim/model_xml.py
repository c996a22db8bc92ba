"""Gazebo model descriptions (the SDF or URDF text ``spawn_model`` sends) as one spawned object.

jointctl spawns single rigid bodies (:class:`~jointctl.sim.objects.ObjectSpec`: a box, cylinder or
sphere with a mass). :func:`parse_model_xml` reads an SDF ``<model>`` with one ``<link>``, or a URDF
``<robot>`` with one ``<link>``, into such an object placed at a pose in the world. Anything it cannot
represent (several links, joints, plugins, sensors, a static model, meshes or any other geometry than
a box, cylinder or sphere, a link without a collision) is refused with :class:`UnsupportedModel`,
whose ``field`` names the element (``sdf/model/joint``); nothing is half-read.

What is read: the collision geometry (its size and pose), the mass, the surface's friction ``mu``.
What is adapted for MuJoCo, each reported in :attr:`SpawnedModel.notes`:

- **Inertia**: the object is a homogeneous solid of its collision shape. A declared inertia that
  differs from that solid's (by more than :data:`INERTIA_RTOL` of its largest moment) is replaced,
  and so is a centre of mass away from the shape's centre. The book's weight declares 0.01 kg·m²
  on every axis for a 10 kg cylinder of radius 0.5 m, whose moments are (0.658, 0.658, 1.25).
- **Friction**: ``mu`` above :data:`FRICTION_MAX` is capped. Measured with MuJoCo's default
  (pyramidal) friction cone, dropping the book's weight from 4 m onto the 1-DOF robot's sensor disk
  (gravity -2, -5 or -9.8 m/s², piston held at -0.2 or -0.5 m): with ``mu`` 1 it stays on in every
  case, up to 2 cm off-centre, and the sensor reads its weight to 0.1 %; with 1.5, 2 or 5 it flips
  off the disk in some of them, and with 10 or the book's 50 it falls through the disk and the floor.
  ``mu2`` (MuJoCo's friction is isotropic), contact ``kp``/``kd`` and the other ODE surface settings
  are not used: MuJoCo's soft contacts are.

The book's ``cylinder`` model writes its geometry as attributes, ``<cylinder length="0.2"
radius="0.5"/>``, where SDF expects ``<radius>`` and ``<length>`` child elements; both forms are read.

Frames: the body sits at the collision geometry's pose. :attr:`SpawnedModel.frame_xyz` and
``frame_quat`` give the model frame in the body frame, so the model's pose (what Gazebo reports in
``model_states``) is the body's pose composed with it.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import mujoco
import numpy as np

from jointctl.errors import ModelError
from jointctl.sim.mjcf_builder import rpy_to_matrix
from jointctl.sim.objects import ObjectSpec, _lowest_extent, solid_inertia

INERTIA_RTOL = 0.05
"""A declared inertia within this fraction of the solid's largest moment counts as the solid's."""
FRICTION_MAX = 1.0
"""Largest sliding friction coefficient passed to MuJoCo (see the module doc)."""
MAX_XML_CHARS = 1_000_000

_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")


class UnsupportedModel(ModelError):
    """A model description jointctl cannot represent as one rigid body; ``field`` names the element."""

    code = "model_xml"


@dataclass(frozen=True)
class SpawnedModel:
    """A parsed model: the object to spawn, where its model frame is, and what was adapted."""

    spec: ObjectSpec
    format: str
    frame_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frame_quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    notes: tuple[str, ...] = ()

    def describe(self) -> str:
        """One line: what was spawned where, then the adaptations."""
        s = self.spec
        if s.shape == "cylinder":
            shape = f"cylinder r {s.size_m[0]:g} m, length {s.size_m[1]:g} m"
        elif s.shape == "box":
            shape = "box " + " x ".join(f"{v:g}" for v in s.size_m) + " m"
        else:
            shape = f"sphere r {s.size_m[0]:g} m"
        where = ", ".join(f"{v:.4g}" for v in s.xyz)
        text = f"{s.name}: {shape}, {s.mass_kg:g} kg, centre at ({where}) m ({self.format})"
        if self.notes:
            text += "; adapted for MuJoCo: " + "; ".join(self.notes)
        return text


def check_model_name(name: object) -> str:
    """A model name usable as a MuJoCo body name; UnsupportedModel otherwise."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise UnsupportedModel("must be letters, digits, '_', '-' or '.' (not empty)", field="model_name",
                               value=name)
    return name


def parse_model_xml(text: str, *, name: str, position=(0.0, 0.0, 0.0), orientation=(1.0, 0.0, 0.0, 0.0),
                    floor: bool = True) -> SpawnedModel:
    """The object an SDF or URDF document describes, its model frame placed at ``position`` [m],
    ``orientation`` (quaternion w, x, y, z; normalised, all zeros meaning none) in the world.
    Raises :class:`UnsupportedModel` naming the element it cannot represent."""
    check_model_name(name)
    root = _parse(text)
    pose = _Pose(_vector(position, "initial_pose.position"), _rotation(orientation))
    if root.tag == "sdf":
        reader = _SdfReader(root)
    elif root.tag == "robot":
        reader = _UrdfReader(root)
    else:
        raise UnsupportedModel("must be an <sdf> or a URDF <robot> document", field=root.tag, value=root.tag)
    for path, element in _walk(root, root.tag):
        if element.tag == "plugin":
            raise UnsupportedModel("plugins cannot run in jointctl", field=path, value=element.get("filename"))
    body = reader.read()
    return _assemble(body, name=name, initial_pose=pose, floor=floor)


# -- the parsed body, before it is placed ---------------------------------------------------------

@dataclass
class _Body:
    format: str
    shape: str
    size: tuple[float, ...]
    mass: float
    model_pose: _Pose  # the document's own model pose (SDF <model><pose>), applied after initial_pose
    link_pose: _Pose  # the collision geometry's pose in the model frame
    inertia: np.ndarray | None  # 3x3 in the collision frame, as declared
    com: np.ndarray | None  # centre of mass in the collision frame, as declared
    friction: float
    notes: list[str]


class _Pose:
    """A rigid transform: position p, rotation matrix R."""

    def __init__(self, p=None, R=None) -> None:
        self.p = np.zeros(3) if p is None else np.asarray(p, dtype=float)
        self.R = np.eye(3) if R is None else np.asarray(R, dtype=float)

    def __mul__(self, other: _Pose) -> _Pose:
        return _Pose(self.p + self.R @ other.p, self.R @ other.R)

    def inverse(self) -> _Pose:
        return _Pose(-self.R.T @ self.p, self.R.T)


def _parse(text: str) -> ET.Element:
    if not isinstance(text, str) or not text.strip():
        raise UnsupportedModel("is empty", field="model_xml")
    if len(text) > MAX_XML_CHARS:
        raise UnsupportedModel(f"is longer than {MAX_XML_CHARS} characters", field="model_xml", value=len(text))
    if "<!DOCTYPE" in text or "<!ENTITY" in text:
        raise UnsupportedModel("document type declarations and entities are not accepted", field="model_xml")
    try:
        return ET.fromstring(text)
    except ET.ParseError as exc:
        raise UnsupportedModel(f"is not well-formed XML ({exc})", field="model_xml") from None


def _walk(element: ET.Element, path: str):
    yield path, element
    for child in element:
        yield from _walk(child, f"{path}/{child.tag}")


def _children(parent: ET.Element, path: str, allowed: set[str], ignored: set[str] = frozenset(),
              why: dict[str, str] | None = None) -> dict[str, list[ET.Element]]:
    """The children of ``parent`` by tag; any tag neither allowed nor ignored is refused."""
    found: dict[str, list[ET.Element]] = {}
    for child in parent:
        if not isinstance(child.tag, str):  # comments, processing instructions
            continue
        if child.tag in ignored:
            continue
        if child.tag not in allowed:
            reason = (why or {}).get(child.tag, "jointctl cannot represent this element")
            raise UnsupportedModel(reason, field=f"{path}/{child.tag}", value=child.get("name", child.tag))
        found.setdefault(child.tag, []).append(child)
    return found


def _one(found: dict[str, list[ET.Element]], tag: str, path: str, what: str, required: bool = True):
    elements = found.get(tag, [])
    if len(elements) > 1:
        raise UnsupportedModel(f"jointctl spawns one rigid body: {what}", field=f"{path}/{tag}[2]",
                               value=elements[1].get("name", tag))
    if not elements:
        if required:
            raise UnsupportedModel(f"is required: {what}", field=f"{path}/{tag}")
        return None
    return elements[0]


def _number(text: str | None, path: str, *, positive: bool = False) -> float:
    try:
        value = float((text or "").strip())
    except ValueError:
        raise UnsupportedModel("must be a number", field=path, value=text) from None
    if not math.isfinite(value) or (positive and value <= 0):
        raise UnsupportedModel("must be a finite positive number" if positive else "must be finite",
                               field=path, value=text)
    return value


def _numbers(text: str | None, count: int, path: str, *, positive: bool = False) -> tuple[float, ...]:
    parts = (text or "").split()
    if len(parts) != count:
        raise UnsupportedModel(f"must be {count} numbers", field=path, value=text)
    return tuple(_number(p, path, positive=positive) for p in parts)


def _vector(values, field: str) -> np.ndarray:
    try:
        array = np.asarray(values, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise UnsupportedModel("must be three numbers", field=field, value=values) from None
    if not np.isfinite(array).all():
        raise UnsupportedModel("must be finite", field=field, value=list(values))
    return array


def _rotation(quat_wxyz) -> np.ndarray:
    try:
        q = np.asarray(quat_wxyz, dtype=float).reshape(4)
    except (TypeError, ValueError):
        raise UnsupportedModel("must be a quaternion", field="initial_pose.orientation", value=quat_wxyz) from None
    if not np.isfinite(q).all():
        raise UnsupportedModel("must be finite", field="initial_pose.orientation", value=list(quat_wxyz))
    norm = float(np.linalg.norm(q))
    if norm < 1e-12:  # a Pose message left at its default: no rotation (Gazebo normalises it so too)
        return np.eye(3)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q / norm)
    return R.reshape(3, 3)


def _matrix_to_quat(R: np.ndarray) -> tuple[float, float, float, float]:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R).ravel())
    return tuple(float(v) for v in q)


def _matrix_to_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """Roll-pitch-yaw (R = Rz(y) Ry(p) Rx(r)) of a rotation matrix [rad]."""
    pitch = -math.asin(max(-1.0, min(1.0, float(R[2, 0]))))
    if abs(R[2, 0]) < 1 - 1e-12:
        roll = math.atan2(float(R[2, 1]), float(R[2, 2]))
        yaw = math.atan2(float(R[1, 0]), float(R[0, 0]))
    else:  # gimbal lock: put it all in yaw
        roll = 0.0
        yaw = math.atan2(-float(R[0, 1]), float(R[1, 1]))
    return (roll, pitch, yaw)


def _fmt(values) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in values) + ")"


# -- SDF --------------------------------------------------------------------------------------------

_SDF_WHY = {
    "joint": "jointctl spawns one rigid body; a joint cannot be represented",
    "plugin": "plugins cannot run in jointctl",
    "include": "jointctl does not resolve included models",
    "model": "jointctl spawns one rigid body; nested models cannot be represented",
    "world": "jointctl spawns models, not worlds",
    "sensor": "jointctl's spawned objects carry no sensors",
    "static": "jointctl's spawned objects are free bodies",
    "frame": "named frames are not supported",
}


class _SdfReader:
    def __init__(self, root: ET.Element) -> None:
        self.root = root
        self.notes: list[str] = []

    def pose(self, parent: ET.Element, path: str) -> _Pose:
        element = parent.find("pose")
        if element is None:
            return _Pose()
        for attribute in ("relative_to", "frame"):
            if element.get(attribute):
                raise UnsupportedModel("poses relative to named frames are not supported",
                                       field=f"{path}/pose@{attribute}", value=element.get(attribute))
        values = _numbers(element.text or "0 0 0 0 0 0", 6, f"{path}/pose")
        return _Pose(values[:3], rpy_to_matrix(values[3:]))

    def read(self) -> _Body:
        version = self.root.get("version", "?")
        found = _children(self.root, "sdf", {"model"}, why=_SDF_WHY)
        model = _one(found, "model", "sdf", "one <model> per document")
        path = "sdf/model"
        found = _children(model, path, {"pose", "link", "static"},
                          ignored={"allow_auto_disable", "self_collide", "enable_wind"}, why=_SDF_WHY)
        static = _one(found, "static", path, "", required=False)
        if static is not None and (static.text or "").strip().lower() in ("1", "true"):
            raise UnsupportedModel(_SDF_WHY["static"] + "; a static model cannot be represented",
                                   field=f"{path}/static", value=static.text)
        model_pose = self.pose(model, path)  # applied after initial_pose, as Gazebo does
        link = _one(found, "link", path, "a model with several links cannot be represented")
        path = f"{path}/link"
        found = _children(link, path, {"pose", "inertial", "collision", "gravity", "kinematic", "velocity_decay"},
                          ignored={"visual", "self_collide", "must_be_base_link", "enable_wind"}, why=_SDF_WHY)
        for tag, bad, why in (("gravity", ("0", "false"), "jointctl's spawned objects always feel gravity"),
                              ("kinematic", ("1", "true"), "kinematic links cannot be represented")):
            element = _one(found, tag, path, "", required=False)
            if element is not None and (element.text or "").strip().lower() in bad:
                raise UnsupportedModel(why, field=f"{path}/{tag}", value=element.text)
        if _one(found, "velocity_decay", path, "", required=False) is not None:
            self.notes.append("velocity_decay not used")
        link_pose = self.pose(link, path)
        collision = _one(found, "collision", path, "one collision shape per link")
        cpath = f"{path}/collision"
        cfound = _children(collision, cpath, {"pose", "geometry", "surface"},
                           ignored={"max_contacts", "laser_retro"}, why=_SDF_WHY)
        collision_pose = link_pose * self.pose(collision, cpath)
        shape, size = self.geometry(_one(cfound, "geometry", cpath, "the collision's shape"), f"{cpath}/geometry")
        friction = self.surface(_one(cfound, "surface", cpath, "", required=False), f"{cpath}/surface")
        inertia, com, mass = None, None, 1.0
        inertial = _one(found, "inertial", path, "", required=False)
        if inertial is None:
            self.notes.append("no <inertial>: SDF's default mass of 1 kg")
        else:
            ipath = f"{path}/inertial"
            ifound = _children(inertial, ipath, {"pose", "mass", "inertia"}, why=_SDF_WHY)
            mass_element = _one(ifound, "mass", ipath, "", required=False)
            if mass_element is None:
                self.notes.append("no <mass>: SDF's default of 1 kg")
            else:
                mass = _number(mass_element.text, f"{ipath}/mass", positive=True)
            # The inertial frame in the collision frame.
            frame = collision_pose.inverse() * link_pose * self.pose(inertial, ipath)
            com = frame.p
            tensor = np.eye(3)  # SDF's defaults: ixx = iyy = izz = 1, no products
            element = _one(ifound, "inertia", ipath, "", required=False)
            if element is not None:
                tensor = _tensor({k: _sdf_value(element, k, f"{ipath}/inertia") for k in _INERTIA_KEYS})
            inertia = frame.R @ tensor @ frame.R.T
        return _Body(f"SDF {version}", shape, size, mass, model_pose, collision_pose, inertia, com, friction,
                     self.notes)

    def geometry(self, geometry: ET.Element, path: str) -> tuple[str, tuple[float, ...]]:
        shapes = [c for c in geometry if isinstance(c.tag, str)]
        if len(shapes) != 1:
            raise UnsupportedModel("needs exactly one shape", field=path, value=[c.tag for c in shapes])
        shape = shapes[0]
        spath = f"{path}/{shape.tag}"
        keys = {"box": ("size",), "cylinder": ("radius", "length"), "sphere": ("radius",)}.get(shape.tag)
        if keys is None:
            raise UnsupportedModel("jointctl's objects are boxes, cylinders or spheres", field=spath,
                                   value=shape.tag)
        _children(shape, spath, set(keys))
        values, from_attributes = [], []
        for key in keys:
            element = shape.find(key)
            if element is not None:
                text = element.text
            elif shape.get(key) is not None:
                text = shape.get(key)
                from_attributes.append(key)
            else:
                raise UnsupportedModel("is required", field=f"{spath}/{key}")
            values += _numbers(text, 3 if key == "size" else 1, f"{spath}/{key}", positive=True)
        if from_attributes:
            self.notes.append(f"<{shape.tag}> {' and '.join(from_attributes)} read from attributes "
                              f"(SDF expects child elements)")
        return shape.tag, tuple(values)

    def surface(self, surface: ET.Element | None, path: str) -> float:
        if surface is None:
            return 1.0  # SDF's default ODE mu
        mu = _find_number(surface, "friction/ode/mu", path)
        mu2 = _find_number(surface, "friction/ode/mu2", path)
        if mu is None:
            mu = 1.0
        if mu2 is not None and mu2 != mu:
            self.notes.append(f"mu2 {mu2:g} not used (MuJoCo's friction is isotropic)")
        unused = [c.tag for c in surface.findall("contact/ode/*")] + [c.tag for c in surface.findall("bounce/*")]
        if unused:
            self.notes.append(f"surface {', '.join(unused)} not used (MuJoCo's soft contacts)")
        return mu


_INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
_SDF_INERTIA_DEFAULTS = {"ixx": 1.0, "iyy": 1.0, "izz": 1.0, "ixy": 0.0, "ixz": 0.0, "iyz": 0.0}


def _sdf_value(inertia: ET.Element, key: str, path: str) -> float:
    element = inertia.find(key)
    if element is None:
        return _SDF_INERTIA_DEFAULTS[key]
    return _number(element.text, f"{path}/{key}")


def _find_number(parent: ET.Element, relative: str, path: str) -> float | None:
    element = parent.find(relative)
    return None if element is None else _number(element.text, f"{path}/{relative}")


def _tensor(v: dict[str, float]) -> np.ndarray:
    return np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]],
                     [v["ixz"], v["iyz"], v["izz"]]])


# -- URDF -------------------------------------------------------------------------------------------

_URDF_WHY = {
    "joint": "jointctl spawns one rigid body; a joint cannot be represented",
    "transmission": "jointctl's spawned objects have no actuators",
    "plugin": "plugins cannot run in jointctl",
    "sensor": "jointctl's spawned objects carry no sensors",
}
_URDF_GAZEBO_USED = {"mu1", "mu2"}
_URDF_GAZEBO_UNUSED = {"kp", "kd", "maxVel", "minDepth", "maxContacts"}
_URDF_GAZEBO_IGNORED = {"material", "selfCollide"}


class _UrdfReader:
    def __init__(self, root: ET.Element) -> None:
        self.root = root
        self.notes: list[str] = []

    def origin(self, parent: ET.Element, path: str) -> _Pose:
        element = parent.find("origin")
        if element is None:
            return _Pose()
        xyz = _numbers(element.get("xyz", "0 0 0"), 3, f"{path}/origin@xyz")
        rpy = _numbers(element.get("rpy", "0 0 0"), 3, f"{path}/origin@rpy")
        return _Pose(xyz, rpy_to_matrix(rpy))

    def read(self) -> _Body:
        found = _children(self.root, "robot", {"link", "gazebo"}, ignored={"material"}, why=_URDF_WHY)
        link = _one(found, "link", "robot", "a robot with several links cannot be represented")
        path = "robot/link"
        lfound = _children(link, path, {"inertial", "collision"}, ignored={"visual"}, why=_URDF_WHY)
        collision = _one(lfound, "collision", path, "one collision shape per link")
        cpath = f"{path}/collision"
        cfound = _children(collision, cpath, {"origin", "geometry"}, why=_URDF_WHY)
        collision_pose = self.origin(collision, cpath)
        shape, size = self.geometry(_one(cfound, "geometry", cpath, "the collision's shape"), f"{cpath}/geometry")
        inertial = _one(lfound, "inertial", path, "a link without <inertial> has no mass")
        ipath = f"{path}/inertial"
        ifound = _children(inertial, ipath, {"origin", "mass", "inertia"}, why=_URDF_WHY)
        mass = _number(_one(ifound, "mass", ipath, "the link's mass").get("value"), f"{ipath}/mass@value",
                       positive=True)
        frame = collision_pose.inverse() * self.origin(inertial, ipath)
        element = _one(ifound, "inertia", ipath, "the link's inertia")
        tensor = _tensor({k: _number(element.get(k, "0"), f"{ipath}/inertia@{k}") for k in _INERTIA_KEYS})
        friction = self.gazebo(found.get("gazebo", []), link.get("name"))
        return _Body("URDF", shape, size, mass, _Pose(), collision_pose, frame.R @ tensor @ frame.R.T, frame.p,
                     friction, self.notes)

    def geometry(self, geometry: ET.Element, path: str) -> tuple[str, tuple[float, ...]]:
        shapes = [c for c in geometry if isinstance(c.tag, str)]
        if len(shapes) != 1:
            raise UnsupportedModel("needs exactly one shape", field=path, value=[c.tag for c in shapes])
        shape = shapes[0]
        spath = f"{path}/{shape.tag}"
        if shape.tag == "box":
            return "box", _numbers(shape.get("size"), 3, f"{spath}@size", positive=True)
        if shape.tag == "cylinder":
            return "cylinder", (_number(shape.get("radius"), f"{spath}@radius", positive=True),
                                _number(shape.get("length"), f"{spath}@length", positive=True))
        if shape.tag == "sphere":
            return "sphere", (_number(shape.get("radius"), f"{spath}@radius", positive=True),)
        raise UnsupportedModel("jointctl's objects are boxes, cylinders or spheres", field=spath, value=shape.tag)

    def gazebo(self, elements: list[ET.Element], link: str | None) -> float:
        mu, mu2, unused = 1.0, None, []
        for k, element in enumerate(elements):
            path = "robot/gazebo" + (f"[{k + 1}]" if len(elements) > 1 else "")
            reference = element.get("reference")
            if reference is not None and reference != link:
                raise UnsupportedModel("refers to something the model does not have", field=f"{path}@reference",
                                       value=reference)
            found = _children(element, path, _URDF_GAZEBO_USED | _URDF_GAZEBO_UNUSED,
                              ignored=_URDF_GAZEBO_IGNORED, why=_URDF_WHY)
            if "mu1" in found:
                mu = _number(found["mu1"][0].text, f"{path}/mu1")
            if "mu2" in found:
                mu2 = _number(found["mu2"][0].text, f"{path}/mu2")
            unused += [tag for tag in found if tag in _URDF_GAZEBO_UNUSED]
        if mu2 is not None and mu2 != mu:
            self.notes.append(f"mu2 {mu2:g} not used (MuJoCo's friction is isotropic)")
        if unused:
            self.notes.append(f"gazebo {', '.join(unused)} not used (MuJoCo's soft contacts)")
        return mu


# -- placing the body -------------------------------------------------------------------------------

def _assemble(body: _Body, *, name: str, initial_pose: _Pose, floor: bool) -> SpawnedModel:
    notes = body.notes
    solid = np.diag(solid_inertia(body.shape, body.size, body.mass))
    if body.inertia is not None and not np.allclose(body.inertia, solid, rtol=0.0,
                                                    atol=INERTIA_RTOL * float(solid.max())):
        declared = body.inertia
        shown = (_fmt(np.diag(declared)) if np.allclose(declared, np.diag(np.diag(declared)))
                 else f"{_fmt(declared.ravel())} (full tensor)")
        notes.insert(0, f"inertia {shown} kg m^2 is not a {body.mass:g} kg solid {body.shape}'s: "
                        f"{_fmt(np.diag(solid))} used")
    if body.com is not None and float(np.linalg.norm(body.com)) > 1e-9:
        notes.append(f"centre of mass {_fmt(body.com)} m off the shape's centre: taken at the centre")
    friction = body.friction
    if not friction > 0:
        raise UnsupportedModel("friction mu must be positive", field="mu", value=friction)
    if friction > FRICTION_MAX:
        notes.append(f"friction mu {friction:g} capped at {FRICTION_MAX:g} (MuJoCo's pyramidal friction cone)")
        friction = FRICTION_MAX
    placed = initial_pose * body.model_pose * body.link_pose
    spec = ObjectSpec(
        name=name, shape=body.shape, size_m=tuple(float(v) for v in body.size), mass_kg=float(body.mass),
        xyz=tuple(float(v) for v in placed.p), rpy=_matrix_to_rpy(placed.R), inertia=None, friction=friction,
    )
    if floor and spec.xyz[2] - _lowest_extent(spec) < 0:
        raise UnsupportedModel("the model would start below the ground (z = 0)", field="initial_pose.position",
                               value=list(spec.xyz))
    frame = body.link_pose.inverse()
    return SpawnedModel(spec, body.format, tuple(float(v) for v in frame.p), _matrix_to_quat(frame.R), tuple(notes))


__all__ = ["FRICTION_MAX", "INERTIA_RTOL", "SpawnedModel", "UnsupportedModel",
           "check_model_name", "parse_model_xml"]

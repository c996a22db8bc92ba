"""The simulated robot of a run: the robot's model with what a real robot leaves uncertain changed.

A scenario's ``model.LINK.FIELD`` and ``model.JOINT.FIELD`` set a link's mass or inertia or a joint's damping,
friction or armature; its ``payload_kg`` adds a point mass at the payload link's origin (the tool or sensor
frame). The result is a new :class:`~jointctl.model.robot_model.RobotModel` the session simulates (its
``plant``): the controllers keep the nominal model, as on a real robot whose model is an estimate.

Errors name ``source`` (the scenario file, or ``--vary``), the field as the user writes it and the value.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from jointctl.control.params import unknown_field_message
from jointctl.errors import ConfigError
from jointctl.model.mjcf import rpy_to_matrix
from jointctl.model.robot_model import Inertial, Pose, RobotModel

#: A link's fields: mass [kg] and its inertia tensor's entries [kg·m²] (in the URDF's inertial frame).
LINK_FIELDS = ("mass", "ixx", "iyy", "izz", "ixy", "ixz", "iyz")
#: A joint's fields: damping [N·s/m or N·m·s/rad], Coulomb friction [N or N·m], armature [kg or kg·m²].
JOINT_FIELDS = ("damping", "friction", "armature")
_INERTIA_INDEX = {name: k for k, name in enumerate(("ixx", "iyy", "izz", "ixy", "ixz", "iyz"))}
#: The robot.yaml field naming the link that carries ``payload_kg``.
PAYLOAD_LINK = "payload_link"
#: The scenario's field of the payload [kg], and the prefix of its model fields (``model.NAME.FIELD``).
PAYLOAD = "payload_kg"
MODEL_PREFIX = "model."


def model_target(robot: RobotModel, field: str, source: str | None = "--vary") -> tuple[str, str, str]:
    """``model.NAME.FIELD`` -> (``"link"`` or ``"joint"``, NAME, FIELD); ConfigError with the nearest
    known name when the robot has no such link or joint, or it no such field."""
    parts = field.split(".")
    if len(parts) != 3:
        raise ConfigError("is model.LINK.FIELD or model.JOINT.FIELD", source=source, field=field)
    _, name, attribute = parts
    is_link, is_joint = robot.has_link(name), robot.has_joint(name)
    if not (is_link or is_joint):
        names = [lk.name for lk in robot.links] + [j.name for j in robot.joints]
        message = unknown_field_message(name, names).replace("unknown field", f"the robot {robot.name} has no such "
                                                             "link or joint")
        raise ConfigError(message, source=source, field=field, value=name)
    if is_joint and attribute in JOINT_FIELDS:
        return "joint", name, attribute
    if is_link and attribute in LINK_FIELDS:
        return "link", name, attribute
    known = (LINK_FIELDS if is_link else ()) + (JOINT_FIELDS if is_joint else ())
    raise ConfigError(unknown_field_message(attribute, known), source=source, field=field, value=attribute)


def check_model_value(field: str, attribute: str, value, source: str | None = "--vary") -> float:
    """The value of a model field as a float; ConfigError unless finite and allowed (a mass positive, a
    diagonal inertia entry, a damping, friction or armature 0 or more)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError("must be a finite number", source=source, field=field, value=value)
    value = float(value)
    if attribute == "mass" and not value > 0:
        raise ConfigError("a mass must be positive [kg]", source=source, field=field, value=value)
    if attribute in ("ixx", "iyy", "izz", *JOINT_FIELDS) and value < 0:
        raise ConfigError("must not be negative", source=source, field=field, value=value)
    return value


def check_payload(value, source: str | None = "--vary") -> float:
    """``payload_kg`` as a float: 0 or more."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise ConfigError("must be a mass, 0 or more [kg]", source=source, field=PAYLOAD, value=value)
    return float(value)


def payload_link(robot: RobotModel, extras: Mapping | None = None, source: str | None = None) -> str:
    """The link carrying ``payload_kg``: robot.yaml's ``payload_link``, else the description's last link."""
    named = (extras or {}).get(PAYLOAD_LINK)
    if named is None:
        return robot.links[-1].name
    if not isinstance(named, str) or not robot.has_link(named):
        raise ConfigError(unknown_field_message(str(named), [lk.name for lk in robot.links]).replace(
            "unknown field", "names no link of the robot"), source=source, field=PAYLOAD_LINK, value=named)
    return named


def varied_plant(robot: RobotModel, changes: Mapping[str, float], payload_kg: float = 0.0,
                 payload_at: str | None = None, source: str | None = "--vary") -> RobotModel:
    """``robot`` with ``changes`` (``model.NAME.FIELD`` -> value, checked) applied and ``payload_kg`` added as a
    point mass at the origin of link ``payload_at`` (needed when ``payload_kg`` is not 0); errors name ``source``."""
    links = {lk.name: lk for lk in robot.links}
    joints = {j.name: j for j in robot.joints}
    # Masses first: a mass scales its link's inertia; an inertia entry given beside it is then set as given.
    ordered = sorted(changes.items(), key=lambda item: item[0].rsplit(".", 1)[-1] != "mass")
    for field, value in ordered:
        kind, name, attribute = model_target(robot, field, source)
        value = check_model_value(field, attribute, value, source)
        if kind == "joint":
            joints[name] = dataclasses.replace(joints[name], **{attribute: value})
            continue
        link = links[name]
        inertial = link.inertial or Inertial(0.0, Pose(), (0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        if attribute == "mass":
            scale = value / inertial.mass_kg if inertial.mass_kg > 0 else 1.0
            inertial = dataclasses.replace(inertial, mass_kg=value,
                                           inertia=tuple(scale * i for i in inertial.inertia))
        else:
            tensor = list(inertial.inertia)
            tensor[_INERTIA_INDEX[attribute]] = value
            inertial = dataclasses.replace(inertial, inertia=tuple(tensor))
        links[name] = dataclasses.replace(link, inertial=inertial)
    if payload_kg:
        if payload_at is None:
            raise ConfigError("a payload needs the link that carries it", field=PAYLOAD_LINK)
        links[payload_at] = dataclasses.replace(
            links[payload_at], inertial=with_point_mass(links[payload_at].inertial, check_payload(payload_kg, source)))
    return dataclasses.replace(robot, links=tuple(links[lk.name] for lk in robot.links),
                               joints=tuple(joints[j.name] for j in robot.joints))


def with_point_mass(inertial: Inertial | None, mass_kg: float) -> Inertial:
    """``inertial`` and a point mass of ``mass_kg`` at the link's origin, as one body: the masses add, the
    centre of mass moves to their mean, and the inertia about it follows by the parallel-axis theorem
    (expressed in the link's frame)."""
    if inertial is None or inertial.mass_kg <= 0:
        # A point mass alone has no rotational inertia; MuJoCo needs some: a 1 cm solid sphere's.
        i = 0.4 * mass_kg * 0.01**2
        return Inertial(mass_kg, Pose(), (i, i, i, 0.0, 0.0, 0.0))
    m1 = inertial.mass_kg
    total = m1 + mass_kg
    c1 = np.array(inertial.origin.xyz, dtype=float)
    centre = m1 * c1 / total  # the point mass sits at the origin
    ixx, iyy, izz, ixy, ixz, iyz = inertial.inertia
    rotation = rpy_to_matrix(inertial.origin.rpy)
    tensor = rotation @ np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]) @ rotation.T

    def shift(mass: float, d: np.ndarray) -> np.ndarray:
        return mass * (float(d @ d) * np.eye(3) - np.outer(d, d))

    tensor = tensor + shift(m1, c1 - centre) + shift(mass_kg, -centre)
    return Inertial(total, Pose(tuple(float(c) for c in centre), (0.0, 0.0, 0.0)),
                    (float(tensor[0, 0]), float(tensor[1, 1]), float(tensor[2, 2]),
                     float(tensor[0, 1]), float(tensor[0, 2]), float(tensor[1, 2])))


__all__ = ["JOINT_FIELDS", "LINK_FIELDS", "MODEL_PREFIX", "PAYLOAD", "PAYLOAD_LINK", "check_model_value",
           "check_payload", "model_target", "payload_link", "varied_plant", "with_point_mass"]

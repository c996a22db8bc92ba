"""The channels of ``run.mcap`` and of the live Foxglove stream, and their messages as bytes.

One set of channels serves both the file (:mod:`jointctl.recording.mcap_record`) and the live
WebSocket stream (:mod:`jointctl.recording.foxglove_live`). ``/joint_states`` is ROS 2's
``sensor_msgs/msg/JointState`` as a ROS 2 bag holds it (CDR messages, a ``ros2msg`` schema:
:mod:`jointctl.wire.ros2_cdr`), which rclpy reads and PlotJuggler names by joint; every other
channel is JSON-encoded with a JSON schema: Foxglove recognises its own schemas by name
(``foxglove.JointStates`` ...), PlotJuggler reads JSON channels field by field, and anyone can read them
with the ``mcap`` package and ``json``.

Channels (``time`` is loop time; messages are stamped with it, in the file from zero, live from the
wall-clock time at loop time zero):

============================  ==========================  =======================================================
topic                         schema                      what
============================  ==========================  =======================================================
``/robot_description``        ``std_msgs/String``         the URDF text (xacro expanded) in ``data``; Foxglove's 3D
                                                          panel draws it (one message, first)
``/joint_states``             ``sensor_msgs/msg/          ROS 2's joint state (CDR): ``header.stamp`` the time,
                              JointState``                ``frame_id`` empty, ``name``, ``position`` [m or rad],
                                                          ``velocity`` [m/s or rad/s], ``effort`` [N or N·m]
``/jointctl/joint_states``    ``foxglove.JointStates``    the same as Foxglove's own schema: each joint's
                                                          position, velocity and effort, every recorded cycle
``/jointctl/references``      ``foxglove.JointStates``    each joint's reference: ``position`` for a position
                                                          controller, ``velocity`` for a velocity controller
``/jointctl/joints``          ``jointctl.Joints``         the same by joint name with the unit in the field name:
                                                          ``{joint: {reference_m, position_m, velocity_m_s,
                                                          effort_N}}`` (``_rad``, ``_rad_s``, ``_Nm`` for
                                                          revolute joints); what PlotJuggler shows by name
``/jointctl/wrenches``        ``jointctl.Wrenches``       each force-torque sensor's ``force_x_N`` ... ``torque_z_Nm``
                                                          in its link's frame (``frame_id``), every recorded cycle
``/tf``                       ``foxglove.FrameTransforms``  every URDF joint's parent -> child link transform
                                                          (position [m], quaternion), from the robot's own
                                                          kinematics at the recorded joint positions; ``world`` is
                                                          the frame of the URDF's root link
``/jointctl/objects``         ``foxglove.SceneUpdate``    the spawned objects (shape, size [m], pose in ``world``,
                                                          a label), removed ones deleted
``/jointctl/events``          ``foxglove.Log``            spawns, removals, trajectory goals starting and ending,
                                                          controller failures: one line each
============================  ==========================  =======================================================

The per-cycle channels (both joint states, references, joints, wrenches) carry one message per row of
``trace.csv``; ``/tf`` and ``/jointctl/objects`` at most :data:`SCENE_RATE_HZ`. Non-finite values (a
joint no controller commands has no reference) are ``null``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from operator import itemgetter
from typing import Any

import numpy as np

from jointctl.model.dynamics import RobotDynamics
from jointctl.model.robot_model import RobotModel
from jointctl.wire import ros2_cdr

#: Topics, in the order their channels are made.
ROBOT_DESCRIPTION = "/robot_description"
#: ROS 2's ``sensor_msgs/msg/JointState`` (CDR), where ROS 2 robots publish their joint states.
ROS_JOINT_STATES = "/joint_states"
#: The joint states as ``foxglove.JointStates`` (JSON).
JOINT_STATES = "/jointctl/joint_states"
REFERENCES = "/jointctl/references"
JOINTS = "/jointctl/joints"
WRENCHES = "/jointctl/wrenches"
TF = "/tf"
OBJECTS = "/jointctl/objects"
EVENTS = "/jointctl/events"
#: The channels with one message per recorded cycle (per row of trace.csv).
PER_CYCLE = (ROS_JOINT_STATES, JOINT_STATES, REFERENCES, JOINTS, WRENCHES)
#: Highest rate of the 3D scene's channels (``/tf``, ``/jointctl/objects``) [Hz of loop time].
SCENE_RATE_HZ = 100.0
#: The frame everything is drawn in: the URDF's root link's (the simulated world's).
WORLD_FRAME = "world"
#: foxglove.Log levels.
INFO, WARNING, ERROR = 2, 3, 4
#: Colour of the spawned objects and of their labels (RGBA, 0..1), as in rviz's markers.
OBJECT_COLOR = (0.95, 0.55, 0.1, 1.0)
LABEL_COLOR = (1.0, 1.0, 1.0, 1.0)
LABEL_SIZE_M = 0.1
WRENCH_AXES = ("force_x_N", "force_y_N", "force_z_N", "torque_x_Nm", "torque_y_Nm", "torque_z_Nm")
#: What the unit suffixes of jointctl's field names mean (channel metadata).
UNIT_SUFFIXES = "_m: m, _rad: rad, _m_s: m/s, _rad_s: rad/s, _N: N, _Nm: N·m; time: loop time [s]"
#: The QoS a ROS 2 bag says ``/joint_states`` was offered with (channel metadata ``offered_qos_profiles``, in
#: rosbag2's YAML as ROS 2 Jazzy writes it): rclcpp's default, keep the last 10, reliable, volatile; deadline,
#: lifespan and lease unspecified (0: the middleware's default). ``ros2 bag play`` publishes with it.
JOINT_STATES_QOS = """\
- history: keep_last
  depth: 10
  reliability: reliable
  durability: volatile
  deadline:
    sec: 0
    nsec: 0
  lifespan:
    sec: 0
    nsec: 0
  liveliness: automatic
  liveliness_lease_duration:
    sec: 0
    nsec: 0
  avoid_ros_namespace_conventions: false
"""


# -- JSON schemas ---------------------------------------------------------------------------------------
def _number(description: str | None = None) -> dict:
    return {"type": "number", **({"description": description} if description else {})}


def _object(title: str | None, properties: dict, description: str | None = None) -> dict:
    schema: dict[str, Any] = {"type": "object", "properties": properties}
    if title:
        schema["title"] = title
    if description:
        schema["description"] = description
    return schema


_TIME = _object(None, {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0}},
                "loop time as seconds and nanoseconds")
_VECTOR3 = _object(None, {"x": _number(), "y": _number(), "z": _number()})
_QUATERNION = _object(None, {"x": _number(), "y": _number(), "z": _number(), "w": _number()})
_POSE = _object(None, {"position": _VECTOR3, "orientation": _QUATERNION})
_COLOR = _object(None, {"r": _number(), "g": _number(), "b": _number(), "a": _number()})


def _array(items: dict) -> dict:
    return {"type": "array", "items": items}


_JOINT_STATES = _object("foxglove.JointStates", {
    "timestamp": _TIME,
    "joints": _array(_object(None, {
        "name": {"type": "string"},
        "position": _number("m for prismatic joints, rad for revolute joints"),
        "velocity": _number("m/s or rad/s"),
        "acceleration": _number("m/s² or rad/s²"),
        "effort": _number("N or N·m"),
    })),
})
_PRIMITIVE = {"pose": _POSE, "size": _VECTOR3, "color": _COLOR}
_SCENE_UPDATE = _object("foxglove.SceneUpdate", {
    "deletions": _array(_object(None, {"timestamp": _TIME, "type": {"type": "integer", "enum": [0, 1]},
                                       "id": {"type": "string"}})),
    "entities": _array(_object(None, {
        "timestamp": _TIME, "frame_id": {"type": "string"}, "id": {"type": "string"},
        "lifetime": _TIME, "frame_locked": {"type": "boolean"},
        "metadata": _array(_object(None, {"key": {"type": "string"}, "value": {"type": "string"}})),
        "arrows": _array({"type": "object"}), "lines": _array({"type": "object"}),
        "triangles": _array({"type": "object"}), "models": _array({"type": "object"}),
        "cubes": _array(_object(None, _PRIMITIVE)), "spheres": _array(_object(None, _PRIMITIVE)),
        "cylinders": _array(_object(None, {**_PRIMITIVE, "bottom_scale": _number(), "top_scale": _number()})),
        "texts": _array(_object(None, {"pose": _POSE, "billboard": {"type": "boolean"}, "font_size": _number(),
                                       "scale_invariant": {"type": "boolean"}, "color": _COLOR,
                                       "text": {"type": "string"}})),
    })),
})
_FRAME_TRANSFORMS = _object("foxglove.FrameTransforms", {"transforms": _array(_object(None, {
    "timestamp": _TIME, "parent_frame_id": {"type": "string"}, "child_frame_id": {"type": "string"},
    "translation": _VECTOR3, "rotation": _QUATERNION}))})
_LOG = _object("foxglove.Log", {
    "timestamp": _TIME, "level": {"type": "integer", "enum": [0, 1, 2, 3, 4, 5]}, "message": {"type": "string"},
    "name": {"type": "string"}, "file": {"type": "string"}, "line": {"type": "integer", "minimum": 0}})
_STRING = _object("std_msgs/String", {"data": {"type": "string"}})


# -- units of each joint --------------------------------------------------------------------------------
@dataclass(frozen=True)
class JointUnits:
    """The unit suffixes of one joint's fields: position, velocity and effort, and the reference's
    (the quantity its controller compares with: ``position`` or ``velocity``)."""

    position: str
    velocity: str
    effort: str
    reference_kind: str

    @property
    def reference(self) -> str:
        return self.position if self.reference_kind == "position" else self.velocity


def joint_units(robot: RobotModel, joint: str, reference_kind: str = "position") -> JointUnits:
    """SI units of ``joint``: m, m/s and N for a prismatic joint, rad, rad/s and N·m otherwise."""
    if robot.joint(joint).type == "prismatic":
        return JointUnits("m", "m_s", "N", reference_kind)
    return JointUnits("rad", "rad_s", "Nm", reference_kind)


def reference_kinds(manager, joint_names: Sequence[str]) -> list[str]:
    """Per joint, what its reference is (``position`` or ``velocity``): the ``controlled`` quantity of the
    active controller that commands it, else ``position``."""
    kinds = ["position"] * len(joint_names)
    for controller in manager.active:
        index, kind = getattr(controller, "index", None), getattr(controller, "controlled", None)
        if isinstance(index, int) and 0 <= index < len(kinds) and kind in ("position", "velocity"):
            kinds[index] = kind
    return kinds


# -- stamps ---------------------------------------------------------------------------------------------
def decimation(rate_hz: float, period_s: float) -> int:
    """Every how many periods of ``period_s`` [s] to send so that the rate stays at most ``rate_hz``."""
    return max(1, math.ceil(1.0 / (rate_hz * period_s) - 1e-9))


def nanoseconds(time_s: float, origin_ns: int = 0) -> int:
    """``origin_ns`` plus ``time_s`` seconds, in whole nanoseconds."""
    return origin_ns + round(time_s * 1e9)


def stamp(ns: int) -> dict[str, int]:
    """foxglove's Timestamp: whole seconds and nanoseconds."""
    sec, nsec = divmod(ns, 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


#: How numbers are written: ten significant digits, as trace.csv writes them (the same values).
NUMBER = "%.10g"


def _number_text(value: float) -> str:
    """A number as JSON text: :data:`NUMBER`, or ``null`` when it is not finite."""
    return NUMBER % value if value - value == 0 else "null"


def _templates(template: str) -> tuple[str, str]:
    """``template``'s numbers (``%r``) written with :data:`NUMBER` (fast, every value finite) and as
    strings (``%s``, for values passed through :func:`_number_text`)."""
    def placeholder(kind: str) -> str:
        return re.sub(r"%%|%r", lambda m: m.group(0) if m.group(0) == "%%" else kind, template)

    return placeholder(NUMBER), placeholder("%s")


def _getter(indices: Sequence[int]):
    """A function of a row giving the values at ``indices`` as a tuple (itemgetter's, also for one)."""
    if len(indices) == 1:
        index = indices[0]
        return lambda row: (row[index],)
    return itemgetter(*indices) if indices else (lambda row: ())


def _name(text: str) -> str:
    """A JSON string literal, safe inside a %-template."""
    return json.dumps(text).replace("%", "%%")


# -- the channels and the per-cycle messages ------------------------------------------------------------
@dataclass(frozen=True)
class SchemaText:
    """A schema given as text: its ``name``, its ``encoding`` (``ros2msg``) and the ``text``."""

    name: str
    encoding: str
    text: str


@dataclass(frozen=True)
class ChannelSpec:
    """A channel: its topic, its schema (a JSON schema as a dict, or a :class:`SchemaText`), its metadata
    and its messages' encoding."""

    topic: str
    schema: dict | SchemaText
    metadata: dict[str, str]
    message_encoding: str = "json"


#: The schema of :data:`ROS_JOINT_STATES`.
ROS_JOINT_STATE_SCHEMA = SchemaText(ros2_cdr.JOINT_STATE, ros2_cdr.SCHEMA_ENCODING, ros2_cdr.JOINT_STATE_DEFINITION)


class RecordFormat:
    """The channels of one robot and the encoding of its per-cycle rows.

    A row is what ``trace.csv`` holds, in its column order: loop time [s], then per joint (``joint_names``
    order) the reference, the position, the velocity, the effort, then six wrench components per sensor
    (``sensor_names``), in SI units. ``kinds`` says per joint whether its reference is a ``position`` or a
    ``velocity`` (:func:`reference_kinds`). :meth:`cycle_messages` turns rows into the per-cycle channels'
    messages.
    """

    def __init__(self, robot: RobotModel, joint_names: Sequence[str], kinds: Sequence[str],
                 sensor_names: Sequence[str] = ()) -> None:
        self.robot = robot
        self.joint_names = tuple(joint_names)
        self.sensor_names = tuple(sensor_names)
        self.units = [joint_units(robot, j, k) for j, k in zip(self.joint_names, kinds)]
        links = {s.name: s.link for s in robot.sensors}
        self.sensor_frames = tuple(links.get(s, s) for s in self.sensor_names)
        n = len(self.joint_names)
        self.width = 1 + 4 * n + 6 * len(self.sensor_names)
        ref, pos, vel, eff = (1 + q * n for q in range(4))
        self._ros_states = ros2_cdr.JointStateEncoder(self.joint_names).encode
        self._ros_values = slice(pos, eff + n)  # positions, velocities, efforts: JointState's order
        interleaved = [i for j in range(n) for i in (pos + j, vel + j, eff + j)]
        self._states_values = _getter(interleaved)
        self._states = ('{"timestamp":{"sec":%d,"nsec":%d},"joints":[' + ",".join(
            '{"name":%s,"position":%%r,"velocity":%%r,"effort":%%r}' % _name(j) for j in self.joint_names) + "]}")
        self._references_values = _getter(range(ref, ref + n))
        self._references = ('{"timestamp":{"sec":%d,"nsec":%d},"joints":[' + ",".join(
            '{"name":%s,"%s":%%r}' % (_name(j), u.reference_kind) for j, u in zip(self.joint_names, self.units))
            + "]}")
        by_joint = [i for j in range(n) for i in (ref + j, pos + j, vel + j, eff + j)]
        self._joints_values = _getter(by_joint)
        self._joints = "{" + ",".join(
            '%s:{"reference_%s":%%r,"position_%s":%%r,"velocity_%s":%%r,"effort_%s":%%r}'
            % (_name(j), u.reference, u.position, u.velocity, u.effort)
            for j, u in zip(self.joint_names, self.units)) + "}"
        self._states, self._states_text = _templates(self._states)
        self._references, self._references_text = _templates(self._references)
        self._joints, self._joints_text = _templates(self._joints)
        w0 = 1 + 4 * n
        self._wrenches_values = _getter(range(w0, self.width)) if self.sensor_names else None
        self._wrenches = "{" + ",".join(
            '%s:{"frame_id":%s,' % (_name(s), _name(f)) + ",".join(f'"{a}":%r' for a in WRENCH_AXES) + "}"
            for s, f in zip(self.sensor_names, self.sensor_frames)) + "}"
        self._wrenches, self._wrenches_text = _templates(self._wrenches)

    # -- the channels ----------------------------------------------------------------------------------
    def channels(self) -> list[ChannelSpec]:
        """Every channel, per-cycle ones first after the robot description."""
        joints_units = {j: {"reference": u.reference, "position": u.position, "velocity": u.velocity,
                            "effort": u.effort} for j, u in zip(self.joint_names, self.units)}
        units_text = json.dumps(joints_units)
        specs = [
            ChannelSpec(ROBOT_DESCRIPTION, _STRING, {"content": "URDF (xacro expanded)"}),
            ChannelSpec(ROS_JOINT_STATES, ROS_JOINT_STATE_SCHEMA, {"offered_qos_profiles": JOINT_STATES_QOS},
                        ros2_cdr.MESSAGE_ENCODING),
            ChannelSpec(JOINT_STATES, _JOINT_STATES, {"units": "position m or rad, velocity m/s or rad/s, "
                                                               "effort N or N·m (prismatic or revolute)"}),
            ChannelSpec(REFERENCES, _JOINT_STATES, {
                "content": "each joint's controller reference: position (m or rad) or velocity (m/s or rad/s)"}),
            ChannelSpec(JOINTS, self._joints_schema(), {"units": UNIT_SUFFIXES, "joint_units": units_text}),
        ]
        if self.sensor_names:
            specs.append(ChannelSpec(WRENCHES, self._wrenches_schema(), {
                "units": UNIT_SUFFIXES, "frames": "each sensor's link frame (frame_id)"}))
        specs += [
            ChannelSpec(TF, _FRAME_TRANSFORMS, {"units": "translation m", "root": WORLD_FRAME}),
            ChannelSpec(OBJECTS, _SCENE_UPDATE, {"units": "m", "frame": WORLD_FRAME}),
            ChannelSpec(EVENTS, _LOG, {"content": "spawns, removals, trajectory goals, controller failures"}),
        ]
        return specs

    def _joints_schema(self) -> dict:
        properties = {}
        for joint, u in zip(self.joint_names, self.units):
            properties[joint] = _object(None, {
                f"reference_{u.reference}": _number(f"the {u.reference_kind} reference [{_unit(u.reference)}]"),
                f"position_{u.position}": _number(f"[{_unit(u.position)}]"),
                f"velocity_{u.velocity}": _number(f"[{_unit(u.velocity)}]"),
                f"effort_{u.effort}": _number(f"[{_unit(u.effort)}]"),
            })
        return _object("jointctl.Joints", properties, "every joint's reference, position, velocity and effort; "
                                                        "the unit ends each field's name")

    def _wrenches_schema(self) -> dict:
        properties = {s: _object(None, {"frame_id": {"type": "string"},
                                        **{a: _number(f"[{_unit(a.rsplit('_', 1)[1])}]") for a in WRENCH_AXES}})
                      for s in self.sensor_names}
        return _object("jointctl.Wrenches", properties, "each force-torque sensor's wrench in its link's frame")

    # -- per-cycle messages ----------------------------------------------------------------------------
    def cycle_messages(self, rows: np.ndarray, lines: Sequence[str] | None = None,
                       origin_ns: int = 0) -> list[tuple[int, list[bytes]]]:
        """For each row (time first): its stamp [ns] and the per-cycle messages in the order of
        :meth:`cycle_topics`. ``lines`` are the rows as trace.csv writes them (comma-separated
        :data:`NUMBER` text); given, their numbers are used as they are written (no formatting again; the
        CDR joint states hold the values of that text)."""
        rows = np.asarray(rows, dtype=float).reshape(-1, self.width)
        stamps = [origin_ns + int(ns) for ns in np.rint(rows[:, 0] * 1e9).astype(np.int64)]
        if lines is None:
            finite = np.isfinite(rows).all(axis=1).tolist()
            return [(ns, self._messages(row, ns, ok)) for ns, row, ok in zip(stamps, rows.tolist(), finite)]
        out = []
        ros_states, ros_values = self._ros_states, self._ros_values
        for ns, line in zip(stamps, lines):
            values = line.split(",")
            ros = ros_states(ns, [float(v) for v in values[ros_values]])
            if "n" in line:  # nan, inf: JSON's null
                values = [v if "n" not in v else "null" for v in values]
            out.append((ns, [ros, *self._text_messages(values, ns)]))
        return out

    def row_messages(self, row: Sequence[float], ns: int) -> list[bytes]:
        """:meth:`cycle_messages` of one row (a sequence of floats) stamped ``ns`` [ns]: the live stream's."""
        total = sum(row)
        return self._messages(row, ns, not total - total)  # NaN when a value is NaN or infinite

    def _messages(self, row, ns: int, finite: bool) -> list[bytes]:
        ros = self._ros_states(ns, row[self._ros_values])
        if not finite:
            return [ros, *self._text_messages([_number_text(v) for v in row], ns)]
        return [ros, *self._format(row, ns, self._states, self._references, self._joints, self._wrenches)]

    def _text_messages(self, texts: Sequence[str], ns: int) -> list[bytes]:
        """The JSON messages of a row given as JSON number texts."""
        return self._format(texts, ns, self._states_text, self._references_text, self._joints_text,
                            self._wrenches_text)

    def _format(self, row, ns: int, states: str, refs: str, joints: str, wrenches: str) -> list[bytes]:
        sec_nsec = divmod(ns, 1_000_000_000)
        messages = [(states % (sec_nsec + self._states_values(row))).encode(),
                    (refs % (sec_nsec + self._references_values(row))).encode(),
                    (joints % self._joints_values(row)).encode()]
        if self._wrenches_values is not None:
            messages.append((wrenches % self._wrenches_values(row)).encode())
        return messages

    def cycle_topics(self) -> tuple[str, ...]:
        """The topics of :meth:`cycle_messages`' messages, in order."""
        return PER_CYCLE if self.sensor_names else PER_CYCLE[:-1]


def _unit(suffix: str) -> str:
    return {"m": "m", "rad": "rad", "m_s": "m/s", "rad_s": "rad/s", "N": "N", "Nm": "N·m"}[suffix]


# -- the robot's frames ---------------------------------------------------------------------------------
class RobotFrames:
    """Each URDF joint's parent -> child transform at given joint positions, from the robot's own
    kinematics (:class:`~jointctl.model.dynamics.RobotDynamics`: the URDF's model, so it holds on real
    hardware too). ``joint_names`` orders the positions given. When the URDF's root link is not called
    ``world``, a ``world`` -> root transform comes first."""

    def __init__(self, robot: RobotModel, joint_names: Sequence[str]) -> None:
        self.dynamics = RobotDynamics(robot, joints=tuple(joint_names))
        self.pairs = [(j.parent, j.child) for j in robot.joints]
        if robot.root_link != WORLD_FRAME:
            self.pairs.insert(0, (WORLD_FRAME, robot.root_link))
        links = sorted({link for pair in self.pairs for link in pair} - {WORLD_FRAME})
        self._frames = [self.dynamics.frame(link) for link in links]
        index = {link: k + 1 for k, link in enumerate(links)}  # 0: the world frame, the identity
        self._parents = np.array([index.get(p, 0) for p, _ in self.pairs])
        self._children = np.array([index.get(c, 0) for _, c in self.pairs])
        self._template = "[" + ",".join(
            '{"timestamp":{"sec":%%d,"nsec":%%d},"parent_frame_id":%s,"child_frame_id":%s,'
            '"translation":{"x":%%r,"y":%%r,"z":%%r},"rotation":{"x":%%r,"y":%%r,"z":%%r,"w":%%r}}'
            % (_name(p), _name(c)) for p, c in self.pairs) + "]"

    def transforms(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Translations (N x P x 3) [m] and quaternions (N x P x 4, x y z w) of every pair (parent in
        child) for joint positions (N x joints)."""
        positions = np.asarray(positions, dtype=float).reshape(len(positions), -1)
        count, links = len(positions), len(self._frames) + 1
        where = np.zeros((count, links, 3))
        rotation = np.tile(np.eye(3), (count, links, 1, 1))
        for k, q in enumerate(positions):
            self.dynamics.set_pose(q, inertia=False)
            for i, frame in enumerate(self._frames, start=1):
                where[k, i] = frame.position
                rotation[k, i] = frame.rotation
        rp, rc = rotation[:, self._parents], rotation[:, self._children]
        offset = where[:, self._children] - where[:, self._parents]
        translation = np.einsum("npji,npj->npi", rp, offset)  # R_p^T (p_c - p_p)
        relative = np.einsum("npji,npjk->npik", rp, rc)  # R_p^T R_c
        return translation, quaternions(relative)

    def messages(self, times_ns: Sequence[int], positions: np.ndarray) -> list[bytes]:
        """foxglove.FrameTransforms of each stamp [ns] and joint-position row."""
        translation, quaternion = self.transforms(positions)
        out = []
        template = _templates('{"transforms":%s}' % self._template)[0]
        for ns, t, q in zip(times_ns, translation.tolist(), quaternion.tolist()):
            sec, nsec = divmod(int(ns), 1_000_000_000)
            values = []
            for tp, qp in zip(t, q):
                values += (sec, nsec, *tp, *qp)
            out.append((template % tuple(values)).encode())
        return out


def quaternions(rotations: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w; w >= 0) of rotation matrices (... x 3 x 3)."""
    r = np.asarray(rotations, dtype=float)
    trace = r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2]
    # Shepperd's method: start from the largest of 4w², 4x², 4y², 4z² (their sum is 4: s >= 1).
    squares = np.stack([1 + trace, 1 + 2 * r[..., 0, 0] - trace, 1 + 2 * r[..., 1, 1] - trace,
                        1 + 2 * r[..., 2, 2] - trace], axis=-1)
    pick = np.argmax(squares, axis=-1)
    s = np.sqrt(np.take_along_axis(squares, pick[..., None], -1)[..., 0])
    half, d = s / 2, 2 * s
    zy, xz, yx = r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]
    xy, xz_, yz = r[..., 0, 1] + r[..., 1, 0], r[..., 0, 2] + r[..., 2, 0], r[..., 1, 2] + r[..., 2, 1]
    cases = np.stack([  # each case's (x, y, z, w)
        np.stack([zy / d, xz / d, yx / d, half], -1),
        np.stack([half, xy / d, xz_ / d, zy / d], -1),
        np.stack([xy / d, half, yz / d, xz / d], -1),
        np.stack([xz_ / d, yz / d, half, yx / d], -1),
    ], -2)
    q = np.take_along_axis(cases, pick[..., None, None], -2)[..., 0, :]
    q = q * np.where(q[..., 3:4] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# -- the 3D scene's objects, events, the description ----------------------------------------------------
def _pose(position: Sequence[float], quat_wxyz: Sequence[float]) -> dict:
    w, x, y, z = (float(v) for v in quat_wxyz)
    return {"position": dict(zip("xyz", (float(v) for v in position))),
            "orientation": {"x": x, "y": y, "z": z, "w": w}}


def object_entity(spec, position: Sequence[float], quat_wxyz: Sequence[float], ns: int) -> dict:
    """A foxglove.SceneEntity for a spawned object (an ObjectSpec) at its pose in ``world`` [m], with its
    name above it."""
    color = dict(zip("rgba", OBJECT_COLOR))
    pose = _pose(position, quat_wxyz)
    size = spec.size_m
    entity = {"timestamp": stamp(ns), "frame_id": WORLD_FRAME, "id": spec.name, "lifetime": {"sec": 0, "nsec": 0},
              "frame_locked": False, "metadata": [{"key": "mass_kg", "value": repr(float(spec.mass_kg))}],
              "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "lines": [], "triangles": [], "texts": [],
              "models": []}
    if spec.shape == "cylinder":  # radius, length -> the bounding box's diameters and length
        entity["cylinders"].append({"pose": pose, "size": {"x": 2 * size[0], "y": 2 * size[0], "z": size[1]},
                                    "bottom_scale": 1.0, "top_scale": 1.0, "color": color})
        reach = max(size[0], size[1] / 2)
    elif spec.shape == "box":
        entity["cubes"].append({"pose": pose, "size": dict(zip("xyz", size)), "color": color})
        reach = max(size) / 2
    else:
        entity["spheres"].append({"pose": pose, "size": dict(zip("xyz", [2 * size[0]] * 3)), "color": color})
        reach = size[0]
    above = [float(position[0]), float(position[1]), float(position[2]) + reach + LABEL_SIZE_M]
    entity["texts"].append({"pose": _pose(above, (1, 0, 0, 0)), "billboard": True, "font_size": LABEL_SIZE_M,
                            "scale_invariant": False, "color": dict(zip("rgba", LABEL_COLOR)), "text": spec.name})
    return entity


def scene_update(entities: Sequence[dict], deleted: Sequence[str], ns: int) -> bytes:
    """A foxglove.SceneUpdate adding ``entities`` and deleting the entities named ``deleted``."""
    return json.dumps({"deletions": [{"timestamp": stamp(ns), "type": 0, "id": name} for name in deleted],
                       "entities": list(entities)}, allow_nan=False).encode()


def log_message(text: str, ns: int, level: int = INFO) -> bytes:
    """A foxglove.Log line from jointctl."""
    return json.dumps({"timestamp": stamp(ns), "level": level, "message": text, "name": "jointctl", "file": "",
                       "line": 0}).encode()


def object_events(before: set[str], now: set[str]) -> list[str]:
    """The event texts for the spawned objects that came (``now`` - ``before``) and went, by name."""
    return [f"spawned {name}" for name in sorted(now - before)] + [f"removed {name}" for name in sorted(before - now)]


def description_message(urdf: str) -> bytes:
    """The ``/robot_description`` message: the URDF text in ``data``."""
    return json.dumps({"data": urdf}).encode()


__all__ = ["EVENTS", "JOINTS", "JOINT_STATES", "JOINT_STATES_QOS", "OBJECTS", "PER_CYCLE", "REFERENCES",
           "ROBOT_DESCRIPTION", "ROS_JOINT_STATES", "ROS_JOINT_STATE_SCHEMA", "SCENE_RATE_HZ", "TF", "WORLD_FRAME",
           "WRENCHES", "ChannelSpec", "JointUnits", "RecordFormat", "SchemaText",
           "RobotFrames", "decimation", "description_message", "joint_units", "log_message", "nanoseconds",
           "object_entity", "object_events", "quaternions", "reference_kinds", "scene_update", "stamp"]

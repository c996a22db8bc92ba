"""ROS 2 messages as ROS 2 serializes them (CDR) and as ROS 2 bags describe them (``ros2msg``): pure, no ROS.

**CDR** here is what rclpy's ``serialize_message`` gives (DDS XCDR1, little-endian, the RTPS
encapsulation header ``00 01 00 00``: CDR_LE, options 0). After those 4 bytes, every primitive is aligned
to its own size (int32, uint32: 4; float64: 8) counted from the end of the header, with zero bytes as
padding. A string is a uint32 length that counts the terminating NUL, the UTF-8 bytes and the NUL; a
sequence is a uint32 element count, then the elements, the first aligned to its size only when there is
one (an empty ``float64[]`` pads nothing, as rclpy's). Nested messages are their fields in order.

**ros2msg** is the schema text rosbag2 writes into an MCAP file (its
``LocalMessageDefinitionSource``): the type's ``.msg`` file as it is installed, then each type it uses,
depth first, as a line of 80 ``=``, a line ``MSG: <package>/<Type>`` (the name as the field writes it)
and that type's ``.msg`` file. :data:`JOINT_STATE_DEFINITION` is that text for
``sensor_msgs/msg/JointState``, from ROS 2 Jazzy's files (the definitions have not changed since ROS 2's
first release).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

#: The RTPS encapsulation header of a little-endian CDR message (representation CDR_LE, options 0).
ENCAPSULATION = b"\x00\x01\x00\x00"
#: The schema encoding and message encoding of ROS 2 channels in MCAP (the MCAP registry's ros2 profile).
SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"
JOINT_STATE = "sensor_msgs/msg/JointState"
#: 80 ``=``: the line before each dependency's ``MSG:`` line.
DELIMITER = "=" * 80

_JOINT_STATE_MSG = """\
# This is a message that holds data to describe the state of a set of torque controlled joints.
#
# The state of each joint (revolute or prismatic) is defined by:
#  * the position of the joint (rad or m),
#  * the velocity of the joint (rad/s or m/s) and
#  * the effort that is applied in the joint (Nm or N).
#
# Each joint is uniquely identified by its name
# The header specifies the time at which the joint states were recorded. All the joint states
# in one message have to be recorded at the same time.
#
# This message consists of a multiple arrays, one for each part of the joint state.
# The goal is to make each of the fields optional. When e.g. your joints have no
# effort associated with them, you can leave the effort array empty.
#
# All arrays in this message should have the same size, or be empty.
# This is the only way to uniquely associate the joint name with the correct
# states.

std_msgs/Header header

string[] name
float64[] position
float64[] velocity
float64[] effort
"""
_HEADER_MSG = """\
# Standard metadata for higher-level stamped data types.
# This is generally used to communicate timestamped data
# in a particular coordinate frame.

# Two-integer timestamp that is expressed as seconds and nanoseconds.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id
"""
_TIME_MSG = """\
# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

# The seconds component, valid over all int32 values.
int32 sec

# The nanoseconds component, valid in the range [0, 1e9).
uint32 nanosec
"""


def definition(root: str, dependencies: Sequence[tuple[str, str]]) -> str:
    """The ros2msg text of a type: its ``.msg`` text ``root``, then each (``package/Type``, ``.msg`` text) of
    ``dependencies`` (in rosbag2's order: depth first) after the two delimiting lines."""
    return root + "".join(f"\n{DELIMITER}\nMSG: {name}\n{text}" for name, text in dependencies)


#: ``sensor_msgs/msg/JointState`` as ROS 2 bags carry it (schema encoding :data:`SCHEMA_ENCODING`).
JOINT_STATE_DEFINITION = definition(_JOINT_STATE_MSG, [("std_msgs/Header", _HEADER_MSG),
                                                       ("builtin_interfaces/Time", _TIME_MSG)])


class CdrWriter:
    """A CDR message being written, field after field (see the module docstring for the rules).

    ``message()`` gives the bytes with the encapsulation header. Offsets and alignment count from the end
    of the header, as in the encoded message."""

    def __init__(self) -> None:
        self.body = bytearray()

    def align(self, size: int) -> None:
        """Zero bytes up to the next multiple of ``size``."""
        self.body += bytes(-len(self.body) % size)

    def int32(self, value: int) -> None:
        self.align(4)
        self.body += struct.pack("<i", value)

    def uint32(self, value: int) -> None:
        self.align(4)
        self.body += struct.pack("<I", value)

    def float64(self, value: float) -> None:
        self.align(8)
        self.body += struct.pack("<d", value)

    def string(self, text: str) -> None:
        data = text.encode() + b"\0"
        self.uint32(len(data))
        self.body += data

    def strings(self, texts: Sequence[str]) -> None:
        """A ``string[]``."""
        self.uint32(len(texts))
        for text in texts:
            self.string(text)

    def float64s(self, values: Sequence[float]) -> None:
        """A ``float64[]``."""
        self.uint32(len(values))
        if len(values):
            self.align(8)
            self.body += struct.pack(f"<{len(values)}d", *values)

    def stamp(self, ns: int) -> None:
        """A ``builtin_interfaces/Time`` of ``ns`` nanoseconds: ``sec`` (int32) and ``nanosec`` (uint32)."""
        sec, nanosec = divmod(ns, 1_000_000_000)
        self.int32(sec)
        self.uint32(nanosec)

    def message(self) -> bytes:
        return ENCAPSULATION + bytes(self.body)


def joint_state(ns: int, names: Sequence[str], positions: Sequence[float], velocities: Sequence[float],
                efforts: Sequence[float], frame_id: str = "") -> bytes:
    """A ``sensor_msgs/msg/JointState`` in CDR: ``header.stamp`` ``ns`` [ns], ``header.frame_id``, then the
    names and the positions [m or rad], velocities [m/s or rad/s] and efforts [N or N·m]."""
    writer = CdrWriter()
    writer.stamp(ns)
    writer.string(frame_id)
    writer.strings(names)
    for values in (positions, velocities, efforts):
        writer.float64s(values)
    return writer.message()


class JointStateEncoder:
    """:func:`joint_state` for a fixed set of joint names, fast: one ``struct`` pack a message.

    Every field but the stamp and the values has the same bytes and place in each message (the names, the
    counts, the padding), so they are computed once, by :class:`CdrWriter`, and packed as constants.
    ``encode(ns, values)`` takes the positions, velocities and efforts of every joint in that order (3 x
    joints values: trace.csv's column order)."""

    def __init__(self, names: Sequence[str], frame_id: str = "") -> None:
        self.names = tuple(names)
        count = len(self.names)
        writer = CdrWriter()
        writer.stamp(0)
        writer.string(frame_id)
        writer.strings(self.names)
        constants = []
        start = 8  # after the stamp
        for _ in range(3):
            writer.float64s([0.0] * count)
            end = len(writer.body)
            constants.append(bytes(writer.body[start:end - 8 * count]))
            start = end
        self._constants = constants
        self._struct = struct.Struct("<4siI" + "".join(f"{len(c)}s{count}d" for c in constants))
        self._count = count
        self.size = len(ENCAPSULATION) + len(writer.body)  # bytes of every message

    def encode(self, ns: int, values: Sequence[float]) -> bytes:
        """The message stamped ``ns`` [ns] of ``values``: positions, velocities, efforts (joint order)."""
        n = self._count
        c1, c2, c3 = self._constants
        sec, nanosec = divmod(ns, 1_000_000_000)
        return self._struct.pack(ENCAPSULATION, sec, nanosec, c1, *values[:n], c2, *values[n:2 * n],
                                 c3, *values[2 * n:3 * n])


__all__ = ["DELIMITER", "ENCAPSULATION", "JOINT_STATE", "JOINT_STATE_DEFINITION", "MESSAGE_ENCODING",
           "SCHEMA_ENCODING", "CdrWriter", "JointStateEncoder", "definition", "joint_state"]

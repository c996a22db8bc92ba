"""ROS-Industrial ``simple_message``: the wire codec, pure (no sockets, no clocks).

Every packet is a 4-byte length prefix (the number of bytes that *follow* it), a 12-byte header
(``msg_type``, ``comm_type``, ``reply_code``) and a body; every int is an int32 and every real a
float32, all in one byte order: little-endian for the default ROS-I nodes, big-endian for the
``*_bswap`` nodes, prefix and header included (facts §1, §2). There is no negotiation: both ends
are configured the same, here with ``big_endian``.

Units on the wire are the controller's: joint values in rad (revolute) or m (prismatic), times and
durations in s, ``JointTrajPt.velocity`` a fraction of maximum speed in [0, 1] (facts §4, §7).

:func:`encode` builds a whole packet and validates its header as the reference's
``validateMessage`` does (facts §1); :class:`PacketReader` frames a TCP byte stream and
:func:`decode` turns a body into a message, requiring the exact body size (stricter than the
reference, which decodes a long body from its tail). Every problem is a :class:`MalformedPacket`
naming the field and the value.

Facts §N refers to ``simple-message-facts.md`` (read from ``ros-industrial/industrial_core``).
"""

from __future__ import annotations

import enum
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from jointctl.errors import MalformedPacket
from jointctl.validate import real_number

_SOURCE = "simple_message"


class MsgType(enum.IntEnum):
    """Standard message types (facts §3). ``JOINT_TRAJ`` (12) has an id but no message class here."""

    PING = 1
    JOINT_POSITION = 10
    JOINT_TRAJ_PT = 11
    JOINT_TRAJ = 12
    STATUS = 13
    JOINT_TRAJ_PT_FULL = 14
    JOINT_FEEDBACK = 15


class CommType(enum.IntEnum):
    """``TOPIC``: no answer expected; ``SERVICE_REQUEST``: the sender blocks for a
    ``SERVICE_REPLY`` (facts §3)."""

    INVALID = 0
    TOPIC = 1
    SERVICE_REQUEST = 2
    SERVICE_REPLY = 3


class ReplyCode(enum.IntEnum):
    """``INVALID`` (0) is required on everything but a ``SERVICE_REPLY`` (facts §3)."""

    INVALID = 0
    SUCCESS = 1
    FAILURE = 2


#: Joint values per packet: ``JointData`` is always exactly 10 reals, unused ones padded (facts §4).
MAX_JOINTS = 10

# Special sequence numbers of JOINT_TRAJ_PT (facts §5).
START_TRAJECTORY_DOWNLOAD = -1
START_TRAJECTORY_STREAMING = -2
END_TRAJECTORY = -3
STOP_TRAJECTORY = -4

#: The reference refuses to send buffers of 1024 bytes or more, the length prefix included
#: (``SimpleSocket::sendBytes``, facts §1).
MAX_PACKET_BYTES = 1024

# ``valid_fields`` bits of JOINT_TRAJ_PT_FULL and JOINT_FEEDBACK (facts §4).
VALID_TIME, VALID_POSITION, VALID_VELOCITY, VALID_ACCELERATION = 0x01, 0x02, 0x04, 0x08

# STATUS values, the same numbers as industrial_msgs/TriState and RobotMode (facts §4).
TRISTATE_UNKNOWN, TRISTATE_FALSE, TRISTATE_TRUE = -1, 0, 1
MODE_UNKNOWN, MODE_MANUAL, MODE_AUTO = -1, 1, 2

_PREFIX_BYTES = 4
_HEADER_BYTES = 12
_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1


# --- messages (facts §4) -------------------------------------------------------------------------


@dataclass(frozen=True)
class Ping:
    """PING (1): an empty body; a controller answers a PING request with SUCCESS."""


@dataclass(frozen=True)
class JointPosition:
    """JOINT_POSITION (10): the controller's joint positions [rad or m] in ``controller_joint_names``
    order. Up to 10 values; encode pads with 0.0, decode gives all 10. ``sequence`` is ignored by
    ROS-I's ``robot_state``."""

    sequence: int
    positions: tuple[float, ...]


@dataclass(frozen=True)
class JointTrajPt:
    """JOINT_TRAJ_PT (11): one trajectory point. ``positions`` [rad or m], up to 10 (padded with 0.0;
    decode gives 10); ``velocity`` a fraction of maximum speed in [0, 1]; ``duration`` [s] of the
    segment that ends at this point. ``sequence`` is the point's index, or one of the special
    values (``STOP_TRAJECTORY``...; facts §5)."""

    sequence: int
    positions: tuple[float, ...]
    velocity: float
    duration: float


@dataclass(frozen=True)
class RobotStatus:
    """STATUS (13): TriState fields (``TRISTATE_*``: -1 unknown, 0 false, 1 true), ``mode``
    (``MODE_*``: -1 unknown, 1 manual, 2 auto) and the controller's ``error_code``."""

    drives_powered: int
    e_stopped: int
    error_code: int
    in_error: int
    in_motion: int
    mode: int
    motion_possible: int


@dataclass(frozen=True)
class JointTrajPtFull:
    """JOINT_TRAJ_PT_FULL (14): ``time`` [s], positions [rad or m], velocities [per s] and
    accelerations [per s²], up to 10 each (padded with 0.0; decode gives 10). ``valid_fields``
    says which are meaningful (``VALID_*`` bits); invalid arrays are still sent."""

    robot_id: int
    sequence: int
    valid_fields: int
    time: float
    positions: tuple[float, ...]
    velocities: tuple[float, ...]
    accelerations: tuple[float, ...]


@dataclass(frozen=True)
class JointFeedback:
    """JOINT_FEEDBACK (15): like :class:`JointTrajPtFull` without ``sequence``; ROS-I's
    ``robot_state`` has no handler for it (facts §7)."""

    robot_id: int
    valid_fields: int
    time: float
    positions: tuple[float, ...]
    velocities: tuple[float, ...]
    accelerations: tuple[float, ...]


Message = Ping | JointPosition | JointTrajPt | RobotStatus | JointTrajPtFull | JointFeedback


@dataclass(frozen=True)
class Packet:
    """A framed packet whose header passed validation (the checks of ``validateMessage``, facts §1);
    ``body`` is raw bytes, not yet decoded (:func:`decode`). ``msg_type`` is a :class:`MsgType`
    when it is a standard one and a plain int otherwise (vendor ids...); likewise ``reply_code``.
    Building one with an invalid header raises :class:`MalformedPacket`."""

    msg_type: int
    comm_type: int
    reply_code: int
    body: bytes

    def __post_init__(self) -> None:
        msg_type, comm_type, reply_code = _checked_header(self.msg_type, self.comm_type,
                                                          self.reply_code)
        body = self.body
        if isinstance(body, (bytearray, memoryview)):
            body = bytes(body)
        elif not isinstance(body, bytes):
            raise MalformedPacket("body must be bytes", source=_SOURCE, field="body", value=body)
        object.__setattr__(self, "msg_type", msg_type)
        object.__setattr__(self, "comm_type", comm_type)
        object.__setattr__(self, "reply_code", reply_code)
        object.__setattr__(self, "body", body)


# --- byte layouts: one precompiled Struct per body and byte order --------------------------------

_JOINTS = f"{MAX_JOINTS}f"
_BODY_FORMATS: dict[MsgType, str] = {
    MsgType.PING: "",
    MsgType.JOINT_POSITION: f"i{_JOINTS}",
    MsgType.JOINT_TRAJ_PT: f"i{_JOINTS}ff",
    MsgType.STATUS: "7i",
    MsgType.JOINT_TRAJ_PT_FULL: f"3if{_JOINTS}{_JOINTS}{_JOINTS}",
    MsgType.JOINT_FEEDBACK: f"2if{_JOINTS}{_JOINTS}{_JOINTS}",
}
_ORDERS = {False: "<", True: ">"}
_BODIES = {(msg_type, big): struct.Struct(order + fmt)
           for msg_type, fmt in _BODY_FORMATS.items() for big, order in _ORDERS.items()}
_PREFIX = {big: struct.Struct(order + "i") for big, order in _ORDERS.items()}
_HEADER = {big: struct.Struct(order + "3i") for big, order in _ORDERS.items()}
_FRAME = {big: struct.Struct(order + "4i") for big, order in _ORDERS.items()}
_FLOAT32 = struct.Struct("<f")

#: Body size in bytes of every message type that has a message class (facts §4).
BODY_BYTES: dict[int, int] = {msg_type: _BODIES[msg_type, False].size for msg_type in _BODY_FORMATS}


# --- encoding ------------------------------------------------------------------------------------


def encode(message: Message, comm_type: CommType = CommType.TOPIC,
           reply_code: ReplyCode = ReplyCode.INVALID, *, big_endian: bool = False) -> bytes:
    """The whole packet for ``message``: length prefix, header and body, every int32 and float32 in
    the chosen byte order (facts §1, §2, §4).

    The header is validated as ``validateMessage`` does: ``comm_type`` 1..3, ``reply_code`` 0 unless
    a ``SERVICE_REPLY``, which needs a non-zero one. Joint arrays hold at most ``MAX_JOINTS`` values
    and are padded with 0.0. Non-finite reals are encoded (the controller decides what to do with
    them), but every value must fit its int32 or float32. Anything else is a
    :class:`MalformedPacket` naming the field. A non-message raises ``TypeError``.
    """
    encoder = _ENCODERS.get(type(message))
    if encoder is None:
        raise TypeError(f"not a simple_message message: {type(message).__name__}")
    msg_type, fields = encoder(message)
    body = _BODIES[msg_type, big_endian].pack(*fields)
    return _frame(msg_type, comm_type, reply_code, body, big_endian)


def encode_reply(request: Packet, code: ReplyCode, *, echo_body: bool = True,
                 big_endian: bool = False) -> bytes:
    """A ``SERVICE_REPLY`` to ``request``: its ``msg_type``, ``code`` (non-zero) and its body echoed
    as ``TypedMessage::toReply`` does; ``echo_body=False`` gives an empty body, as
    ``MessageManager``'s generic FAILURE for an unhandled request (facts §3)."""
    body = request.body if echo_body else b""
    return _frame(request.msg_type, CommType.SERVICE_REPLY, code, body, big_endian)


def _frame(msg_type: Any, comm_type: Any, reply_code: Any, body: bytes, big_endian: bool) -> bytes:
    msg_type, comm_type, reply_code = _checked_header(msg_type, comm_type, reply_code)
    total = _PREFIX_BYTES + _HEADER_BYTES + len(body)
    if total >= MAX_PACKET_BYTES:
        raise MalformedPacket(f"a packet must be smaller than {MAX_PACKET_BYTES} bytes, the length "
                              "prefix included (the reference refuses to send it)",
                              source=_SOURCE, field="length", value=total)
    head = _FRAME[big_endian].pack(total - _PREFIX_BYTES, msg_type, comm_type, reply_code)
    return head + body


def _encode_joint_position(message: JointPosition) -> tuple[MsgType, tuple]:
    return MsgType.JOINT_POSITION, (_int32("sequence", message.sequence),
                                    *_joints("positions", message.positions))


def _encode_joint_traj_pt(message: JointTrajPt) -> tuple[MsgType, tuple]:
    return MsgType.JOINT_TRAJ_PT, (_int32("sequence", message.sequence),
                                   *_joints("positions", message.positions),
                                   _float32("velocity", message.velocity),
                                   _float32("duration", message.duration))


def _encode_status(message: RobotStatus) -> tuple[MsgType, tuple]:
    return MsgType.STATUS, tuple(_int32(name, getattr(message, name)) for name in _STATUS_FIELDS)


def _encode_joint_traj_pt_full(message: JointTrajPtFull) -> tuple[MsgType, tuple]:
    return MsgType.JOINT_TRAJ_PT_FULL, (_int32("robot_id", message.robot_id),
                                        _int32("sequence", message.sequence),
                                        _int32("valid_fields", message.valid_fields),
                                        _float32("time", message.time), *_arrays(message))


def _encode_joint_feedback(message: JointFeedback) -> tuple[MsgType, tuple]:
    return MsgType.JOINT_FEEDBACK, (_int32("robot_id", message.robot_id),
                                    _int32("valid_fields", message.valid_fields),
                                    _float32("time", message.time), *_arrays(message))


_STATUS_FIELDS = ("drives_powered", "e_stopped", "error_code", "in_error", "in_motion", "mode",
                  "motion_possible")
_ENCODERS: dict[type, Callable[[Any], tuple[MsgType, tuple]]] = {
    Ping: lambda message: (MsgType.PING, ()),
    JointPosition: _encode_joint_position,
    JointTrajPt: _encode_joint_traj_pt,
    RobotStatus: _encode_status,
    JointTrajPtFull: _encode_joint_traj_pt_full,
    JointFeedback: _encode_joint_feedback,
}


def _arrays(message: JointTrajPtFull | JointFeedback) -> list[float]:
    return [*_joints("positions", message.positions), *_joints("velocities", message.velocities),
            *_joints("accelerations", message.accelerations)]


def _int32(field: str, value: Any) -> int:
    if isinstance(value, bool) or not hasattr(value, "__index__"):
        raise MalformedPacket("must be an integer", source=_SOURCE, field=field,
                              value=value)
    number = value.__index__()
    if not _INT32_MIN <= number <= _INT32_MAX:
        raise MalformedPacket(f"must fit an int32 ({_INT32_MIN}..{_INT32_MAX})",
                              source=_SOURCE, field=field, value=value)
    return number


def _float32(field: str, value: Any, index: int | None = None) -> float:
    place = "" if index is None else f"joint {index} "
    number = real_number(value)
    if number is None:
        raise MalformedPacket(f"{place}must be a real number", source=_SOURCE, field=field,
                              value=value)
    try:
        _FLOAT32.pack(number)
    except OverflowError:
        raise MalformedPacket(f"{place}must fit a float32 (magnitude up to about 3.4e38; "
                              "inf and nan are allowed)", source=_SOURCE, field=field,
                              value=value) from None
    return number


def _joints(field: str, values: Any) -> list[float]:
    try:
        if isinstance(values, (str, bytes, bytearray)):
            raise TypeError
        items = list(values)
    except TypeError:
        raise MalformedPacket(f"must be a sequence of at most {MAX_JOINTS} numbers",
                              source=_SOURCE, field=field, value=values) from None
    if len(items) > MAX_JOINTS:
        raise MalformedPacket(f"must hold at most {MAX_JOINTS} joint values",
                              source=_SOURCE, field=field, value=len(items))
    numbers = [_float32(field, item, index) for index, item in enumerate(items)]
    return numbers + [0.0] * (MAX_JOINTS - len(numbers))


# --- decoding ------------------------------------------------------------------------------------


def decode(packet: Packet, *, big_endian: bool = False) -> Message:
    """The message in ``packet``'s body, by its ``msg_type`` (facts §4). The body must have exactly
    ``BODY_BYTES[msg_type]`` bytes: a short or a long one is a :class:`MalformedPacket` (field
    ``"body"``, value its size). A type with no message class (12 ``JOINT_TRAJ``, 20, 21, vendor
    ids...) is a :class:`MalformedPacket` with field ``"msg_type"``. Joint arrays come back with all
    ``MAX_JOINTS`` values, as floats."""
    msg_type = packet.msg_type
    if msg_type not in _DECODERS:
        raise MalformedPacket(f"no message class for msg_type {_type_name(msg_type)} (known: "
                              f"{', '.join(f'{t.value} {t.name}' for t in _DECODERS)})",
                              source=_SOURCE, field="msg_type", value=int(msg_type))
    layout = _BODIES[msg_type, big_endian]
    if len(packet.body) != layout.size:
        raise MalformedPacket(f"{MsgType(msg_type).name} body must be {layout.size} bytes",
                              source=_SOURCE, field="body", value=len(packet.body))
    return _DECODERS[msg_type](layout.unpack(packet.body))


_J = MAX_JOINTS
_DECODERS: dict[MsgType, Callable[[tuple], Message]] = {
    MsgType.PING: lambda v: Ping(),
    MsgType.JOINT_POSITION: lambda v: JointPosition(v[0], v[1:1 + _J]),
    MsgType.JOINT_TRAJ_PT: lambda v: JointTrajPt(v[0], v[1:1 + _J], v[1 + _J], v[2 + _J]),
    MsgType.STATUS: lambda v: RobotStatus(*v),
    MsgType.JOINT_TRAJ_PT_FULL: lambda v: JointTrajPtFull(
        v[0], v[1], v[2], v[3], v[4:4 + _J], v[4 + _J:4 + 2 * _J], v[4 + 2 * _J:4 + 3 * _J]),
    MsgType.JOINT_FEEDBACK: lambda v: JointFeedback(
        v[0], v[1], v[2], v[3:3 + _J], v[3 + _J:3 + 2 * _J], v[3 + 2 * _J:3 + 3 * _J]),
}


def _type_name(msg_type: int) -> str:
    return f"{int(msg_type)} ({msg_type.name})" if isinstance(msg_type, MsgType) else str(msg_type)


# --- framing -------------------------------------------------------------------------------------


def _checked_header(msg_type: Any, comm_type: Any, reply_code: Any) -> tuple[int, int, int]:
    """The header as ``validateMessage`` checks it (facts §1), with known values as enums."""
    msg_type = _int32("msg_type", msg_type)
    comm_type = _int32("comm_type", comm_type)
    reply_code = _int32("reply_code", reply_code)
    if msg_type == 0:
        raise MalformedPacket("must not be 0 (INVALID)", source=_SOURCE,
                              field="msg_type", value=msg_type)
    if comm_type not in (CommType.TOPIC, CommType.SERVICE_REQUEST, CommType.SERVICE_REPLY):
        raise MalformedPacket("must be 1 (TOPIC), 2 (SERVICE_REQUEST) or 3 "
                              "(SERVICE_REPLY)", source=_SOURCE, field="comm_type",
                              value=comm_type)
    if comm_type == CommType.SERVICE_REPLY and reply_code == ReplyCode.INVALID:
        raise MalformedPacket("a SERVICE_REPLY needs a non-zero reply_code (1 SUCCESS, "
                              "2 FAILURE)", source=_SOURCE, field="reply_code", value=reply_code)
    if comm_type != CommType.SERVICE_REPLY and reply_code != ReplyCode.INVALID:
        raise MalformedPacket(f"must be 0 (INVALID) on a {CommType(comm_type).name}",
                              source=_SOURCE, field="reply_code", value=reply_code)
    return (_known(MsgType, msg_type), CommType(comm_type), _known(ReplyCode, reply_code))


def _known(kind: type[enum.IntEnum], value: int) -> int:
    try:
        return kind(value)
    except ValueError:
        return value


def _checked_length(length: int, max_packet_bytes: int) -> None:
    """The length prefix (bytes after it) must hold the header and fit ``max_packet_bytes``."""
    if length < _HEADER_BYTES:
        raise MalformedPacket(f"length prefix must be at least {_HEADER_BYTES} (the header), "
                              "framing is lost", source=_SOURCE, field="length", value=length)
    if length > max_packet_bytes - _PREFIX_BYTES:
        raise MalformedPacket(f"length prefix must be at most {max_packet_bytes - _PREFIX_BYTES} "
                              f"(packets of up to {max_packet_bytes} bytes), framing is lost",
                              source=_SOURCE, field="length", value=length)


def parse_packet(data: bytes, *, big_endian: bool = False) -> Packet:
    """Exactly one whole packet, length prefix included, validated as :class:`PacketReader` does
    (with ``MAX_PACKET_BYTES``); data shorter or longer than its prefix says is a
    :class:`MalformedPacket` with field ``"length"``."""
    data = bytes(data)
    if len(data) < _PREFIX_BYTES:
        raise MalformedPacket(f"a packet starts with a {_PREFIX_BYTES}-byte length prefix",
                              source=_SOURCE, field="length", value=len(data))
    (length,) = _PREFIX[big_endian].unpack_from(data)
    _checked_length(length, MAX_PACKET_BYTES)
    if len(data) != _PREFIX_BYTES + length:
        raise MalformedPacket(f"length prefix says {length} bytes follow, but "
                              f"{len(data) - _PREFIX_BYTES} do", source=_SOURCE, field="length",
                              value=length)
    header = _HEADER[big_endian].unpack_from(data, _PREFIX_BYTES)
    return Packet(*header, data[_PREFIX_BYTES + _HEADER_BYTES:])


class PacketReader:
    """Incremental framing of a TCP byte stream (facts §1: no delimiter, no checksum).

    :meth:`feed` returns every complete packet and keeps a partial one for the next call. A packet
    with a valid header but an unknown ``msg_type`` is returned (the server answers FAILURE to
    unknown requests); bodies are not checked here (:func:`decode` does).

    Errors, all :class:`MalformedPacket`:

    * a length prefix below 12 (it cannot hold the header) or above ``max_packet_bytes - 4``:
      field ``"length"``. The stream's framing is lost and cannot be resynchronised, so the reader
      is poisoned: every later :meth:`feed` raises the same error; the caller closes the connection.
    * an invalid header (``msg_type`` 0, ``comm_type`` not 1..3, a reply code that does not fit the
      comm type): field ``"msg_type"``, ``"comm_type"`` or ``"reply_code"``. Framing is intact: the
      bad packet is skipped and the reader stays usable; packets that followed it are returned by
      the next :meth:`feed` (``feed(b"")`` will do).

    No packet is lost to an error: when one is found after good packets of the same feed, those
    are returned and the error is raised by the next :meth:`feed`.
    """

    def __init__(self, *, big_endian: bool = False,
                 max_packet_bytes: int = MAX_PACKET_BYTES) -> None:
        if (isinstance(max_packet_bytes, bool) or not isinstance(max_packet_bytes, int)
                or max_packet_bytes < _PREFIX_BYTES + _HEADER_BYTES):
            raise ValueError(f"max_packet_bytes must be an int of at least "
                             f"{_PREFIX_BYTES + _HEADER_BYTES}, got {max_packet_bytes!r}")
        self.big_endian = big_endian
        self.max_packet_bytes = max_packet_bytes
        self._prefix = _PREFIX[big_endian]
        self._header = _HEADER[big_endian]
        self._buffer = bytearray()
        self._pending: MalformedPacket | None = None
        self._poison: MalformedPacket | None = None

    @property
    def poisoned(self) -> bool:
        """True once the framing is lost: every :meth:`feed` raises."""
        return self._poison is not None

    @property
    def buffered(self) -> int:
        """Bytes received and not yet returned as a packet."""
        return len(self._buffer)

    def feed(self, data: bytes) -> list[Packet]:
        """Append ``data`` and return every complete packet, in stream order."""
        if self._poison is not None:
            raise self._poison
        self._buffer += data
        if self._pending is not None:
            error, self._pending = self._pending, None
            raise error
        packets: list[Packet] = []
        position = 0
        error: MalformedPacket | None = None
        try:
            while error is None:
                packet, error, position = self._next(position)
                if packet is None and error is None:
                    break
                if packet is not None:
                    packets.append(packet)
        except MalformedPacket as lost:  # the length prefix: framing is lost for good
            self._poison = error = lost
            self._buffer.clear()
            position = 0
        del self._buffer[:position]
        if error is not None:
            if not packets:
                raise error
            if self._poison is None:
                self._pending = error
        return packets

    def _next(self, position: int) -> tuple[Packet | None, MalformedPacket | None, int]:
        """The packet starting at ``position`` (or the error of its header) and the position after
        it; ``(None, None, position)`` when it is not complete yet. A bad length prefix raises."""
        buffer = self._buffer
        if len(buffer) - position < _PREFIX_BYTES:
            return None, None, position
        (length,) = self._prefix.unpack_from(buffer, position)
        _checked_length(length, self.max_packet_bytes)
        end = position + _PREFIX_BYTES + length
        if len(buffer) < end:
            return None, None, position
        header = self._header.unpack_from(buffer, position + _PREFIX_BYTES)
        body = bytes(buffer[position + _PREFIX_BYTES + _HEADER_BYTES:end])
        try:
            return Packet(*header, body), None, end
        except MalformedPacket as error:
            return None, error, end

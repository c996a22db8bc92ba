"""ROS-Industrial simple_message codec, checked against simple-message-facts.md (§1-§5): the expected
bytes are built here with ``struct`` from the facts' layouts, never copied from the codec."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointctl.errors import JointCtlError, MalformedPacket
from jointctl.wire.simple_message import (
    BODY_BYTES,
    END_TRAJECTORY,
    MAX_JOINTS,
    MAX_PACKET_BYTES,
    MODE_AUTO,
    MODE_MANUAL,
    MODE_UNKNOWN,
    START_TRAJECTORY_DOWNLOAD,
    START_TRAJECTORY_STREAMING,
    STOP_TRAJECTORY,
    TRISTATE_FALSE,
    TRISTATE_TRUE,
    TRISTATE_UNKNOWN,
    VALID_ACCELERATION,
    VALID_POSITION,
    VALID_TIME,
    VALID_VELOCITY,
    CommType,
    JointFeedback,
    JointPosition,
    JointTrajPt,
    JointTrajPtFull,
    MsgType,
    Packet,
    PacketReader,
    Ping,
    ReplyCode,
    RobotStatus,
    decode,
    encode,
    encode_reply,
    parse_packet,
)

ORDERS = pytest.mark.parametrize("big_endian", [False, True], ids=["little", "big"])
GIB = 2**30


def fmt(big_endian: bool) -> str:
    return ">" if big_endian else "<"


def frame(msg_type: int, comm: int, reply: int, body: bytes = b"", *, big_endian: bool = False,
          length: int | None = None) -> bytes:
    """A packet built by hand: prefix = bytes after it (facts §1), header, body."""
    length = 12 + len(body) if length is None else length
    return struct.pack(fmt(big_endian) + "4i", length, msg_type, comm, reply) + body


def f32(value: float) -> float:
    return float(np.float32(value))


def f32s(values, n: int = MAX_JOINTS) -> tuple[float, ...]:
    padded = list(values) + [0.0] * (n - len(values))
    return tuple(f32(v) for v in padded)


def assert_malformed(info: pytest.ExceptionInfo, field: str, value) -> None:
    error = info.value
    assert isinstance(error, MalformedPacket) and isinstance(error, JointCtlError)
    assert error.code == "packet"
    assert error.field == field
    assert error.value == value
    assert field in str(error) and "got" in str(error)


# --- constants (facts §3, §4, §5) ----------------------------------------------------------------


def test_enum_values_and_constants_are_the_references():
    assert [(t.name, t.value) for t in MsgType] == [
        ("PING", 1), ("JOINT_POSITION", 10), ("JOINT_TRAJ_PT", 11), ("JOINT_TRAJ", 12), ("STATUS", 13),
        ("JOINT_TRAJ_PT_FULL", 14), ("JOINT_FEEDBACK", 15)]
    assert [int(c) for c in CommType] == [0, 1, 2, 3]
    assert [int(c) for c in ReplyCode] == [0, 1, 2]
    assert (START_TRAJECTORY_DOWNLOAD, START_TRAJECTORY_STREAMING, END_TRAJECTORY, STOP_TRAJECTORY) == (
        -1, -2, -3, -4)
    assert (VALID_TIME, VALID_POSITION, VALID_VELOCITY, VALID_ACCELERATION) == (1, 2, 4, 8)
    assert (TRISTATE_UNKNOWN, TRISTATE_FALSE, TRISTATE_TRUE) == (-1, 0, 1)
    assert (MODE_UNKNOWN, MODE_MANUAL, MODE_AUTO) == (-1, 1, 2)
    assert MAX_JOINTS == 10 and MAX_PACKET_BYTES == 1024
    assert BODY_BYTES == {1: 0, 10: 44, 11: 52, 13: 28, 14: 136, 15: 132}


# --- golden bytes (facts §1, §2, §4 worked example) ----------------------------------------------


POINT = JointTrajPt(7, (0.1, -0.2, 0.3, 1.5, -2.5, 3.0), 0.25, 1.5)


def point_body(big_endian: bool) -> bytes:
    joints = [0.1, -0.2, 0.3, 1.5, -2.5, 3.0, 0.0, 0.0, 0.0, 0.0]
    return struct.pack(fmt(big_endian) + "i10fff", 7, *joints, 0.25, 1.5)


def test_joint_traj_pt_request_little_endian_golden_bytes():
    data = encode(POINT, CommType.SERVICE_REQUEST)
    # Facts §4's worked example prints the prefix as "44 00 00 00" but says "length 64"; the prefix
    # counts the bytes after it (facts §1; SmplMsgConnection::sendMsg loads msgData's size):
    # 12 + 52 = 64 = 0x40.
    assert data[:16] == bytes.fromhex("40000000 0b000000 02000000 00000000")
    assert len(data) == 68
    assert data == struct.pack("<4i", 64, 11, 2, 0) + point_body(False)


def test_joint_traj_pt_request_big_endian_golden_bytes():
    data = encode(POINT, CommType.SERVICE_REQUEST, big_endian=True)
    assert data[:16] == bytes.fromhex("00000040 0000000b 00000002 00000000")
    assert len(data) == 68
    assert data == struct.pack(">4i", 64, 11, 2, 0) + point_body(True)


def test_stop_packet_is_seq_minus_four_and_zeros():
    data = encode(JointTrajPt(STOP_TRAJECTORY, (), 0.0, 0.0), CommType.SERVICE_REQUEST)
    assert data == struct.pack("<4i", 64, 11, 2, 0) + struct.pack("<i12f", -4, *[0.0] * 12)


@ORDERS
def test_every_body_in_wire_order(big_endian):
    o = fmt(big_endian)
    p, v, a = [0.5] * 10, [-1.0] * 10, [2.0] * 10
    cases = [
        (Ping(), 1, b""),
        (JointPosition(3, tuple(p)), 10, struct.pack(o + "i10f", 3, *p)),
        (RobotStatus(1, 0, 42, -1, 3, 2, 4), 13, struct.pack(o + "7i", 1, 0, 42, -1, 3, 2, 4)),
        (JointTrajPtFull(2, 9, 0x0F, 0.75, tuple(p), tuple(v), tuple(a)), 14,
         struct.pack(o + "3if30f", 2, 9, 15, 0.75, *p, *v, *a)),
        (JointFeedback(2, 0x03, 0.75, tuple(p), tuple(v), tuple(a)), 15,
         struct.pack(o + "2if30f", 2, 3, 0.75, *p, *v, *a)),
    ]
    for message, msg_type, body in cases:
        assert encode(message, big_endian=big_endian) == frame(msg_type, 1, 0, body, big_endian=big_endian)
        packet = parse_packet(frame(msg_type, 1, 0, body, big_endian=big_endian), big_endian=big_endian)
        assert decode(packet, big_endian=big_endian) == message


@pytest.mark.parametrize(("message", "size"), [
    (Ping(), 16), (JointPosition(0, ()), 60), (JointTrajPt(0, (), 0.0, 0.0), 68),
    (RobotStatus(0, 0, 0, 0, 0, 0, 0), 44), (JointTrajPtFull(0, 0, 0, 0.0, (), (), ()), 152),
    (JointFeedback(0, 0, 0.0, (), (), ()), 148),
])
@ORDERS
def test_packet_sizes_including_the_prefix(message, size, big_endian):
    data = encode(message, big_endian=big_endian)
    assert len(data) == size
    assert struct.unpack_from(fmt(big_endian) + "i", data)[0] == size - 4


# --- round trips ---------------------------------------------------------------------------------


MESSAGES = [
    Ping(),
    JointPosition(12345, (0.1, 0.2, -0.3)),
    JointPosition(-7, tuple(float(i) / 3 for i in range(10))),
    JointTrajPt(0, (math.pi, -math.e, 1e-7), 0.1, 10.0),
    JointTrajPt(START_TRAJECTORY_DOWNLOAD, tuple(range(10)), 1.0, 0.001),
    RobotStatus(TRISTATE_TRUE, TRISTATE_FALSE, -2**31, TRISTATE_UNKNOWN, 1, MODE_AUTO, 2**31 - 1),
    JointTrajPtFull(1, 2, VALID_TIME | VALID_POSITION, 0.123456789, (0.1,) * 6, (0.2,) * 7, ()),
    JointFeedback(0, 0x0F, 1e6, (1.1,) * 10, (-2.2,) * 10, (3.3e-3,) * 10),
]


def expected_after_round_trip(message):
    """The message as the wire gives it back: float32 values, joint arrays padded to 10."""
    match message:
        case JointPosition():
            return JointPosition(message.sequence, f32s(message.positions))
        case JointTrajPt():
            return JointTrajPt(message.sequence, f32s(message.positions), f32(message.velocity),
                               f32(message.duration))
        case JointTrajPtFull():
            return JointTrajPtFull(message.robot_id, message.sequence, message.valid_fields,
                                   f32(message.time), f32s(message.positions),
                                   f32s(message.velocities), f32s(message.accelerations))
        case JointFeedback():
            return JointFeedback(message.robot_id, message.valid_fields, f32(message.time),
                                 f32s(message.positions), f32s(message.velocities),
                                 f32s(message.accelerations))
    return message


@pytest.mark.parametrize("message", MESSAGES, ids=lambda m: type(m).__name__)
@pytest.mark.parametrize("comm", [CommType.TOPIC, CommType.SERVICE_REQUEST])
@ORDERS
def test_round_trip(message, comm, big_endian):
    data = encode(message, comm, big_endian=big_endian)
    packet = parse_packet(data, big_endian=big_endian)
    assert packet.comm_type == comm and packet.reply_code == 0
    decoded = decode(packet, big_endian=big_endian)
    assert decoded == expected_after_round_trip(message)
    assert type(decoded) is type(message)
    # decoded values re-encode to the same bytes
    assert encode(decoded, comm, big_endian=big_endian) == data


@ORDERS
def test_round_trip_of_a_reply(big_endian):
    data = encode(RobotStatus(1, 0, 0, 0, 0, 2, 1), CommType.SERVICE_REPLY, ReplyCode.FAILURE,
                  big_endian=big_endian)
    packet = parse_packet(data, big_endian=big_endian)
    assert (packet.msg_type, packet.comm_type, packet.reply_code) == (13, 3, 2)
    assert decode(packet, big_endian=big_endian) == RobotStatus(1, 0, 0, 0, 0, 2, 1)


def test_decoded_joint_arrays_are_tuples_of_ten_floats():
    message = decode(parse_packet(encode(JointPosition(1, (1, 2)))))
    assert message.positions == (1.0, 2.0) + (0.0,) * 8
    assert isinstance(message.positions, tuple) and all(type(v) is float for v in message.positions)


def test_non_finite_numbers_are_encoded_for_the_controller_to_judge():
    message = JointTrajPt(1, (math.inf, -math.inf, math.nan), math.nan, math.inf)
    decoded = decode(parse_packet(encode(message)))
    assert decoded.positions[:2] == (math.inf, -math.inf) and math.isnan(decoded.positions[2])
    assert math.isnan(decoded.velocity) and decoded.duration == math.inf


def test_numpy_values_and_lists_are_accepted():
    message = JointTrajPt(np.int64(3), list(np.linspace(0, 1, 6)), np.float32(0.5), np.float64(2))
    decoded = decode(parse_packet(encode(message)))
    assert decoded.sequence == 3 and decoded.positions == f32s(np.linspace(0, 1, 6))


# --- malformed packets: decode -------------------------------------------------------------------


@pytest.mark.parametrize("size", [0, 51, 53, 104])
def test_joint_traj_pt_body_of_the_wrong_size(size):
    with pytest.raises(MalformedPacket, match="JOINT_TRAJ_PT body must be 52 bytes") as info:
        decode(Packet(11, 2, 0, bytes(size)))
    assert_malformed(info, "body", size)


@pytest.mark.parametrize(("msg_type", "size"), [(1, 1), (10, 43), (10, 45), (13, 27), (13, 29),
                                                (14, 135), (14, 137), (15, 131), (15, 133)])
def test_short_and_long_bodies_of_every_type(msg_type, size):
    with pytest.raises(MalformedPacket, match=f"body must be {BODY_BYTES[msg_type]} bytes") as info:
        decode(Packet(msg_type, 1, 0, bytes(size)))
    assert_malformed(info, "body", size)


@pytest.mark.parametrize("msg_type", [12, 2, 20, 21, 1000, 1300, 2000, -5])
def test_unknown_msg_type_is_malformed_for_decode(msg_type):
    with pytest.raises(MalformedPacket) as info:
        decode(Packet(msg_type, 2, 0, bytes(52)))
    assert_malformed(info, "msg_type", msg_type)


# --- malformed packets: headers ------------------------------------------------------------------


HEADER_CASES = [
    # (msg_type, comm, reply, field, value)
    pytest.param(11, 1, 1, "reply_code", 1, id="reply code on a topic"),
    pytest.param(11, 2, 2, "reply_code", 2, id="reply code on a request"),
    pytest.param(11, 3, 0, "reply_code", 0, id="reply code 0 on a reply"),
    pytest.param(11, 0, 0, "comm_type", 0, id="comm type 0"),
    pytest.param(11, 4, 0, "comm_type", 4, id="comm type 4"),
    pytest.param(11, -1, 0, "comm_type", -1, id="comm type -1"),
    pytest.param(0, 1, 0, "msg_type", 0, id="msg type 0"),
]


@pytest.mark.parametrize(("msg_type", "comm", "reply", "field", "value"), HEADER_CASES)
@ORDERS
def test_bad_headers_are_refused_by_the_reader(msg_type, comm, reply, field, value, big_endian):
    data = frame(msg_type, comm, reply, bytes(52), big_endian=big_endian)
    reader = PacketReader(big_endian=big_endian)
    with pytest.raises(MalformedPacket) as info:
        reader.feed(data)
    assert_malformed(info, field, value)
    with pytest.raises(MalformedPacket) as info:
        parse_packet(data, big_endian=big_endian)
    assert_malformed(info, field, value)
    with pytest.raises(MalformedPacket) as info:
        Packet(msg_type, comm, reply, bytes(52))
    assert_malformed(info, field, value)
    # framing is intact: the bad packet was skipped and the reader goes on
    assert not reader.poisoned
    assert reader.feed(encode(Ping(), big_endian=big_endian)) == [Packet(1, 1, 0, b"")]


@pytest.mark.parametrize(("msg_type", "comm", "reply", "field", "value"), HEADER_CASES[:6])
def test_bad_headers_are_refused_by_encode(msg_type, comm, reply, field, value):
    with pytest.raises(MalformedPacket) as info:
        encode(JointTrajPt(0, (), 0.0, 0.0), comm, reply)
    assert_malformed(info, field, value)


def test_encode_reply_needs_a_non_zero_code():
    request = parse_packet(encode(Ping(), CommType.SERVICE_REQUEST))
    with pytest.raises(MalformedPacket) as info:
        encode_reply(request, ReplyCode.INVALID)
    assert_malformed(info, "reply_code", 0)


# --- malformed packets: length prefix ------------------------------------------------------------


@pytest.mark.parametrize("length", [0, 11, -1, -(2**31), 1021, GIB])
@ORDERS
def test_bad_length_prefix_poisons_the_reader(length, big_endian):
    reader = PacketReader(big_endian=big_endian)
    good = encode(Ping(), big_endian=big_endian)
    prefix = struct.pack(fmt(big_endian) + "i", length)
    with pytest.raises(MalformedPacket, match="length prefix") as info:
        reader.feed(prefix)  # refused as soon as the prefix is in, without waiting for a body
    assert_malformed(info, "length", length)
    assert reader.poisoned
    for later in (good, b"", good + good):
        with pytest.raises(MalformedPacket) as again:
            reader.feed(later)
        assert_malformed(again, "length", length)
    with pytest.raises(MalformedPacket) as info:
        parse_packet(prefix + bytes(max(0, min(length, 2000))), big_endian=big_endian)
    assert_malformed(info, "length", length)


def test_length_prefix_limits():
    # 1020 bytes after the prefix: a 1024-byte packet, the most the reader accepts by default
    largest = frame(1300, 1, 0, bytes(1008))
    assert [p.msg_type for p in PacketReader().feed(largest)] == [1300]
    assert parse_packet(largest).body == bytes(1008)
    # a header alone (12) is the least
    assert PacketReader().feed(frame(1, 1, 0)) == [Packet(1, 1, 0, b"")]
    # a larger max_packet_bytes lets bigger packets through
    big = frame(12, 1, 0, bytes(52 * 30 + 4))
    assert len(PacketReader(max_packet_bytes=4096).feed(big)) == 1
    with pytest.raises(MalformedPacket) as info:
        PacketReader(max_packet_bytes=64).feed(frame(11, 2, 0, bytes(52)))
    assert_malformed(info, "length", 64)


@pytest.mark.parametrize("bad", [0, 15, 1.5, True, None])
def test_reader_max_packet_bytes_must_hold_a_header(bad):
    with pytest.raises(ValueError):
        PacketReader(max_packet_bytes=bad)


@pytest.mark.parametrize(("data", "value"), [
    (b"", 0), (b"\x10\x00", 2),  # no whole prefix
])
def test_parse_packet_needs_a_prefix(data, value):
    with pytest.raises(MalformedPacket) as info:
        parse_packet(data)
    assert_malformed(info, "length", value)


@pytest.mark.parametrize("extra", [-1, 1, 16])
def test_parse_packet_wants_exactly_one_packet(extra):
    data = encode(JointPosition(0, ()))
    data = data[:extra] if extra < 0 else data + bytes(extra)
    with pytest.raises(MalformedPacket, match="length prefix says 56 bytes follow") as info:
        parse_packet(data)
    assert_malformed(info, "length", 56)


# --- malformed messages: encode ------------------------------------------------------------------


@pytest.mark.parametrize(("message", "field", "value"), [
    (JointPosition(0, (0.0,) * 11), "positions", 11),
    (JointTrajPt(0, tuple(range(12)), 0.0, 0.0), "positions", 12),
    (JointTrajPtFull(0, 0, 0, 0.0, (), (0.0,) * 11, ()), "velocities", 11),
    (JointFeedback(0, 0, 0.0, (), (), (0.0,) * 11), "accelerations", 11),
    (JointPosition(2**31, ()), "sequence", 2**31),
    (JointPosition(-(2**31) - 1, ()), "sequence", -(2**31) - 1),
    (JointPosition(1.0, ()), "sequence", 1.0),
    (JointPosition(True, ()), "sequence", True),
    (RobotStatus(0, 0, 2**40, 0, 0, 0, 0), "error_code", 2**40),
    (JointTrajPtFull(2**31, 0, 0, 0.0, (), (), ()), "robot_id", 2**31),
    (JointFeedback(0, 0, 1e39, (), (), ()), "time", 1e39),
    (JointTrajPt(0, (), 3.5e38, 0.0), "velocity", 3.5e38),
    (JointTrajPt(0, (), 0.0, -1e300), "duration", -1e300),
    (JointTrajPt(0, (0.0, "1.0"), 0.0, 0.0), "positions", "1.0"),
    (JointTrajPt(0, (0.0, 0.0, 1e39), 0.0, 0.0), "positions", 1e39),
    (JointTrajPt(0, 1.0, 0.0, 0.0), "positions", 1.0),
    (JointTrajPt(0, "abc", 0.0, 0.0), "positions", "abc"),
    (JointTrajPt(0, (), None, 0.0), "velocity", None),
])
def test_encode_refuses_values_that_do_not_fit(message, field, value):
    with pytest.raises(MalformedPacket) as info:
        encode(message)
    assert_malformed(info, field, value)


def test_float32_range_matches_struct():
    largest = float(np.finfo(np.float32).max)
    assert decode(parse_packet(encode(JointTrajPt(0, (), largest, -largest)))).velocity == largest
    with pytest.raises(MalformedPacket):
        encode(JointTrajPt(0, (), largest * 2, 0.0))


def test_encode_refuses_a_non_message():
    with pytest.raises(TypeError):
        encode(object())


def test_packet_body_must_be_bytes():
    assert Packet(1, 1, 0, bytearray(b"ab")).body == b"ab"
    with pytest.raises(MalformedPacket) as info:
        Packet(1, 1, 0, "ab")
    assert_malformed(info, "body", "ab")


# --- replies (facts §3) ---------------------------------------------------------------------------


@ORDERS
def test_encode_reply_echoes_the_body_and_keeps_the_type(big_endian):
    request = parse_packet(encode(POINT, CommType.SERVICE_REQUEST, big_endian=big_endian),
                           big_endian=big_endian)
    data = encode_reply(request, ReplyCode.SUCCESS, big_endian=big_endian)
    assert len(data) == 68
    assert data == frame(11, 3, 1, point_body(big_endian), big_endian=big_endian)
    reply = parse_packet(data, big_endian=big_endian)
    assert (reply.msg_type, reply.comm_type, reply.reply_code) == (MsgType.JOINT_TRAJ_PT, 3, 1)
    assert decode(reply, big_endian=big_endian) == decode(request, big_endian=big_endian)


@ORDERS
def test_generic_failure_reply_has_an_empty_body(big_endian):
    request = PacketReader(big_endian=big_endian).feed(
        frame(1300, 2, 0, bytes(8), big_endian=big_endian))[0]
    data = encode_reply(request, ReplyCode.FAILURE, echo_body=False, big_endian=big_endian)
    assert data == frame(1300, 3, 2, big_endian=big_endian)
    assert len(data) == 16


def test_encode_reply_refuses_a_body_the_reference_would_not_send():
    request = PacketReader(max_packet_bytes=4096).feed(frame(12, 2, 0, bytes(1008)))[0]
    with pytest.raises(MalformedPacket) as info:
        encode_reply(request, ReplyCode.SUCCESS)
    assert_malformed(info, "length", 1024)
    assert len(encode_reply(request, ReplyCode.FAILURE, echo_body=False)) == 16


# --- PacketReader ---------------------------------------------------------------------------------


def stream(big_endian: bool) -> tuple[bytes, list[Packet]]:
    """A few packets of every kind back to back, and the packets they are."""
    parts = [encode(message, comm, big_endian=big_endian)
             for message in MESSAGES for comm in (CommType.TOPIC, CommType.SERVICE_REQUEST)]
    parts.append(frame(1300, 2, 0, bytes(range(20)), big_endian=big_endian))
    parts.append(frame(11, 3, 2, big_endian=big_endian))
    return b"".join(parts), [parse_packet(part, big_endian=big_endian) for part in parts]


@ORDERS
def test_a_stream_split_at_every_byte_gives_the_same_packets(big_endian):
    data, packets = stream(big_endian)
    assert PacketReader(big_endian=big_endian).feed(data) == packets
    for cut in range(len(data) + 1):
        reader = PacketReader(big_endian=big_endian)
        assert reader.feed(data[:cut]) + reader.feed(data[cut:]) == packets
        assert reader.buffered == 0
    reader = PacketReader(big_endian=big_endian)
    got = [packet for i in range(len(data)) for packet in reader.feed(data[i:i + 1])]
    assert got == packets


def test_two_packets_in_one_feed_and_a_partial_one_kept():
    first, second = encode(Ping()), encode(RobotStatus(1, 0, 0, 0, 0, 2, 1))
    third = encode(JointPosition(5, (1.0,)))
    reader = PacketReader()
    got = reader.feed(first + second + third[:30])
    assert [p.msg_type for p in got] == [MsgType.PING, MsgType.STATUS]
    assert reader.buffered == 30
    (last,) = reader.feed(third[30:])
    assert decode(last) == JointPosition(5, f32s([1.0]))


def test_unknown_msg_type_with_a_valid_header_is_returned():
    data = frame(1300, 2, 0, b"vendor!!") + frame(12, 1, 0, bytes(56)) + frame(20, 1, 0)
    packets = PacketReader().feed(data)
    assert packets == [Packet(1300, 2, 0, b"vendor!!"), Packet(12, 1, 0, bytes(56)), Packet(20, 1, 0, b"")]
    assert packets[0].msg_type == 1300 and packets[1].msg_type is MsgType.JOINT_TRAJ


def test_header_error_after_good_packets_loses_nothing():
    good, bad, after = encode(Ping()), frame(11, 1, 1, bytes(52)), encode(JointPosition(1, ()))
    reader = PacketReader()
    assert reader.feed(good + good + bad + after) == [Packet(1, 1, 0, b"")] * 2
    with pytest.raises(MalformedPacket) as info:
        reader.feed(b"")
    assert_malformed(info, "reply_code", 1)
    assert [p.msg_type for p in reader.feed(b"")] == [MsgType.JOINT_POSITION]


def test_length_error_after_good_packets_returns_them_then_poisons():
    reader = PacketReader()
    assert reader.feed(encode(Ping()) + struct.pack("<i", GIB)) == [Packet(1, 1, 0, b"")]
    assert reader.poisoned
    for _ in range(2):
        with pytest.raises(MalformedPacket) as info:
            reader.feed(encode(Ping()))
        assert_malformed(info, "length", GIB)


# --- property: arbitrary bytes never raise anything but MalformedPacket ---------------------------


@settings(max_examples=400, deadline=None)
@given(data=st.binary(max_size=600), cuts=st.lists(st.integers(0, 600), max_size=12),
       big_endian=st.booleans())
def test_arbitrary_bytes_give_packets_or_malformed_packet(data, cuts, big_endian):
    reader = PacketReader(big_endian=big_endian, max_packet_bytes=256)
    bounds = sorted({0, len(data), *(c for c in cuts if c <= len(data))})
    poisoned = None
    for start, end in [*zip(bounds, bounds[1:]), (len(data), len(data))]:
        try:
            packets = reader.feed(data[start:end])
        except MalformedPacket as error:
            assert error.field in {"length", "msg_type", "comm_type", "reply_code"}
            if poisoned is not None:
                assert (error.field, error.value) == poisoned
            if reader.poisoned:
                poisoned = (error.field, error.value)
            continue
        assert poisoned is None
        for packet in packets:
            assert isinstance(packet, Packet) and len(packet.body) <= 256 - 16
            try:
                decode(packet, big_endian=big_endian)
            except MalformedPacket as error:
                assert error.field in {"msg_type", "body"}


@settings(max_examples=200, deadline=None)
@given(picks=st.lists(st.sampled_from(range(len(MESSAGES))), min_size=1, max_size=8),
       cuts=st.lists(st.integers(0, 2000), max_size=10), big_endian=st.booleans())
def test_valid_streams_cut_anywhere_give_their_messages(picks, cuts, big_endian):
    messages = [MESSAGES[i] for i in picks]
    data = b"".join(encode(m, big_endian=big_endian) for m in messages)
    reader = PacketReader(big_endian=big_endian)
    bounds = sorted({0, len(data), *(c for c in cuts if c <= len(data))})
    packets = [p for start, end in zip(bounds, bounds[1:]) for p in reader.feed(data[start:end])]
    assert [decode(p, big_endian=big_endian) for p in packets] == [
        expected_after_round_trip(m) for m in messages]

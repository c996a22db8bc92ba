"""The simulated controller's motion program: ROS-Industrial's streaming and download handshakes,
STOP, PING, refusals and flow control, packet in, reply and references out (no sockets)."""

from __future__ import annotations

import math
import struct
import threading

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jointctl.industrial_controller.interpolator import (
    ERROR_BAD_VELOCITY,
    ERROR_NOT_FINITE,
    ERROR_POSITION_LIMIT,
    JointLimits,
)
from jointctl.industrial_controller.program import (
    ERROR_MALFORMED_POINT,
    ERROR_NO_DOWNLOAD,
    ControllerProgram,
    MotionConnection,
)
from jointctl.wire.simple_message import (
    END_TRAJECTORY,
    START_TRAJECTORY_DOWNLOAD,
    STOP_TRAJECTORY,
    CommType,
    JointPosition,
    JointTrajPt,
    MsgType,
    Packet,
    Ping,
    ReplyCode,
    encode,
    parse_packet,
)

# Two joints: range [-1, 1], 1 rad/s, stop at 5 rad/s²; range [-2, 2], 0.5 rad/s, stop at 2 rad/s².
LIMITS = (JointLimits(-1.0, 1.0, 1.0, 5.0), JointLimits(-2.0, 2.0, 0.5, 2.0))
DT = 0.001
REQUEST, TOPIC = CommType.SERVICE_REQUEST, CommType.TOPIC


def point(seq: int, positions, duration: float = 0.0, velocity: float = 1.0, *, comm=REQUEST,
          big_endian: bool = False) -> Packet:
    return parse_packet(encode(JointTrajPt(seq, tuple(positions), velocity, duration), comm,
                               big_endian=big_endian), big_endian=big_endian)


def reply_code(reply: bytes, big_endian: bool = False) -> int:
    packet = parse_packet(reply, big_endian=big_endian)
    assert packet.comm_type == CommType.SERVICE_REPLY
    return packet.reply_code


def run(program: ControllerProgram, seconds: float) -> tuple[list[float], list[float]]:
    q = v = None
    for _ in range(round(seconds / DT)):
        q, v, _ = program.cycle(DT)
    return q, v


def test_streamed_points_are_queued_answered_and_followed_in_their_durations() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    for seq, (q, d) in enumerate([((0.0, 0.0), 0.0), ((0.5, 0.2), 1.0), ((0.5, 0.4), 0.5)]):
        request = point(seq, q, d)
        reply = program.handle(request)
        assert reply_code(reply) == ReplyCode.SUCCESS
        assert parse_packet(reply).body == request.body  # the request echoed, as toReply does
    assert program.accepted == 3 and program.in_motion
    q, v = run(program, 0.5)
    assert q == pytest.approx([0.25, 0.1], abs=1e-6) and v == pytest.approx([0.5, 0.2])
    q, _ = run(program, 1.0)
    assert q == pytest.approx([0.5, 0.4], abs=1e-6)
    assert not program.in_motion
    assert program.status().in_motion == 0 and program.status(joints_moving=True).in_motion == 1


def test_a_full_queue_holds_the_reply_until_the_robot_takes_a_point() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0], capacity=2)
    for seq in range(3):  # the first goes into motion at the first cycle; two wait in the queue
        assert reply_code(program.handle(point(seq, (0.1 * seq, 0.0), 0.1))) == ReplyCode.SUCCESS
        if seq == 0:
            program.cycle(DT)
    replies = []
    sender = threading.Thread(target=lambda: replies.append(program.handle(point(3, (0.3, 0.0), 0.1))))
    sender.start()
    sender.join(0.3)
    assert sender.is_alive() and replies == []  # held back: the queue is full
    run(program, 0.1)  # the first segment ends: a slot frees
    sender.join(2.0)
    assert not sender.is_alive() and reply_code(replies[0]) == ReplyCode.SUCCESS
    q, _ = run(program, 0.4)
    assert q == pytest.approx([0.3, 0.0], abs=1e-6)


def test_a_held_point_is_dropped_without_reply_when_its_connection_goes() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0], capacity=1)
    program.handle(point(0, (0.2, 0.0), 1.0))
    program.cycle(DT)
    program.handle(point(1, (0.4, 0.0), 1.0))
    assert program.handle(point(2, (0.6, 0.0), 1.0), keep_waiting=lambda: False) is None
    q, _ = run(program, 3.0)
    assert q == pytest.approx([0.4, 0.0], abs=1e-6)  # the dropped point was never executed


def test_sequence_zero_starts_a_new_trajectory_from_where_the_reference_is() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    program.handle(point(0, (0.0, 0.0)))
    program.handle(point(1, (0.8, 0.0), 1.0))
    program.handle(point(2, (0.9, 0.0), 1.0))
    q_then, _ = run(program, 0.5)
    program.handle(point(0, q_then))
    program.handle(point(1, (-0.5, 0.0), 2.0))
    q, _ = run(program, 3.0)
    assert q == pytest.approx([-0.5, 0.0], abs=1e-6)  # 0.8 and 0.9 forgotten


def test_a_download_moves_nothing_until_its_end_then_runs_every_point() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    for seq, q, d in ((START_TRAJECTORY_DOWNLOAD, (0.0, 0.0), 0.0), (1, (0.4, 0.0), 0.5), (2, (0.4, 0.3), 0.6),
                      (END_TRAJECTORY, (0.2, 0.3), 0.2)):
        assert program.handle(point(seq, q, d, comm=TOPIC)) is None  # topics: no replies
        if seq != END_TRAJECTORY:
            assert run(program, 0.1)[0] == [0.0, 0.0] and not program.in_motion
    assert program.in_motion
    q, _ = run(program, 0.5)
    assert q == pytest.approx([0.4, 0.0], abs=1e-6)
    q, _ = run(program, 0.6)
    assert q == pytest.approx([0.4, 0.3], abs=1e-6)
    q, _ = run(program, 0.3)
    assert q == pytest.approx([0.2, 0.3], abs=1e-6) and program.accepted == 4


def test_a_download_longer_than_the_queue_flows_through_it() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0], capacity=2)
    program.handle(point(START_TRAJECTORY_DOWNLOAD, (0.0, 0.0), comm=TOPIC))
    for seq in range(1, 10):
        program.handle(point(seq, (0.05 * seq, 0.0), 0.1, comm=TOPIC))
    program.handle(point(END_TRAJECTORY, (0.5, 0.1), 0.2, comm=TOPIC))
    q, _ = run(program, 1.5)
    assert q == pytest.approx([0.5, 0.1], abs=1e-6) and not program.in_motion


def test_a_download_with_a_refused_point_moves_nothing_and_reports_the_error() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    program.handle(point(START_TRAJECTORY_DOWNLOAD, (0.0, 0.0), comm=TOPIC))
    program.handle(point(1, (0.5, 3.0), 1.0, comm=TOPIC))  # joint 2 beyond its range
    program.handle(point(END_TRAJECTORY, (0.5, 0.0), 1.0, comm=TOPIC))
    assert run(program, 1.0)[0] == [0.0, 0.0] and not program.in_motion
    status = program.status()
    assert (status.in_error, status.error_code) == (1, ERROR_POSITION_LIMIT)


def test_an_end_without_a_start_is_refused() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    assert reply_code(program.handle(point(END_TRAJECTORY, (0.5, 0.0), 1.0))) == ReplyCode.FAILURE
    assert program.error_code == ERROR_NO_DOWNLOAD and run(program, 0.5)[0] == [0.0, 0.0]


def test_stop_brakes_at_each_joints_deceleration_clears_the_queue_and_is_answered() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    program.handle(point(0, (0.0, 0.0)))
    program.handle(point(1, (0.9, 1.8), 0.0))  # at the limits: 1 and 0.5 rad/s
    program.handle(point(2, (-0.9, 0.0), 5.0))
    q0, v0 = run(program, 0.5)
    assert v0 == pytest.approx([0.25, 0.5])  # joint 1 slowed to joint 2's pace (both arrive together)
    assert reply_code(program.handle(point(STOP_TRAJECTORY, ()))) == ReplyCode.SUCCESS
    _, v = run(program, 0.04)
    assert v == pytest.approx([0.25 - 5.0 * 0.04, 0.5 - 2.0 * 0.04], abs=1e-9)
    q, v = run(program, 1.0)
    assert v == [0.0, 0.0] and not program.in_motion
    # v²/2a past where the stop began: 0.00625 rad and 0.0625 rad; the queued -0.9 point is gone.
    assert q == pytest.approx([q0[0] + 0.00625, q0[1] + 0.0625], abs=1e-6)
    # Points of the stopped trajectory move nothing; a new one does.
    assert reply_code(program.handle(point(3, (0.0, 0.0), 0.5))) == ReplyCode.FAILURE
    assert run(program, 1.0)[0] == q
    assert program.status().in_error == 0  # a stop is no error
    program.handle(point(0, q))
    program.handle(point(1, (0.0, 0.0), 5.0))
    assert run(program, 5.5)[0] == pytest.approx([0.0, 0.0], abs=1e-6)


@pytest.mark.parametrize("positions, velocity, code", [
    ((0.5, 2.5), 0.0, ERROR_POSITION_LIMIT),
    ((math.nan, 0.0), 0.0, ERROR_NOT_FINITE),
    ((0.5, math.inf), 0.0, ERROR_NOT_FINITE),
    ((0.5, 0.0), 1.5, ERROR_BAD_VELOCITY),
])
def test_a_refused_point_moves_nothing_and_sets_in_error_until_a_new_trajectory(positions, velocity, code) -> None:
    program = ControllerProgram(LIMITS, [0.1, -0.1])
    program.handle(point(0, (0.1, -0.1)))
    assert reply_code(program.handle(point(1, positions, 1.0, velocity))) == ReplyCode.FAILURE
    assert reply_code(program.handle(point(2, (0.3, 0.0), 1.0))) == ReplyCode.FAILURE  # the same trajectory
    assert run(program, 2.0)[0] == [0.1, -0.1]
    status = program.status()
    assert (status.in_error, status.error_code, status.in_motion) == (1, code, 0)
    assert program.refused == 1
    assert reply_code(program.handle(point(0, (0.1, -0.1)))) == ReplyCode.SUCCESS
    assert program.status().in_error == 0
    program.handle(point(1, (0.3, 0.0), 1.0))
    assert run(program, 1.5)[0] == pytest.approx([0.3, 0.0], abs=1e-6)


def test_a_refusal_while_moving_brakes_instead_of_halting() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    program.handle(point(0, (0.0, 0.0)))
    program.handle(point(1, (0.9, 0.0), 0.0))
    _, v = run(program, 0.3)
    assert v[0] == pytest.approx(1.0)
    program.handle(point(2, (math.nan, 0.0), 0.1))
    _, v, _ = program.cycle(DT)
    assert v[0] == pytest.approx(1.0 - 5.0 * DT)  # decelerating, not stopped dead
    q, v = run(program, 1.0)
    assert v == [0.0, 0.0] and q[0] == pytest.approx(0.3 + DT + 0.1, abs=2e-3)  # v²/2a = 0.1 rad


def test_a_point_with_a_malformed_body_is_refused() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    short = Packet(MsgType.JOINT_TRAJ_PT, REQUEST, 0, b"\x00" * 20)
    assert reply_code(program.handle(short)) == ReplyCode.FAILURE
    assert program.error_code == ERROR_MALFORMED_POINT


def test_the_joint_count_is_the_controllers_and_padding_beyond_it_is_ignored() -> None:
    program = ControllerProgram(LIMITS[:1], [0.0])
    program.handle(point(0, (0.0,)))
    assert reply_code(program.handle(point(1, (0.5, 99.0), 1.0))) == ReplyCode.SUCCESS  # joint 2 is padding
    assert run(program, 1.0)[0] == pytest.approx([0.5])


def test_ping_is_answered_other_requests_fail_and_topics_and_replies_are_ignored() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    ping = parse_packet(encode(Ping(), REQUEST))
    assert reply_code(program.handle(ping)) == ReplyCode.SUCCESS
    assert reply_code(program.handle(Packet(MsgType.PING, REQUEST, 0, b"\x01\x00\x00\x00"))) == ReplyCode.FAILURE
    state_request = parse_packet(encode(JointPosition(0, (0.5, 0.5)), REQUEST))
    reply = program.handle(state_request)
    assert reply_code(reply) == ReplyCode.FAILURE and parse_packet(reply).body == b""
    assert reply_code(program.handle(Packet(99, REQUEST, 0, b"abcd"))) == ReplyCode.FAILURE
    assert program.handle(parse_packet(encode(JointPosition(0, (0.5, 0.5)), TOPIC))) is None
    assert program.handle(Packet(MsgType.JOINT_TRAJ_PT, CommType.SERVICE_REPLY, 1, b"")) is None
    assert run(program, 0.5)[0] == [0.0, 0.0] and program.error_code == 0


def test_a_lost_connection_stops_the_motion() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    program.handle(point(0, (0.0, 0.0)))
    program.handle(point(1, (0.9, 0.0), 0.0))
    q0, _ = run(program, 0.2)
    program.connection_lost()
    q, v = run(program, 1.0)
    assert v == [0.0, 0.0] and q[0] == pytest.approx(q0[0] + 0.1, abs=1e-6)


def test_big_endian_requests_get_big_endian_replies() -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0], big_endian=True)
    reply = program.handle(point(0, (0.0, 0.0), big_endian=True))
    assert reply[:4] == struct.pack(">i", 64) and reply_code(reply, big_endian=True) == ReplyCode.SUCCESS
    program.handle(point(1, (0.5, 0.0), 0.5, big_endian=True))
    assert run(program, 0.6)[0] == pytest.approx([0.5, 0.0])


# -- the byte stream -------------------------------------------------------------------------------
def test_a_connection_answers_packets_split_anywhere_and_skips_a_bad_header() -> None:
    connection = MotionConnection(ControllerProgram(LIMITS, [0.0, 0.0]))
    bad_header = struct.pack("<4i", 12, 11, 7, 0)  # comm_type 7
    stream = encode(Ping(), REQUEST) + bad_header + encode(JointTrajPt(0, (0.0, 0.0), 1.0, 0.0), REQUEST)
    replies = []
    for k in range(0, len(stream), 5):
        replies += connection.feed(stream[k:k + 5])
    assert [parse_packet(r).msg_type for r in replies] == [MsgType.PING, MsgType.JOINT_TRAJ_PT]
    assert connection.skipped == 1 and not connection.closed


@pytest.mark.parametrize("length", [0, 11, 1 << 30, -5])
def test_a_lying_length_prefix_closes_the_connection_and_moves_nothing(length) -> None:
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    connection = MotionConnection(program)
    assert connection.feed(struct.pack("<i", length) + b"\x0b\x00\x00\x00" * 20) == []
    assert connection.closed
    assert run(program, 0.2)[0] == [0.0, 0.0]


_REFUSED_POINTS = st.builds(
    lambda seq, positions, bad, velocity, duration: JointTrajPt(seq, tuple(positions[:1]) + (bad,), velocity, duration),
    st.integers(-(2**31), 2**31 - 1), st.lists(st.floats(-1.0, 1.0), min_size=1, max_size=1),
    st.one_of(st.just(math.nan), st.just(math.inf), st.floats(2.0001, 1e30), st.floats(-1e30, -2.0001)),
    st.floats(0.0, 1.0), st.floats(0.0, 10.0))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.one_of(
    st.binary(max_size=200),
    _REFUSED_POINTS.map(lambda p: encode(p, REQUEST)),
    _REFUSED_POINTS.map(lambda p: encode(p, TOPIC)),
    st.builds(lambda t, c, body: struct.pack("<4i", 12 + len(body), t, c, 0) + body,
              st.integers(-3, 30).filter(lambda t: t != MsgType.JOINT_TRAJ_PT), st.integers(0, 4),
              st.binary(max_size=60)),
), max_size=12), st.integers(1, 17))
def test_no_byte_stream_of_refused_points_and_garbage_raises_or_moves_the_robot(chunks, cut) -> None:
    """Whatever arrives, nothing raises, the robot stays where it is, and a new client is served."""
    program = ControllerProgram(LIMITS, [0.25, -0.5])
    connection = MotionConnection(program, keep_waiting=lambda: False)
    stream = b"".join(chunks)
    for k in range(0, len(stream), cut):
        for reply in connection.feed(stream[k:k + cut]):
            parse_packet(reply)  # every reply is a well-formed packet
        if connection.closed:
            break
    assert run(program, 0.05)[0] == [0.25, -0.5] and not program.in_motion
    program.connection_lost()
    fresh = MotionConnection(program)
    replies = fresh.feed(encode(JointTrajPt(0, (0.25, -0.5), 1.0, 0.0), REQUEST)
                         + encode(JointTrajPt(1, (0.0, 0.0), 1.0, 1.0), REQUEST))
    assert [reply_code(r) for r in replies] == [ReplyCode.SUCCESS, ReplyCode.SUCCESS]
    assert run(program, 1.1)[0] == pytest.approx([0.0, 0.0], abs=1e-6)


def test_stops_and_refusals_are_logged_one_line_each_naming_field_and_value() -> None:
    lines: list[str] = []
    program = ControllerProgram(LIMITS, [0.0, 0.0], on_event=lines.append)
    program.handle(point(0, (0.0, 0.0)))
    program.handle(point(1, (0.5, 7.5), 1.0))
    program.handle(point(STOP_TRAJECTORY, ()))
    assert lines == ["refused a point (error_code 1): positions[1]: outside the joint's range [-2, 2] (got 7.5); "
                     "the trajectory is stopped", "STOP: decelerating to rest, queue cleared"]


# -- JOINT_TRAJ_PT_FULL: points by their time ---------------------------------------------------------------

def full_point(seq: int, time_s: float, positions, velocities=None, fields=None):
    from jointctl.wire.simple_message import VALID_POSITION, VALID_TIME, VALID_VELOCITY, JointTrajPtFull

    if fields is None:
        fields = VALID_TIME | VALID_POSITION | (VALID_VELOCITY if velocities is not None else 0)
    message = JointTrajPtFull(0, seq, fields, time_s, tuple(positions), tuple(velocities or (0.0, 0.0)), (0.0, 0.0))
    return parse_packet(encode(message, REQUEST))


def test_full_points_are_reached_at_their_times_from_the_trajectorys_start():
    F32 = 1e-7  # positions and times went through float32
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    for seq, t, q in ((0, 1.0, (0.2, 0.1)), (1, 3.0, (0.6, 0.1))):  # 1 s, then 2 s: both within the limits
        reply = program.handle(full_point(seq, t, q))
        assert reply_code(reply) == ReplyCode.SUCCESS
        assert parse_packet(reply).msg_type == 14  # the answer is of the request's type
    q, _ = run(program, 1.0)
    assert q == pytest.approx([0.2, 0.1], abs=F32)
    q, v = run(program, 1.0)
    assert q[0] == pytest.approx(0.4, abs=F32) and v[0] == pytest.approx(0.2, rel=1e-6)  # half of 0.4 rad in 2 s
    q, v = run(program, 1.0)
    assert q == pytest.approx([0.6, 0.1], abs=F32) and v == [0.0, 0.0]
    # a new trajectory counts its times from its own start again
    program.handle(full_point(0, 0.5, (0.5, 0.1)))
    q, _ = run(program, 0.5)
    assert q == pytest.approx([0.5, 0.1], abs=F32)


def test_a_full_point_without_its_time_is_refused_and_moves_nothing():
    from jointctl.wire.simple_message import VALID_POSITION

    program = ControllerProgram(LIMITS, [0.0, 0.0])
    assert reply_code(program.handle(full_point(0, 1.0, (0.5, 0.0), fields=VALID_POSITION))) == ReplyCode.FAILURE
    assert program.error_code == ERROR_MALFORMED_POINT
    assert run(program, 1.2)[0] == [0.0, 0.0]


def test_a_speed_fraction_of_zero_is_refused_as_a_real_controller_does():
    program = ControllerProgram(LIMITS, [0.0, 0.0])
    assert reply_code(program.handle(point(0, (0.5, 0.0), 1.0, velocity=0.0))) == ReplyCode.FAILURE
    assert program.error_code == ERROR_BAD_VELOCITY
    assert run(program, 1.2)[0] == [0.0, 0.0]

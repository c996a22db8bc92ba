"""IndustrialHardware against a controller double that speaks simple_message on loopback
(tests/hardware/controller_doubles.py, the "duration" kind): what the PC side sends and how it reads
the state, checked packet by packet. (The simulated industrial controller, a real robot in MuJoCo
behind the same protocol, is tested with it in tests/industrial.)"""

from __future__ import annotations

import functools
import math
import socket

import numpy as np
import pytest

from jointctl.hardware.industrial import HardwareUnreachable, IndustrialHardware
from jointctl.hardware.interface import POSITION
from jointctl.wire.simple_message import STOP_TRAJECTORY
from tests.hardware.controller_doubles import ERROR_RANGE, ERROR_TOO_FAST, ControllerDouble, asked_values
from tests.waiting import wait_until

JOINTS = ("a", "b")
TIMEOUT_S = 10.0


wait_for = functools.partial(wait_until, timeout_s=TIMEOUT_S, every_s=0.005)


@pytest.fixture
def peer():
    # Little-endian only: the byte order is covered by the codec tests and, over a socket, by
    # tests/industrial/test_controller.py's streaming handshake in both orders.
    p = ControllerDouble()
    yield p
    p.close()


def connected(peer: ControllerDouble, **kwargs) -> IndustrialHardware:
    hw = IndustrialHardware(JOINTS, robot_ip="127.0.0.1", motion_port=peer.motion_port,
                            state_port=peer.state_port, big_endian=peer.big_endian, **kwargs)
    hw.connect()
    return hw


def cycle(hw: IndustrialHardware, cycles: int = 1, period_s: float = 0.001) -> None:
    for _ in range(cycles):
        hw.read()
        hw.write()
        hw.advance(period_s)


def test_state_is_read_as_reported_and_the_command_starts_there(peer) -> None:
    hw = connected(peer)
    try:
        assert hw.command_interfaces("a") == frozenset({POSITION})
        assert hw.position == pytest.approx([0.1, -0.2], abs=1e-7)  # float32 on the wire
        assert hw.command_buffer(POSITION) == hw.position
        assert hw.fault is None
        wait_for(lambda: hw.status is not None, "the first STATUS")  # it follows the first JOINT_POSITION
        assert hw.status.mode == 2 and hw.status.in_motion == 0
        peer.place([0.3, -0.2])
        wait_for(lambda: (hw.read(), hw.position[0])[1] == pytest.approx(0.3, abs=1e-7), "the new state")
        cycle(hw, 20)
        hw.command_buffer(POSITION)[:] = [0.3, -0.25]  # a changed command: sent, after anything the unchanged one sent
        cycle(hw, 20)
        wait_for(lambda: len(peer.points) >= 1, "the changed command")
        assert [p.positions[:2] for p in peer.points] == [pytest.approx((0.3, -0.25), abs=1e-7)]
    finally:
        hw.close()


def test_a_motion_streams_points_at_the_stream_rate_from_sequence_zero(peer) -> None:
    hw = connected(peer, stream_rate_hz=50.0, max_velocities=(2.0, 1.0))
    try:
        command = hw.command_buffer(POSITION)
        for k in range(100):  # 100 ms of loop time, the command moving every cycle, 1 mm from the robot's 0.1
            command[:] = [0.1 + 0.001 * (k + 1), -0.2]
            cycle(hw)
        wait_for(lambda: len(peer.points) == 5, "five points")
        assert [p.sequence for p in peer.points] == [0, 1, 2, 3, 4]  # one every 20 ms, a new trajectory
        assert all(p.duration == pytest.approx(0.02) for p in peer.points)
        # ROS-I's speed fraction of each point's velocity: the largest |v / vmax| over the joints, clipped to
        # [0, 1] (simple-message-facts, calc_velocity). Δq / period = 0.02 m / 0.02 s = 1 m/s on joint a, against
        # its limit of 2: 0.5. The first point moves the command from where the robot is (as reported, in
        # float32): 0.101 - 0.1 = 1 mm in 0.02 s, 0.05 m/s of 2, 0.025 (joint b, at its report's -0.2, moves by
        # float32's rounding only, 3e-9 m: 1.5e-7 of its limit).
        reported = [float(np.float32(0.1)), float(np.float32(-0.2))]
        first = max(abs(0.101 - reported[0]) / 0.02 / 2.0, abs(-0.2 - reported[1]) / 0.02 / 1.0)
        assert first == pytest.approx(0.025, rel=1e-4)
        assert peer.points[0].velocity == pytest.approx(first, rel=1e-6)
        assert [p.velocity for p in peer.points[1:]] == pytest.approx([0.5] * 4, rel=1e-5)
        # Each point carries the command of the cycle it was sent in (t = 0, 20, 40... ms).
        assert [p.positions[0] for p in peer.points] == pytest.approx(
            [0.1 + 0.001 * (k + 1) for k in (0, 20, 40, 60, 80)], abs=1e-6)
        assert all(p.positions[2:] == (0.0,) * 8 for p in peer.points)  # padded to ten joints
        wait_for(lambda: hw.replies == 5, "the five replies")
    finally:
        hw.close()


def test_stop_motion_sends_stop_and_the_next_motion_starts_a_new_trajectory(peer) -> None:
    hw = connected(peer)
    try:
        command = hw.command_buffer(POSITION)
        command[0] = 0.2
        cycle(hw, 25)
        wait_for(lambda: len(peer.points) == 1, "the first point")
        hw.stop_motion()
        wait_for(lambda: len(peer.points) == 2, "the stop")
        assert peer.points[1].sequence == STOP_TRAJECTORY
        # "stopping" until the peer's next STATUS (in_motion 0) after its reply (tested against the
        # simulated controller in tests/industrial/test_controller.py).
        wait_for(lambda: (hw.read(), hw.fault is None)[1], "the stop to be over")
        command[0] = 0.25
        cycle(hw, 20)
        wait_for(lambda: len(peer.points) == 3, "the next motion")
        assert peer.points[2].sequence == 0
    finally:
        hw.close()


def test_flow_control_holds_the_next_point_until_the_reply(peer) -> None:
    hw = connected(peer)
    try:
        peer.hold.set()
        command = hw.command_buffer(POSITION)
        for k in range(100):
            command[0] = 0.1 + 0.001 * k
            cycle(hw)
        wait_for(lambda: len(peer.points) == 1, "the first point")
        # The four later points exist and wait in the hardware's outbox behind the held reply (the
        # positive evidence that they would have been sent, had the sender not waited).
        wait_for(lambda: hw._outbox.qsize() == 4, "the four later points queued behind the held reply")
        assert len(peer.points) == 1 and hw.replies == 0
        peer.hold.clear()
        wait_for(lambda: len(peer.points) == 5, "the held points")
        assert [p.sequence for p in peer.points] == [0, 1, 2, 3, 4]
    finally:
        hw.close()


def test_the_controllers_full_buffer_holds_the_stream_back(peer) -> None:
    # A controller with room for 8 waiting points, each taking 10 s: the first runs, 8 wait, the
    # reply to the 10th is held, and the hardware's sender waits for it: the rest wait at the PC.
    hw = connected(peer, stream_rate_hz=0.1)
    try:
        command = hw.command_buffer(POSITION)
        for k in range(20):  # 200 s of loop time: 20 points, one every 10 s, each 1 mm further
            command[0] = 0.1 + 0.001 * (k + 1)
            cycle(hw, 1000, period_s=0.01)
        held = peer.capacity + 2
        wait_for(lambda: len(peer.points) == held and hw._outbox.qsize() == 20 - held,
                 "the buffer full, a reply held and the rest waiting at the PC")
        assert hw.replies == held - 1 and peer.moving
        wait_for(lambda: (hw.read(), hw.in_motion)[1] is True, "STATUS in_motion 1 from the moving controller")
    finally:
        hw.close()


@pytest.mark.parametrize("command, code, joint", [
    ((0.3, -0.2), ERROR_TOO_FAST, "a"),       # 0.2 m in one 20 ms stream period: 10 m/s, its limit 1 m/s
    ((0.1, math.nan), ERROR_RANGE, "b"),       # not a number: outside every range
    ((0.1, -1.5), ERROR_RANGE, "b"),           # beyond the controller's soft limit of -1 m (25 m/s, too)
])
def test_a_streamed_command_the_controller_refuses_is_a_fault_naming_the_joint_and_is_not_sent_again(
        command, code, joint) -> None:
    # A controller with soft limits [-1, 1] m and speed limits of 1 m/s, at rest at (0.1, -0.2), refuses the
    # command streamed as a point; the hardware reports it naming the joint and the value asked, does not send
    # the refused command again while it stays, and the robot holds. The next command is sent as a new
    # trajectory from where the robot is.
    double = ControllerDouble(max_velocities=(1.0, 1.0), ranges=((-1.0, 1.0), (-1.0, 1.0)))
    hw = connected(double, max_velocities=(1.0, 1.0))
    try:
        hw.command_buffer(POSITION)[:] = command
        fault = wait_for(lambda: (cycle(hw), hw.fault)[1], "the refusal")
        assert f"the controller refused point 0 of the trajectory (FAILURE; STATUS error_code {code})" in fault
        asked = asked_values(fault, JOINTS)[joint]
        reported = float(np.float32(0.1 if joint == "a" else -0.2))
        value = command[JOINTS.index(joint)]
        if math.isnan(value):
            assert math.isnan(asked[0]) and math.isnan(asked[1])
        else:
            assert asked == pytest.approx((value, abs(value - reported) / 0.02), rel=1e-6)
        wait_for(lambda: (cycle(hw), hw.fault)[1] is None, "the fault over, the robot at rest")
        cycle(hw, 100)  # five stream periods with the refused command
        assert double.positions == pytest.approx([0.1, -0.2]) and not double.moving  # the robot held
        hw.command_buffer(POSITION)[:] = [0.105, -0.2]  # 5 mm: 0.25 m/s over the period
        wait_for(lambda: (cycle(hw), double.points[-1].positions[0] == pytest.approx(0.105))[1],
                 "the next command at the controller")
        # One sender, one connection: anything sent again would have arrived before the next command.
        assert [p.sequence for p in double.points] == [0, 0]
        assert double.points[0].positions[:2] == pytest.approx(command, nan_ok=True)
    finally:
        hw.close()
        double.close()


def test_stale_state_is_a_fault_until_state_flows_again(peer) -> None:
    hw = connected(peer, stale_after_s=0.2)
    try:
        cycle(hw)
        assert hw.fault is None
        peer.publishing.clear()
        wait_for(lambda: (hw.read(), hw.fault)[1] is not None, "the stale fault")
        assert "no joint state from 127.0.0.1" in hw.fault
        command = hw.command_buffer(POSITION)
        command[0] = 0.5  # must not be sent while faulted
        cycle(hw, 40)
        command[0] = 0.1  # back where it was: nothing to send once the state flows again
        peer.publishing.set()
        wait_for(lambda: (cycle(hw), hw.fault)[1] is None, "the state again")
        command[0] = 0.6
        cycle(hw, 40)
        wait_for(lambda: len(peer.points) >= 1 and peer.points[-1].positions[0] == pytest.approx(0.6),
                 "the command given once the state flows")
        # One sender, one connection: anything sent while faulted would have arrived before the 0.6.
        assert [p.positions[0] for p in peer.points] == [pytest.approx(0.6)]
    finally:
        hw.close()


def test_a_lost_motion_connection_is_a_fault_and_is_reopened(peer) -> None:
    # The loss is the fault of at least one read, however late that read comes (reopened meanwhile or not):
    # tests/industrial_controller/test_controller.py restarts the controller between two reads.
    hw = connected(peer, retry_s=0.5)
    try:
        command = hw.command_buffer(POSITION)
        command[0] = 0.2
        cycle(hw, 25)
        wait_for(lambda: hw.replies == 1, "the first point answered on the first connection")
        assert [c for c, _, _ in peer.received] == [0]
        peer.drop_connections()  # a FIN to the hardware on both connections
        command[0] = 0.3
        cycle(hw, 25)  # a point for the dead connection: its failure is the fault
        wait_for(lambda: (hw.read(), hw.fault)[1] is not None and "motion connection" in hw.fault,
                 "the lost motion connection as a fault")
        assert "lost the motion connection to 127.0.0.1" in hw.fault
        wait_for(lambda: len(peer.motion_connections) == 2, "the motion connection reopened")
        wait_for(lambda: (cycle(hw), hw.fault)[1] is None, "no fault once reopened")
        command[0] = 0.35
        cycle(hw, 25)
        wait_for(lambda: any(c == 1 for c, _, _ in peer.received), "a point on the new connection")
        on_new = [p for c, _, p in peer.received if c == 1]
        assert on_new[0].sequence == 0 and on_new[0].positions[0] == pytest.approx(0.35)  # a new trajectory
        wait_for(lambda: hw.replies == 1 + len(on_new), "its reply, over the new connection")
    finally:
        hw.close()


def test_a_motion_connection_closed_while_idle_is_reopened_before_the_next_motion(peer) -> None:
    # Nothing is sent while idle: the hardware must notice the closed connection by itself, or the next
    # motion's first point would find it dead and abort a goal the state said could start.
    hw = connected(peer, retry_s=0.05)
    try:
        cycle(hw, 5)
        wait_for(lambda: len(peer.motion_connections) == 1, "the double to accept the motion connection")
        peer.drop_motion()
        wait_for(lambda: len(peer.motion_connections) == 2, "the motion connection reopened while idle")
        wait_for(lambda: (cycle(hw), hw.fault)[1] is None, "no fault once reopened")
        hw.command_buffer(POSITION)[0] = 0.2
        cycle(hw, 25)
        wait_for(lambda: len(peer.points) == 1, "the first point")
        assert peer.received[0][0] == 1  # on the new connection
        cycle(hw)
        assert peer.points[0].sequence == 0 and hw.fault is None
    finally:
        hw.close()


def test_an_unreachable_controller_is_a_clear_error() -> None:
    with socket.socket() as bound:  # bound, not listening, and kept: nobody listens on its port
        bound.bind(("127.0.0.1", 0))
        port = bound.getsockname()[1]
        hw = IndustrialHardware(JOINTS, robot_ip="127.0.0.1", motion_port=port, state_port=port)
        with pytest.raises(HardwareUnreachable, match="no industrial controller answers on its state port") as info:
            hw.connect()
    assert info.value.field == "robot_ip" and info.value.value == f"127.0.0.1:{port}"


def test_bad_settings_are_refused_naming_the_field() -> None:
    with pytest.raises(Exception, match="1 to 10 joints"):
        IndustrialHardware([f"j{k}" for k in range(11)], robot_ip="127.0.0.1")
    with pytest.raises(Exception, match="must be positive") as info:
        IndustrialHardware(JOINTS, robot_ip="127.0.0.1", stream_rate_hz=0.0)
    assert info.value.field == "stream_rate_hz"

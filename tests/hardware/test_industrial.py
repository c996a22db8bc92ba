"""IndustrialHardware against a peer that speaks simple_message on loopback: what the PC side sends
and how it reads the state, checked packet by packet. (The simulated industrial controller, a
real robot in MuJoCo behind the same protocol, is tested with it in tests/industrial.)"""

from __future__ import annotations

import socket
import threading
import time

import pytest

from jointctl.hardware.industrial import HardwareUnreachable, IndustrialHardware
from jointctl.hardware.interface import POSITION
from jointctl.wire.simple_message import (
    STOP_TRAJECTORY,
    CommType,
    JointPosition,
    JointTrajPt,
    PacketReader,
    ReplyCode,
    RobotStatus,
    decode,
    encode,
    encode_reply,
)

JOINTS = ("a", "b")
TIMEOUT_S = 10.0


def wait_for(condition, what: str) -> None:
    deadline = time.monotonic() + TIMEOUT_S
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.005)


class Peer:
    """A controller double: state pushed every ``period_s`` from ``positions``; motion requests
    recorded and answered SUCCESS (or held while ``hold`` is set)."""

    def __init__(self, big_endian: bool = False, period_s: float = 0.01, positions=(0.1, -0.2),
                 follow: bool = False) -> None:
        self.big_endian, self.period_s = big_endian, period_s
        self.positions = list(positions)
        self.follow = follow  # jump to each point received (an ideal servo)
        self.step_per_report = 0.0  # added to the first joint after each JOINT_POSITION sent
        self.in_motion = 0
        self.points: list[JointTrajPt] = []
        self.hold = threading.Event()
        self.publishing = threading.Event()
        self.publishing.set()
        self.closing = threading.Event()
        self.servers = [socket.create_server(("127.0.0.1", 0)) for _ in range(2)]
        self.motion_port, self.state_port = (s.getsockname()[1] for s in self.servers)
        self.connections: list[socket.socket] = []
        self.motion_connections: list[socket.socket] = []
        self.threads = [threading.Thread(target=self._state, daemon=True),
                        threading.Thread(target=self._motion, daemon=True)]
        for thread in self.threads:
            thread.start()

    def _accept(self, server: socket.socket) -> socket.socket | None:
        while not self.closing.is_set():
            try:
                server.settimeout(0.1)
                conn, _ = server.accept()
            except TimeoutError:
                continue
            except OSError:  # closed by close()
                return None
            self.connections.append(conn)
            return conn
        return None

    def _state(self) -> None:
        while (conn := self._accept(self.servers[1])) is not None:
            try:
                while not self.closing.is_set():
                    if self.publishing.is_set():
                        conn.sendall(encode(JointPosition(0, tuple(self.positions)), big_endian=self.big_endian))
                        self.positions[0] += self.step_per_report
                        conn.sendall(encode(RobotStatus(1, 0, 0, 0, self.in_motion, 2, 1), big_endian=self.big_endian))
                    time.sleep(self.period_s)
            except OSError:
                continue

    def _motion(self) -> None:
        while (conn := self._accept(self.servers[0])) is not None:
            self.motion_connections.append(conn)
            reader = PacketReader(big_endian=self.big_endian)
            try:
                while not self.closing.is_set():
                    data = conn.recv(4096)
                    if not data:
                        break
                    for packet in reader.feed(data):
                        assert packet.comm_type == CommType.SERVICE_REQUEST
                        point = decode(packet, big_endian=self.big_endian)
                        self.points.append(point)
                        if self.follow and point.sequence >= 0:
                            self.positions = list(point.positions[: len(self.positions)])
                        while self.hold.is_set() and not self.closing.is_set():
                            time.sleep(0.005)
                        conn.sendall(encode_reply(packet, ReplyCode.SUCCESS, big_endian=self.big_endian))
            except OSError:
                continue

    def drop_motion(self) -> None:
        """Close the motion connection only (the state goes on)."""
        for conn in self.motion_connections:
            conn.shutdown(socket.SHUT_RDWR)  # a FIN now: close() alone waits for the thread blocked in recv
            conn.close()

    def drop_connections(self) -> None:
        for conn in self.connections:
            conn.close()
        self.connections.clear()

    def close(self) -> None:
        self.closing.set()
        self.drop_connections()
        for server in self.servers:
            server.close()
        for thread in self.threads:
            thread.join(2.0)


@pytest.fixture(params=[False, True], ids=["little-endian", "big-endian"])
def peer(request):
    p = Peer(big_endian=request.param)
    yield p
    p.close()


def connected(peer: Peer, **kwargs) -> IndustrialHardware:
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
        peer.positions = [0.3, -0.2]
        wait_for(lambda: (hw.read(), hw.position[0])[1] == pytest.approx(0.3, abs=1e-7), "the new state")
        cycle(hw, 20)
        assert peer.points == []  # an unchanged command sends nothing
    finally:
        hw.close()


def test_a_motion_streams_points_at_the_stream_rate_from_sequence_zero(peer) -> None:
    hw = connected(peer, stream_rate_hz=50.0)
    try:
        command = hw.command_buffer(POSITION)
        for k in range(100):  # 100 ms of loop time, the command moving every cycle
            command[:] = [0.1 + 0.001 * k, -0.2]
            cycle(hw)
        wait_for(lambda: len(peer.points) == 5, "five points")
        assert [p.sequence for p in peer.points] == [0, 1, 2, 3, 4]  # one every 20 ms, a new trajectory
        assert all(p.duration == pytest.approx(0.02) and p.velocity == 0.0 for p in peer.points)
        # Each point carries the command of the cycle it was sent in (t = 0, 20, 40... ms).
        assert [p.positions[0] for p in peer.points] == pytest.approx([0.1 + 0.001 * k for k in (0, 20, 40, 60, 80)],
                                                                       abs=1e-6)
        assert all(p.positions[2:] == (0.0,) * 8 for p in peer.points)  # padded to ten joints
        assert hw.replies == 5
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
        time.sleep(0.1)  # (a bound on a hang, not a speed): nothing else is sent while the reply is held
        assert len(peer.points) == 1 and hw.replies == 0
        peer.hold.clear()
        wait_for(lambda: len(peer.points) == 5, "the held points")
        assert [p.sequence for p in peer.points] == [0, 1, 2, 3, 4]
    finally:
        hw.close()


def test_stale_state_is_a_fault_until_state_flows_again(peer) -> None:
    hw = connected(peer, stale_after_s=0.2)
    try:
        cycle(hw)
        assert hw.fault is None
        peer.publishing.clear()
        wait_for(lambda: (hw.read(), hw.fault)[1] is not None, "the stale fault")
        assert "no joint state from 127.0.0.1" in hw.fault
        hw.command_buffer(POSITION)[0] = 0.5
        cycle(hw, 40)
        assert peer.points == []  # nothing is sent while the hardware is faulted
        peer.publishing.set()
        wait_for(lambda: (hw.read(), hw.fault)[1] is None, "the state again")
    finally:
        hw.close()


def test_a_lost_motion_connection_is_a_fault_and_is_reopened(peer) -> None:
    hw = connected(peer, retry_s=0.05)
    try:
        command = hw.command_buffer(POSITION)
        command[0] = 0.2
        cycle(hw, 25)
        wait_for(lambda: len(peer.points) == 1, "the first point")
        peer.drop_connections()
        command[0] = 0.3
        for _ in range(200):
            cycle(hw)
            if hw.fault is not None and "motion connection" in hw.fault:
                break
            time.sleep(0.002)
        assert hw.fault is not None and "lost the motion connection to 127.0.0.1" in hw.fault
        command[0] = 0.35
        wait_for(lambda: (cycle(hw, 20), hw.fault)[1] is None and len(peer.points) >= 2, "reconnected and sent")
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
        wait_for(lambda: len(peer.points) == 1, "the first point, on the new connection")
        cycle(hw)
        assert peer.points[0].sequence == 0 and hw.fault is None
    finally:
        hw.close()


def test_an_unreachable_controller_is_a_clear_error() -> None:
    with socket.create_server(("127.0.0.1", 0)) as probe:
        free_port = probe.getsockname()[1]  # closed when the block ends: nobody listens there
    hw = IndustrialHardware(JOINTS, robot_ip="127.0.0.1", motion_port=free_port, state_port=free_port)
    with pytest.raises(HardwareUnreachable, match="no industrial controller answers on its state port") as info:
        hw.connect()
    assert info.value.field == "robot_ip" and info.value.value == f"127.0.0.1:{free_port}"


def test_bad_settings_are_refused_naming_the_field() -> None:
    with pytest.raises(Exception, match="1 to 10 joints"):
        IndustrialHardware([f"j{k}" for k in range(11)], robot_ip="127.0.0.1")
    with pytest.raises(Exception, match="must be positive") as info:
        IndustrialHardware(JOINTS, robot_ip="127.0.0.1", stream_rate_hz=0.0)
    assert info.value.field == "stream_rate_hz"

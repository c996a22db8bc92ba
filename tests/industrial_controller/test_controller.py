"""The simulated industrial controller on loopback: the robot in MuJoCo behind simple_message, driven
by jointctl's own client (IndustrialHardware) and by raw packets, in both byte orders; faults on
the sockets never stop it."""

from __future__ import annotations

import functools
import socket
import struct
import threading
import time

import pytest

from jointctl.errors import ConfigError, JointCtlError
from jointctl.hardware.industrial import IndustrialHardware
from jointctl.hardware.interface import POSITION
from jointctl.industrial_controller.controller import ControllerUnavailable, SimulatedController
from jointctl.wire.simple_message import (
    END_TRAJECTORY,
    START_TRAJECTORY_DOWNLOAD,
    STOP_TRAJECTORY,
    CommType,
    JointPosition,
    JointTrajPt,
    MsgType,
    PacketReader,
    Ping,
    ReplyCode,
    RobotStatus,
    decode,
    encode,
)
from jointctl.scenario.spec import scenario_for_robot
from tests.ports import check_free, restart_safe_ports
from tests.waiting import wait_until

TIMEOUT_S = 20.0
START_M = -0.5  # robot.yaml's serve default for one_dof


wait_for = functools.partial(wait_until, timeout_s=TIMEOUT_S, every_s=0.005)


@pytest.fixture
def controller(request):
    """The controller on free ports the OS picks; little-endian unless parametrised (indirect) with True."""
    ctl = SimulatedController(scenario_for_robot("one_dof", "servo"), host="127.0.0.1",
                              motion_port=0, state_port=0, big_endian=getattr(request, "param", False))
    thread = threading.Thread(target=ctl.run, daemon=True)
    thread.start()
    yield ctl
    ctl.close()
    thread.join(5.0)
    assert not thread.is_alive()


def joint1(ctl: SimulatedController) -> float:
    return ctl.session.hardware.position[0]


def let_loop_time_pass(ctl: SimulatedController, seconds: float) -> None:
    """Wait until the controller's loop has run ``seconds`` more of its own time."""
    until = ctl.session.loop.time_s + seconds
    wait_for(lambda: ctl.session.loop.time_s >= until, f"{seconds} s more of the controller's loop time")


class RawClient:
    """A motion-port client sending packets and reading replies."""

    def __init__(self, ctl: SimulatedController, port: int | None = None) -> None:
        self.big = ctl.big_endian
        self.sock = socket.create_connection(("127.0.0.1", port or ctl.motion_port), timeout=TIMEOUT_S)
        self.reader = PacketReader(big_endian=self.big)
        self.pending = []

    def send(self, message, comm=CommType.SERVICE_REQUEST) -> None:
        self.sock.sendall(encode(message, comm, big_endian=self.big))

    def request(self, message):
        self.send(message)
        return self.reply()

    def reply(self):
        while not self.pending:
            data = self.sock.recv(4096)
            assert data, "the controller closed the connection"
            self.pending += self.reader.feed(data)
        return self.pending.pop(0)

    def closed_by_peer(self) -> bool:
        try:
            return self.sock.recv(4096) == b""
        except ConnectionResetError:
            return True

    def close(self) -> None:
        self.sock.close()


def point(seq, q, duration=0.0, velocity=1.0) -> JointTrajPt:
    return JointTrajPt(seq, (q,), velocity, duration)


def test_state_reports_the_measured_position_and_a_truthful_status(controller) -> None:
    sock = socket.create_connection(("127.0.0.1", controller.state_port), timeout=TIMEOUT_S)
    reader = PacketReader(big_endian=controller.big_endian)
    messages = []
    while len([m for m in messages if isinstance(m, RobotStatus)]) < 3:
        messages += [decode(p, big_endian=controller.big_endian) for p in reader.feed(sock.recv(4096))]
    sock.close()
    positions = [m for m in messages if isinstance(m, JointPosition)]
    status = [m for m in messages if isinstance(m, RobotStatus)][-1]
    assert positions[0].positions[0] == pytest.approx(START_M, abs=1e-3)
    assert positions[0].positions[1:] == (0.0,) * 9  # padding
    assert [p.sequence for p in positions[:3]] == [0, 1, 2]
    assert (status.in_motion, status.in_error, status.drives_powered, status.motion_possible, status.mode) == \
        (0, 0, 1, 1, 2)


# The one socket-level test in both byte orders (the codec tests cover the rest): jointctl's client
# and the controller, both channels.
@pytest.mark.parametrize("controller", [False, True], ids=["little-endian", "big-endian"], indirect=True)
def test_jointctl_drives_it_through_the_streaming_handshake(controller) -> None:
    hw = IndustrialHardware(["joint1"], robot_ip="127.0.0.1", motion_port=controller.motion_port,
                            state_port=controller.state_port, big_endian=controller.big_endian)
    hw.connect()
    try:
        assert hw.position[0] == pytest.approx(START_M, abs=1e-3)
        seen_moving = False
        for k in range(1500):  # 1.5 s of loop time: a ramp to -0.2 m over 1 s, then hold
            hw.read()
            hw.command_buffer(POSITION)[0] = START_M + 0.3 * min(k / 1000, 1.0)
            hw.write()
            hw.advance(0.001)
            time.sleep(0.001)
            seen_moving |= hw.status is not None and hw.status.in_motion == 1
        wait_for(lambda: (hw.read(), hw.status.in_motion == 0)[1], "the robot at rest")
        assert seen_moving
        assert hw.position[0] == pytest.approx(-0.2, abs=2e-3)
        assert joint1(controller) == pytest.approx(-0.2, abs=2e-3)
        assert controller.program.accepted == hw.replies >= 40  # 50 Hz for ~1 s, each answered
    finally:
        hw.close()


def test_the_download_handshake_runs_only_after_its_end(controller) -> None:
    client = RawClient(controller)
    for seq, q, d in ((START_TRAJECTORY_DOWNLOAD, START_M, 0.0), (1, -0.4, 0.5)):
        client.send(point(seq, q, d), CommType.TOPIC)
    # The PING's reply comes after the two topics were handled (one connection, handled in order).
    assert client.request(Ping()).reply_code == ReplyCode.SUCCESS
    assert not controller.program.in_motion  # kept, not executed: nothing queued to move to
    assert joint1(controller) == pytest.approx(START_M, abs=1e-3)
    client.send(point(END_TRAJECTORY, -0.3, 0.5), CommType.TOPIC)
    wait_for(lambda: controller.program.in_motion, "the download to start")
    wait_for(lambda: not controller.program.in_motion, "the download to end")
    wait_for(lambda: abs(joint1(controller) + 0.3) < 2e-3, "the robot at -0.3 m")
    client.close()


def test_stop_is_answered_and_the_robot_comes_to_rest_short_of_the_point(controller) -> None:
    client = RawClient(controller)
    assert client.request(point(0, START_M)).reply_code == ReplyCode.SUCCESS
    assert client.request(point(1, -0.05, 4.5)).reply_code == ReplyCode.SUCCESS  # 0.1 m/s for 4.5 s
    wait_for(lambda: joint1(controller) > START_M + 0.05, "the robot moving")
    reply = client.request(point(STOP_TRAJECTORY, 0.0))
    assert (reply.msg_type, reply.reply_code) == (MsgType.JOINT_TRAJ_PT, ReplyCode.SUCCESS)
    wait_for(lambda: not controller.program.in_motion, "the stop")
    stopped_at = joint1(controller)
    let_loop_time_pass(controller, 0.5)
    # At rest: the references stand still and the servo has only its settling tail left (a robot
    # that went on at the point's 0.1 m/s would be 50 mm further).
    assert joint1(controller) == pytest.approx(stopped_at, abs=2e-3) and stopped_at < -0.1
    client.close()


def test_ping_and_unknown_requests_are_answered(controller) -> None:
    client = RawClient(controller)
    assert client.request(Ping()).reply_code == ReplyCode.SUCCESS
    reply = client.request(JointPosition(0, (0.0,)))
    assert (reply.msg_type, reply.reply_code) == (MsgType.JOINT_POSITION, ReplyCode.FAILURE)
    client.close()


def test_a_refused_point_moves_nothing_and_shows_in_status(controller) -> None:
    client = RawClient(controller)
    client.request(point(0, START_M))
    assert client.request(point(1, float("nan"), 1.0)).reply_code == ReplyCode.FAILURE
    assert client.request(point(0, START_M)).reply_code == ReplyCode.SUCCESS  # delivered: a new trajectory
    assert client.request(point(1, 5.0, 1.0)).reply_code == ReplyCode.FAILURE  # beyond the upper limit
    assert not controller.program.in_motion  # nothing queued: the robot has nothing to move to
    assert joint1(controller) == pytest.approx(START_M, abs=1e-3)
    status = controller.program.status()
    assert status.in_error == 1 and status.error_code == 1
    client.close()


@pytest.mark.parametrize("length, tail", [
    (0, b"\x00" * 12),             # length 0
    (11, b"\x01" * 11),            # length 11: shorter than the header
    (1 << 30, b"\x0b" * 64),       # 1 GiB
    (None, bytes(range(256)) * 4),  # noise: its first four bytes say 0x03020100 (or 0x00010203)
])
def test_garbage_closes_only_that_connection_and_the_next_client_is_served(controller, length, tail) -> None:
    garbage = (b"" if length is None else struct.pack(">i" if controller.big_endian else "<i", length)) + tail
    state = socket.create_connection(("127.0.0.1", controller.state_port), timeout=TIMEOUT_S)
    client = RawClient(controller)
    client.sock.sendall(garbage)
    assert client.closed_by_peer()
    client.close()
    assert joint1(controller) == pytest.approx(START_M, abs=1e-3)
    good = RawClient(controller)
    assert good.request(Ping()).reply_code == ReplyCode.SUCCESS
    good.close()
    reports = controller.reports_sent
    wait_for(lambda: controller.reports_sent > reports + 2, "state reports to go on")
    assert state.recv(4096)  # the state client was never dropped
    state.close()


def test_a_client_lost_mid_trajectory_brakes_the_robot_and_can_come_back(controller) -> None:
    client = RawClient(controller)
    client.request(point(0, START_M))
    client.request(point(1, -0.05, 4.5))  # 0.1 m/s
    wait_for(lambda: joint1(controller) > START_M + 0.05, "the robot moving")
    client.close()
    wait_for(lambda: not controller.program.in_motion, "the robot braking to rest")
    stopped_at = joint1(controller)
    assert stopped_at < -0.1
    again = RawClient(controller)
    assert again.request(point(0, stopped_at)).reply_code == ReplyCode.SUCCESS
    assert again.request(point(1, START_M, 0.5)).reply_code == ReplyCode.SUCCESS
    wait_for(lambda: abs(joint1(controller) - START_M) < 2e-3, "the robot back at the start")
    assert controller.motion_clients == 2
    again.close()


def test_a_port_in_use_is_a_clear_error() -> None:
    taken = socket.create_server(("127.0.0.1", 0))
    try:
        with pytest.raises(ControllerUnavailable) as info:
            SimulatedController(scenario_for_robot("one_dof", "position"), host="127.0.0.1",
                                motion_port=taken.getsockname()[1], state_port=0)
        assert info.value.field == "motion_port" and str(taken.getsockname()[1]) in str(info.value)
    finally:
        taken.close()


def test_joints_without_position_servos_are_refused_naming_the_joint() -> None:
    with pytest.raises(ConfigError) as info:
        SimulatedController(scenario_for_robot("one_dof", "velocity"), motion_port=0, state_port=0)
    assert info.value.field == "joint" and info.value.value == "joint1"


def test_a_refusal_reaches_jointctl_as_a_fault_until_the_robot_is_at_rest_and_the_next_motion_clears_it(
        controller) -> None:
    hw = IndustrialHardware(["joint1"], robot_ip="127.0.0.1", motion_port=controller.motion_port,
                            state_port=controller.state_port, big_endian=controller.big_endian)
    hw.connect()
    try:
        hw.command_buffer(POSITION)[0] = 0.5  # beyond joint1's upper limit (0 m)
        hw.write()

        def refusal_reported() -> bool:  # the FAILURE reply, named with the point, the STATUS error code, the value
            hw.read()
            return (hw.fault or "").startswith("the controller refused point 0 of the trajectory "
                                               "(FAILURE; STATUS error_code 1): it asked joint1 0.5 at ")

        wait_for(refusal_reported, "the refusal as a fault")
        wait_for(lambda: (hw.read(), hw.fault)[1] is None, "the fault over: the controller reports the robot at rest")
        assert joint1(controller) == pytest.approx(START_M, abs=1e-3)
        for k in range(1, 600):  # a good motion afterwards: from sequence 0 again
            hw.command_buffer(POSITION)[0] = START_M + 0.1 * min(k / 300, 1.0)
            hw.advance(0.001)
            hw.write()
            time.sleep(0.001)
        wait_for(lambda: abs(joint1(controller) - START_M - 0.1) < 2e-3, "the good motion")
        hw.read()
        assert hw.status.in_error == 0 and hw.fault is None
    finally:
        hw.close()


def test_stop_motion_is_a_fault_until_the_controller_reports_the_robot_at_rest(controller) -> None:
    # One streamed point to -0.1 m taking 4 s (the stream period is the point's duration): 0.1 m/s,
    # so the robot is still on its way, 0.35 m short, when the STOP goes out after it passed -0.45 m.
    hw = IndustrialHardware(["joint1"], robot_ip="127.0.0.1", motion_port=controller.motion_port,
                            state_port=controller.state_port, stream_rate_hz=1 / 4.0)
    hw.connect()
    try:
        hw.command_buffer(POSITION)[0] = -0.1
        hw.write()
        wait_for(lambda: (hw.read(), hw.position[0] > START_M + 0.05 and hw.status.in_motion == 1)[1],
                 "the robot moving toward -0.1 m")
        assert hw.fault is None
        hw.stop_motion()
        hw.read()
        assert hw.fault == "stopping: STOP sent, until the controller reports the robot at rest"
        wait_for(lambda: (hw.read(), hw.fault is None)[1], "the stop to end")
        assert hw.status.in_motion == 0 and controller.program.accepted == 1
        stopped_at = hw.position[0]
        # Short of -0.1 m by far more than the braking distance at 0.1 m/s (v * stop_time_s / 2 =
        # 10 mm): -0.2 m leaves 2.5 s of travel for the STOP's way from the test to the controller.
        assert START_M + 0.05 < stopped_at < -0.2
        reports = hw.state_reports
        wait_for(lambda: hw.state_reports >= reports + 25, "0.5 s more of state reports (50 Hz)")
        hw.read()
        # Still: STATUS said every joint slower than moving_threshold (1 mm/s) with its reference at
        # rest; 0.5 s of that is under 0.5 mm, and a robot still going at 0.1 m/s would be 50 mm on.
        assert hw.position[0] == pytest.approx(stopped_at, abs=1e-3)
        assert joint1(controller) == pytest.approx(stopped_at, abs=1e-3)
    finally:
        hw.close()


def test_a_goal_downloaded_whole_is_executed_by_the_controller(controller) -> None:
    from jointctl.scenario.session import Session
    from jointctl.trajectory.executor import GoalStatus
    from jointctl.trajectory.messages import JointTrajectory, JointTrajectoryPoint

    hw = IndustrialHardware(["joint1"], robot_ip="127.0.0.1", motion_port=controller.motion_port,
                            state_port=controller.state_port, big_endian=controller.big_endian, motion="download")
    hw.connect()
    try:
        session = Session(scenario_for_robot("one_dof", "industrial"), hardware=hw, realtime=True)
        executor = session.manager.controller("joint1_trajectory_controller")
        goal = JointTrajectory(("joint1",), (JointTrajectoryPoint(positions=(-0.3,), time_from_start_s=1.0),))
        handle = executor.submit(goal, now_s=0.0)
        session.run(1.0)
        assert controller.program.accepted == 2  # the goal's one point, twice (as ROS-I's downloader sends it)
        session.run(2.5)
        assert handle.status is GoalStatus.SUCCEEDED, handle.result
        assert joint1(controller) == pytest.approx(-0.3, abs=0.01)
        assert controller.program.refused == 0
    finally:
        hw.close()


def test_a_controller_restarted_between_two_reads_is_a_fault_for_one_read() -> None:
    """A controller that goes away and comes back (a cabinet rebooted) while jointctl's loop reads
    nothing (descheduled longer than retry_s): both connections re-open in the background, and the
    lost motion connection is still the fault of the next read (the controller dropped the trajectory
    in hand: the goal must abort); then no fault, with state from the new controller."""
    motion_port, state_port = restart_safe_ports(2)  # no port the OS hands out: free for the restart

    def start() -> tuple[SimulatedController, threading.Thread]:
        ctl = SimulatedController(scenario_for_robot("one_dof", "servo"), host="127.0.0.1",
                                  motion_port=motion_port, state_port=state_port)
        thread = threading.Thread(target=ctl.run, daemon=True)
        thread.start()
        return ctl, thread

    first, thread = start()
    hw = IndustrialHardware(["joint1"], robot_ip="127.0.0.1", motion_port=motion_port, state_port=state_port,
                            retry_s=0.05)
    hw.connect()
    try:
        hw.read()
        assert hw.fault is None and hw.connected
        first.close()
        thread.join(5.0)
        wait_for(lambda: not hw.connected, "the hardware to see the controller gone")
        check_free(motion_port, state_port)
        second, thread = start()
        try:
            reports = hw.state_reports
            wait_for(lambda: hw.connected and second.motion_clients == 1 and hw.state_reports > reports,
                     "both connections re-opened to the new controller, its state read")
            hw.read()  # the first read since the controller went away
            assert hw.fault is not None and f"lost the motion connection to 127.0.0.1:{motion_port}" in hw.fault
            hw.read()
            assert hw.fault is None and hw.position[0] == pytest.approx(START_M, abs=1e-3)
        finally:
            second.close()
            thread.join(5.0)
    finally:
        hw.close()


def test_an_unknown_motion_handshake_is_refused() -> None:
    with pytest.raises(JointCtlError) as info:
        IndustrialHardware(["joint1"], robot_ip="127.0.0.1", motion="upload")
    assert info.value.field == "motion" and info.value.value == "upload"

"""An industrial robot controller that interpolates by itself, driven over ROS-Industrial's simple_message.

Section 11.5 of the chapter: the robot's own controller runs its own interpolator; a PC sends it
trajectory points and reads back its joint state. :class:`IndustrialHardware` is that PC side as a
jointctl hardware implementation, so the same controllers, executor and ROS node drive it:

- **State** (the controller's STATE port, 11002 by default): the controller pushes JOINT_POSITION
  and STATUS packets as TOPIC. A reader thread keeps the latest; :meth:`read` copies it into the
  state handles: ``position`` [rad or m] as reported, ``velocity`` [rad/s or m/s] differenced
  between the last two reports (JOINT_POSITION carries no velocity), ``effort`` zero (not
  reported). ``status`` is the last STATUS (``in_motion``, ``in_error``...); ``in_motion`` its
  ``in_motion`` as a bool (None when unknown): a goal succeeds only once the controller says the
  robot is not in motion, as ROS-I's action server requires.
- **Commands**: each joint has a ``position`` command interface only (the controller servos its
  joints; there is no PID on this side). :meth:`write` streams the position command on the MOTION
  port (11000) every ``1 / stream_rate_hz`` of loop time, when it changed, as a JOINT_TRAJ_PT
  SERVICE_REQUEST whose ``duration`` is the stream period and ``velocity`` 0 (no speed fraction:
  the controller's joint limits apply), in ROS-I's streaming handshake: a sender thread sends one
  point, waits for the reply (the controller's flow control) and sends the next. A motion that
  starts with the robot at rest (STATUS ``in_motion`` 0, nothing streamed at the last tick)
  begins with sequence number 0, which tells the controller a new trajectory begins; every other
  point continues the numbering, so the controller queues it behind the ones it has.
  With ``motion="download"`` nothing is streamed: a trajectory executor hands each goal to
  :meth:`download_motion`, sent in ROS-I's download handshake (TOPIC points from sequence -1 to -3;
  the controller executes after the last). :meth:`stop_motion` sends STOP (-4); ``fault`` then
  says "stopping" until the controller has answered and reports the robot at rest.
- **Faults**: ``fault`` says why the robot cannot be commanded now (``None`` when it can): the
  state stale for ``stale_after_s`` (ROS-I's action server aborts after 1 s without feedback), or
  a connection lost; and, for one :meth:`read`, that the controller refused a point (STATUS
  ``in_error``): enough for the executor to abort its goal, after which the next motion starts a
  new trajectory, which clears the controller's error. Lost connections are re-opened in the
  background every ``retry_s``; the fault clears when state flows again. The trajectory executor
  aborts its goal on a fault and refuses new ones while it lasts.

Time: :meth:`advance` counts loop time (the controller runs on its own clock). Byte order:
little-endian unless ``big_endian`` (the ``_bswap`` drivers). Joint ``i`` of a packet is joint
``i`` of ``joint_names`` (ROS-I's ``controller_joint_names``).
"""

from __future__ import annotations

import queue
import select
import socket
import threading
import time
from collections.abc import Sequence

from jointctl.errors import JointCtlError, MalformedPacket
from jointctl.hardware.interface import POSITION, HardwareInterface
from jointctl.wire.simple_message import (
    END_TRAJECTORY,
    MAX_JOINTS,
    START_TRAJECTORY_DOWNLOAD,
    STOP_TRAJECTORY,
    TRISTATE_TRUE,
    TRISTATE_UNKNOWN,
    CommType,
    JointPosition,
    JointTrajPt,
    MsgType,
    PacketReader,
    RobotStatus,
    decode,
    encode,
)

MOTION_PORT = 11000
STATE_PORT = 11002
#: The motion handshakes of ROS-I's motion interfaces.
MOTION_HANDSHAKES = ("streaming", "download")


class HardwareUnreachable(JointCtlError):
    """The robot controller does not answer (refused, timed out, unknown host)."""

    code = "unreachable"


class IndustrialHardware(HardwareInterface):
    """Joints of a robot controller reached over simple_message (see the module docstring)."""

    def __init__(self, joint_names: Sequence[str], *, robot_ip: str, motion_port: int = MOTION_PORT,
                 state_port: int = STATE_PORT, big_endian: bool = False, stream_rate_hz: float = 50.0,
                 stale_after_s: float = 1.0, connect_timeout_s: float = 2.0, retry_s: float = 0.5,
                 motion: str = "streaming") -> None:
        super().__init__(tuple(joint_names))
        if not 0 < len(self.joint_names) <= MAX_JOINTS:
            raise JointCtlError(f"simple_message carries 1 to {MAX_JOINTS} joints", field="joints",
                                value=list(self.joint_names))
        if motion not in MOTION_HANDSHAKES:
            raise JointCtlError(f"must be one of {', '.join(MOTION_HANDSHAKES)}", field="motion", value=motion)
        #: The motion handshake: "streaming" (points streamed as the loop runs) or "download" (whole
        #: trajectories, from a trajectory executor's goals, executed by the controller after their end).
        self.motion = motion
        self.takes_trajectories = motion == "download"
        if not stream_rate_hz > 0:
            raise JointCtlError("must be positive", field="stream_rate_hz", value=stream_rate_hz)
        self.robot_ip = robot_ip
        self.motion_port, self.state_port = int(motion_port), int(state_port)
        self.big_endian = big_endian
        self.stream_period_s = 1.0 / stream_rate_hz
        self.stale_after_s = stale_after_s
        self.connect_timeout_s = connect_timeout_s
        self.retry_s = retry_s
        #: Why the robot cannot be commanded now, or None.
        self.fault: str | None = "not connected"
        #: The controller's last STATUS, or None before the first.
        self.status: RobotStatus | None = None
        n = len(self.joint_names)
        self._lock = threading.Lock()
        self._reported: tuple[float, ...] | None = None   # last JOINT_POSITION (first n joints)
        self._reported_at = -float("inf")                 # its arrival, time.monotonic() [s]
        self._velocity = [0.0] * n
        self._state_reports = 0
        self._time_s = 0.0
        self._next_stream_s = 0.0
        self._last_sent: list[float] | None = None
        self._streaming = False  # a point was sent at the last stream tick
        self._sequence = 0
        self._refusal_reported = False  # the controller's current in_error was turned into a fault
        self._stopping = False  # STOP sent, the robot not yet reported at rest since it was answered
        self._stop_answered_at: float | None = None  # time.monotonic() of the STOP's reply
        self._status_at = -float("inf")  # arrival of the last STATUS, time.monotonic() [s]
        self._outbox: queue.SimpleQueue = queue.SimpleQueue()
        self._closing = threading.Event()
        self._motion: socket.socket | None = None
        self._state: socket.socket | None = None
        self._motion_lost: str | None = None
        self._threads: list[threading.Thread] = []
        self.replies = 0  # points the controller acknowledged
        #: JOINT_POSITION reports received when ``position`` was last refreshed (by :meth:`read`).
        self.reports_read = 0

    # -- connection ------------------------------------------------------------------------------------
    def connect(self, *, first_state_timeout_s: float = 5.0) -> None:
        """Open both connections and wait for the first state report; HardwareUnreachable if not."""
        self._state = self._open(self.state_port, "state")
        self._motion = self._open(self.motion_port, "motion")
        for target, name in ((self._state_reader, "state"), (self._sender, "motion")):
            thread = threading.Thread(target=target, name=f"jointctl-industrial-{name}", daemon=True)
            thread.start()
            self._threads.append(thread)
        deadline = time.monotonic() + first_state_timeout_s
        while self._reported is None:
            if time.monotonic() > deadline:
                self.close()
                raise HardwareUnreachable(f"the controller sent no joint state within {first_state_timeout_s} s",
                                          field="robot_ip", value=f"{self.robot_ip}:{self.state_port}")
            time.sleep(0.01)
        self.read()
        self._last_sent = list(self.position)
        self.command_buffer(POSITION)[:] = self.position

    def _open(self, port: int, what: str) -> socket.socket:
        try:
            sock = socket.create_connection((self.robot_ip, port), timeout=self.connect_timeout_s)
        except OSError as exc:
            raise HardwareUnreachable(f"no industrial controller answers on its {what} port ({exc.strerror or exc})",
                                      field="robot_ip", value=f"{self.robot_ip}:{port}") from None
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.settimeout(None)
        return sock

    def close(self) -> None:
        """Close both connections and stop the threads."""
        self._closing.set()
        self._outbox.put(None)
        for sock in (self._motion, self._state):
            if sock is not None:
                try:
                    sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                sock.close()
        for thread in self._threads:
            thread.join(timeout=2.0)

    # -- the state channel (its thread) -------------------------------------------------------------------
    def _state_reader(self) -> None:
        while not self._closing.is_set():
            sock = self._state
            if sock is None:
                if not self._reconnect("state"):
                    return
                continue
            reader = PacketReader(big_endian=self.big_endian)
            try:
                while not self._closing.is_set():
                    data = sock.recv(4096)
                    if not data:
                        raise ConnectionError("the controller closed the state connection")
                    for packet in reader.feed(data):
                        self._on_state(packet)
            except (OSError, ConnectionError, MalformedPacket):
                if self._closing.is_set():
                    return
                sock.close()
                self._state = None

    def _on_state(self, packet) -> None:
        if packet.comm_type != CommType.TOPIC:
            return
        try:
            message = decode(packet, big_endian=self.big_endian)
        except MalformedPacket:
            return
        now = time.monotonic()
        if isinstance(message, JointPosition):
            positions = tuple(message.positions[: len(self.joint_names)])
            with self._lock:
                previous, previous_at = self._reported, self._reported_at
                if previous is not None and now > previous_at:
                    dt = now - previous_at
                    self._velocity = [(q - p) / dt for q, p in zip(positions, previous)]
                self._reported, self._reported_at = positions, now
                self._state_reports += 1
        elif isinstance(message, RobotStatus):
            self.status = message
            self._status_at = now

    def _reconnect(self, which: str) -> bool:
        """Re-open ``which`` connection, trying every ``retry_s``; False when closing."""
        port = self.state_port if which == "state" else self.motion_port
        while not self._closing.wait(self.retry_s):
            try:
                sock = self._open(port, which)
            except HardwareUnreachable:
                continue
            if which == "state":
                self._state = sock
            else:
                self._motion = sock
                self._motion_lost = None
            return True
        return False

    # -- the motion channel (its thread) ------------------------------------------------------------------
    def _sender(self) -> None:
        while True:
            try:
                item = self._outbox.get(timeout=self.retry_s)
            except queue.Empty:
                # Idle: a controller that went away while nothing was sent must be noticed now, not
                # when the next motion's first point finds the connection dead.
                item = ()
            if item is None or self._closing.is_set():
                return
            try:
                if item == ():
                    self._check_motion_alive()
                elif isinstance(item, tuple):  # (TOPIC, point): sent, no reply to wait for
                    self._motion.sendall(encode(item[1], item[0], big_endian=self.big_endian))
                else:
                    self._request(item)
            except (OSError, ConnectionError, MalformedPacket) as exc:
                if self._closing.is_set():
                    return
                self._motion_lost = f"lost the motion connection to {self.robot_ip}:{self.motion_port} ({exc})"
                if self._motion is not None:
                    self._motion.close()
                self._motion = None
                self._drop_outbox()
                self._stopping = False  # the controller stops by itself when its client goes
                self._last_sent = None  # after a reconnect, the next motion starts a new trajectory
                if not self._reconnect("motion"):
                    return

    def _check_motion_alive(self) -> None:
        """Raise ConnectionError when the idle motion connection was closed by the controller (it
        sends nothing unasked: anything readable now is its end of the connection)."""
        sock = self._motion
        if sock is None:
            return
        readable, _, _ = select.select([sock], [], [], 0)
        if readable and not sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT):
            raise ConnectionError("the controller closed the motion connection")

    def _request(self, point: JointTrajPt) -> None:
        """Send one point as a SERVICE_REQUEST and wait for the reply (the flow control)."""
        sock = self._motion
        sock.sendall(encode(point, CommType.SERVICE_REQUEST, big_endian=self.big_endian))
        reader = PacketReader(big_endian=self.big_endian)
        while True:
            data = sock.recv(4096)
            if not data:
                raise ConnectionError("the controller closed the motion connection")
            for packet in reader.feed(data):
                if packet.comm_type == CommType.SERVICE_REPLY and packet.msg_type == MsgType.JOINT_TRAJ_PT:
                    self.replies += 1
                    if point.sequence == STOP_TRAJECTORY:
                        self._stop_answered_at = time.monotonic()
                    return

    def _drop_outbox(self) -> None:
        while True:
            try:
                if self._outbox.get_nowait() is None:
                    self._outbox.put(None)
                    return
            except queue.Empty:
                return

    def stop_motion(self) -> None:
        """Send STOP (-4): the controller decelerates to rest and clears its queue. Until it has
        answered and a later STATUS says the robot is not in motion, ``fault`` says so (the
        executor then follows the measured position, so that nothing moves when it clears)."""
        self._drop_outbox()
        self._stop_answered_at = None
        self._stopping = True
        self._outbox.put(JointTrajPt(STOP_TRAJECTORY, (0.0,) * MAX_JOINTS, 0.0, 0.0))
        self._last_sent = None  # the next motion starts a new trajectory from where the robot stops

    def _stopped(self, status: RobotStatus | None) -> bool:
        """The STOP was answered and a STATUS since says the robot is not in motion."""
        answered = self._stop_answered_at
        return (answered is not None and status is not None and self._status_at > answered
                and status.in_motion != TRISTATE_TRUE)

    # -- HardwareInterface -----------------------------------------------------------------------------
    def command_interfaces(self, joint: str) -> frozenset[str]:
        self.joint_index(joint)
        return frozenset({POSITION})

    def read(self) -> None:
        with self._lock:
            reported, reported_at, velocity = self._reported, self._reported_at, self._velocity
            self.reports_read = self._state_reports
        if reported is not None:
            self.position[:] = reported
            self.velocity[:] = velocity
        age = time.monotonic() - reported_at
        status = self.status
        self.in_motion = None if status is None or status.in_motion == TRISTATE_UNKNOWN else \
            status.in_motion == TRISTATE_TRUE
        refused = status is not None and status.in_error == TRISTATE_TRUE
        if self._stopping and self._stopped(status):
            self._stopping = False
        if self._motion_lost is not None:
            self.fault = self._motion_lost
        elif self._stopping:
            self.fault = "stopping: STOP sent, until the controller reports the robot at rest"
        elif refused and not self._refusal_reported:
            # Reported for one read: the trajectory in progress is aborted; the next motion starts a
            # new trajectory (sequence 0), which clears the controller's error.
            self._refusal_reported = True
            self._last_sent = None
            self.fault = f"the controller refused a point (STATUS error_code {status.error_code})"
        elif self._state is None or age > self.stale_after_s:
            self.fault = (f"no joint state from {self.robot_ip}:{self.state_port} for {age:.1f} s"
                          if reported is not None else "no joint state yet")
            if age > self.stale_after_s:
                self.velocity[:] = [0.0] * len(self.velocity)
        else:
            self.fault = None
        if not refused:
            self._refusal_reported = False

    def download_motion(self, joint_indices: Sequence[int], times_s: Sequence[float],
                        positions: Sequence[Sequence[float]]) -> None:
        """Send a trajectory in ROS-I's download handshake: every point as a TOPIC, the first with
        sequence -1 (START_TRAJECTORY_DOWNLOAD), the last -3 (END_TRAJECTORY), a one-point
        trajectory twice; each point's ``duration`` is the time since the previous one. Joints not
        in ``joint_indices`` keep their last position command."""
        base = list(self.command_buffer(POSITION))
        points = []
        for k, (t, row) in enumerate(zip(times_s, positions)):
            full = list(base)
            for i, q in zip(joint_indices, row):
                full[i] = float(q)
            duration = float(t - times_s[k - 1]) if k else 0.0
            points.append((tuple(full) + (0.0,) * (MAX_JOINTS - len(full)), duration))
        if len(points) == 1:
            points.append(points[0])
        last = len(points) - 1
        self._drop_outbox()
        for k, (q, duration) in enumerate(points):
            seq = START_TRAJECTORY_DOWNLOAD if k == 0 else END_TRAJECTORY if k == last else k
            self._outbox.put((CommType.TOPIC, JointTrajPt(seq, q, 0.0, duration)))
        self._last_sent = list(points[-1][0][: len(self.joint_names)])

    def write(self) -> None:
        if self.takes_trajectories:
            return  # the controller executes downloaded trajectories; nothing is streamed
        if self._time_s + 1e-9 < self._next_stream_s:
            return
        self._next_stream_s += self.stream_period_s
        command = self.command_buffer(POSITION)
        if command == self._last_sent or self.fault is not None:
            self._streaming = False  # a tick without a point: the motion (if any) has ended
            return
        if self._last_sent is None or not self._streaming and self._at_rest():
            self._sequence = 0  # a motion from rest: a new trajectory at the controller
        positions = tuple(command) + (0.0,) * (MAX_JOINTS - len(command))
        self._outbox.put(JointTrajPt(self._sequence, positions, 0.0, self.stream_period_s))
        self._sequence += 1
        self._last_sent = list(command)
        self._streaming = True

    def _at_rest(self) -> bool:
        status = self.status
        return status is not None and status.in_motion == 0

    def advance(self, period_s: float) -> None:
        self._time_s += period_s

    @property
    def state_reports(self) -> int:
        """JOINT_POSITION packets received so far."""
        return self._state_reports


__all__ = ["MOTION_HANDSHAKES", "MOTION_PORT", "STATE_PORT", "HardwareUnreachable", "IndustrialHardware"]

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
  robot is not in motion, as ROS-I's action server requires. Listeners added with
  :meth:`add_state_listener` get every JOINT_POSITION and STATUS as it is read, on the reader's
  thread (ROS-I's ``robot_state`` relays each one: several read between two loop cycles are each
  relayed, not only the last).
- **Commands**: each joint has a ``position`` command interface only (the controller servos its
  joints; there is no PID on this side). The hardware *takes trajectories*: a trajectory executor
  hands it each goal (:meth:`execute_trajectory`), sent as ROS-I's client sends it
  (``hardware/ros_industrial_points.py``): per point the speed fraction of the critical joint
  (``|v_i| / v_max,i`` from the goal's velocities and the URDF's limits ``max_velocities``;
  ``default_speed``, 0.1, when there are none) and the duration since the previous point. Which
  points: the goal's own (``points="goal"``, ROS-I's way) or the goal resampled every stream period
  (``points="resampled"``, the chapter's streamer's). Which message: JOINT_TRAJ_PT (``message="pt"``)
  or JOINT_TRAJ_PT_FULL (``"full"``: time, positions, velocities, accelerations). In the streaming
  handshake each point is a SERVICE_REQUEST with sequence 0, 1, 2... (0: a new trajectory), sent by a
  thread once the previous one was answered (the controller's flow control); a FAILURE answer
  abandons the rest and is a fault naming the point, the STATUS error code and what the point asked
  of each joint (its position, and the speed its segment asks); a streamed command the controller
  refused is not sent again until it changes. In the download
  handshake (``motion="download"``) every point is a TOPIC from sequence -1 to -3, executed by the
  controller after the last. :attr:`executing` stays True until every point was answered (or sent)
  and the controller reported the robot at rest. Outside a goal, :meth:`write` streams the position
  command every ``1 / stream_rate_hz`` of loop time when it changed (a jog, a bode sweep), with the
  stream period as duration. :meth:`stop_motion` sends STOP (-4); ``fault`` then says "stopping"
  until the controller has answered and reports the robot at rest.
- **Faults**: ``fault`` says why the robot cannot be commanded now (``None`` when it can): the
  state stale for ``stale_after_s`` (ROS-I's action server aborts after 1 s without feedback), or
  a connection lost; and, from a refusal (a FAILURE answer, or STATUS ``in_error``) until a STATUS
  after it says the robot is at rest, that the controller refused a point: the executor aborts its
  goal and follows the robot to where the controller halted it (its joints may still be on their
  way: servo lag), and holds there; the next motion starts a new trajectory, which clears the
  controller's error. Lost connections are re-opened in the background every ``retry_s``
  (:attr:`connected` says when both are open); the fault clears when state flows again. A lost motion
  connection is a fault for at least one :meth:`read`, also when it was re-opened before that read
  came (the loop descheduled longer than ``retry_s``): the controller dropped the trajectory in hand
  with it, and the goal it belonged to must abort. The trajectory executor aborts its goal on a fault
  and refuses new ones while it lasts.

Time: :meth:`advance` counts loop time (the controller runs on its own clock). Byte order:
little-endian unless ``big_endian`` (the ``_bswap`` drivers). Joint ``i`` of a packet is joint
``i`` of ``joint_names`` (ROS-I's ``controller_joint_names``).
"""

from __future__ import annotations

import math
import queue
import select
import socket
import threading
import time
from collections.abc import Callable, Sequence

from jointctl.errors import JointCtlError, MalformedPacket
from jointctl.hardware.interface import POSITION, HardwareInterface
from jointctl.hardware.ros_industrial_points import DEFAULT_SPEED_FRACTION, WirePoint, speed_fraction, wire_points
from jointctl.wire.simple_message import (
    END_TRAJECTORY,
    MAX_JOINTS,
    START_TRAJECTORY_DOWNLOAD,
    STOP_TRAJECTORY,
    TRISTATE_TRUE,
    TRISTATE_UNKNOWN,
    VALID_ACCELERATION,
    VALID_POSITION,
    VALID_TIME,
    VALID_VELOCITY,
    CommType,
    JointPosition,
    JointTrajPt,
    JointTrajPtFull,
    MsgType,
    PacketReader,
    ReplyCode,
    RobotStatus,
    decode,
    encode,
)

MOTION_PORT = 11000
STATE_PORT = 11002
#: The motion handshakes of ROS-I's motion interfaces.
MOTION_HANDSHAKES = ("streaming", "download")
#: Which points a goal becomes: its own (as ROS-I's client sends them), or the goal resampled every
#: stream period (as the chapter's arm streamer sends them, for controllers that want a dense stream).
STREAM_POINTS = ("goal", "resampled")
#: The point message: JOINT_TRAJ_PT (speed fraction and duration, as ROS-I's client sends) or
#: JOINT_TRAJ_PT_FULL (time from the trajectory's start, positions, velocities, accelerations).
POINT_MESSAGES = ("pt", "full")
#: STATUS reports saying "not in motion" after the last point was answered before a trajectory counts
#: as executed (one may have been on its way when the point was answered: the two ports race).
REST_REPORTS = 2
#: ``fault`` from a STOP until the controller has answered it and reports the robot at rest.
STOPPING = "stopping: STOP sent, until the controller reports the robot at rest"
#: How long a FAILURE reply waits for the STATUS that carries its error code before it is reported [s]:
#: two and a half periods of a 10 Hz status stream (ROS-I's robot_status rate on many controllers).
ERROR_CODE_WAIT_S = 0.25


class HardwareUnreachable(JointCtlError):
    """The robot controller does not answer (refused, timed out, unknown host)."""

    code = "unreachable"


class IndustrialHardware(HardwareInterface):
    """Joints of a robot controller reached over simple_message (see the module docstring)."""

    def __init__(self, joint_names: Sequence[str], *, robot_ip: str, motion_port: int = MOTION_PORT,
                 state_port: int = STATE_PORT, big_endian: bool = False, stream_rate_hz: float = 50.0,
                 stale_after_s: float = 1.0, connect_timeout_s: float = 2.0, retry_s: float = 0.5,
                 motion: str = "streaming", points: str = "goal", message: str = "pt",
                 max_velocities: Sequence[float] | None = None,
                 default_speed: float = DEFAULT_SPEED_FRACTION) -> None:
        super().__init__(tuple(joint_names))
        if not 0 < len(self.joint_names) <= MAX_JOINTS:
            raise JointCtlError(f"simple_message carries 1 to {MAX_JOINTS} joints", field="joints",
                                value=list(self.joint_names))
        if motion not in MOTION_HANDSHAKES:
            raise JointCtlError(f"must be one of {', '.join(MOTION_HANDSHAKES)}", field="motion", value=motion)
        if points not in STREAM_POINTS:
            raise JointCtlError(f"must be one of {', '.join(STREAM_POINTS)}", field="points", value=points)
        if message not in POINT_MESSAGES:
            raise JointCtlError(f"must be one of {', '.join(POINT_MESSAGES)}", field="message", value=message)
        if isinstance(default_speed, bool) or not isinstance(default_speed, (int, float)) or not 0 < default_speed <= 1:
            raise JointCtlError("must be a fraction of the maximum speed in (0, 1]", field="default_speed",
                                value=default_speed)
        #: The motion handshake: "streaming" (each point a request, answered when the controller has
        #: room) or "download" (every point a topic, executed by the controller after the last).
        self.motion = motion
        self.points = points
        self.message = message
        self.default_speed = default_speed
        #: Each joint's speed limit [rad/s or m/s] for the speed fractions (the URDF's; inf: unknown).
        self.max_velocities = tuple(float(v) for v in max_velocities) if max_velocities is not None else \
            (math.inf,) * len(self.joint_names)
        if len(self.max_velocities) != len(self.joint_names):
            raise JointCtlError(f"needs one speed limit per joint ({len(self.joint_names)})",
                                field="max_velocities", value=list(self.max_velocities))
        self.takes_trajectories = True
        if not stream_rate_hz > 0:
            raise JointCtlError("must be positive", field="stream_rate_hz", value=stream_rate_hz)
        self.robot_ip = robot_ip
        self.motion_port, self.state_port = int(motion_port), int(state_port)
        self.big_endian = big_endian
        self.stream_period_s = 1.0 / stream_rate_hz
        self.trajectory_sample_period_s = self.stream_period_s if points == "resampled" else None
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
        #: (fault, time.monotonic() of the refusal) from a refusal reported until the controller reports the
        #: robot at rest after it (the controller halts; its joints may still be on their way).
        self._after_refusal: tuple[str, float] | None = None
        #: The positions of the last point the controller refused: a streamed command still there is not
        #: sent again (it would be refused again), until it changes.
        self._refused_command: tuple[float, ...] | None = None
        self._stopping = False  # STOP sent, the robot not yet reported at rest since it was answered
        self._stop_answered_at: float | None = None  # time.monotonic() of the STOP's reply
        self._status_at = -float("inf")  # arrival of the last STATUS, time.monotonic() [s]
        self._error_since = -float("inf")  # arrival of the first STATUS in error of the last error [s]
        self._outbox: queue.SimpleQueue = queue.SimpleQueue()
        self._closing = threading.Event()
        self._motion: socket.socket | None = None
        self._state: socket.socket | None = None
        self._motion_lost: str | None = None  # why the motion connection is down, until re-opened
        self._motion_losses = 0  # motion connections lost so far ...
        self._motion_losses_reported = 0  # ... and when read() last reported one as the fault
        self._last_motion_loss = ""  # what the last loss said
        self._threads: list[threading.Thread] = []
        self.replies = 0  # points the controller acknowledged
        self._trajectory = 0  # the number of the trajectory in hand (each handed over or stopped: +1)
        self._unanswered = 0  # points of the trajectory in hand not yet answered (streaming) or sent
        self._done_at = -float("inf")  # time.monotonic() its last point was answered or sent
        self._rest_reports = 0  # STATUS reports since then saying the robot is not in motion
        #: (sequence, time.monotonic(), what it asked) of a point answered FAILURE, until reported.
        self._refused_point: tuple[int, float, str] | None = None
        self._awaiting_reply_since: float | None = None  # time.monotonic() a SERVICE_REQUEST was sent, unanswered
        self._trajectory_end: list[float] | None = None  # the last point of the trajectory in hand
        #: JOINT_POSITION reports received when ``position`` was last refreshed (by :meth:`read`).
        self.reports_read = 0
        self._state_listeners: list[tuple[Callable | None, Callable | None]] = []

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

    def add_state_listener(self, positions: Callable[[tuple[float, ...]], None] | None = None,
                           status: Callable[[RobotStatus], None] | None = None) -> None:
        """Call ``positions(reported positions)`` for every JOINT_POSITION (the first ``len(joint_names)``
        joints, [rad or m]) and ``status(message)`` for every STATUS, as each is read: on the state
        reader's thread, before the next one is read. A listener must return quickly and not raise."""
        self._state_listeners.append((positions, status))

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
            for listener, _ in self._state_listeners:
                if listener is not None:
                    listener(positions)
        elif isinstance(message, RobotStatus):
            if message.in_error == TRISTATE_TRUE and (self.status is None or self.status.in_error != TRISTATE_TRUE):
                self._error_since = now
            self.status = message
            self._status_at = now
            if message.in_motion == TRISTATE_TRUE:
                self._rest_reports = 0
            elif now > self._done_at:
                self._rest_reports += 1
            for _, listener in self._state_listeners:
                if listener is not None:
                    listener(message)

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
                else:  # (comm type, point, the trajectory it belongs to, where its segment starts)
                    comm, point, trajectory, start = item
                    if comm == CommType.TOPIC:  # sent, no reply to wait for
                        self._motion.sendall(encode(point, comm, big_endian=self.big_endian))
                        self._point_done(trajectory)
                    else:
                        self._request(point, trajectory, start)
            except (OSError, ConnectionError, MalformedPacket) as exc:
                if self._closing.is_set():
                    return
                self._last_motion_loss = f"lost the motion connection to {self.robot_ip}:{self.motion_port} ({exc})"
                self._motion_lost = self._last_motion_loss
                self._motion_losses += 1
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

    def _request(self, point: JointTrajPt | JointTrajPtFull, trajectory: int, start: Sequence[float] | None) -> None:
        """Send one point (its segment starting at ``start``) as a SERVICE_REQUEST and wait for the reply
        (the flow control). A FAILURE reply to a trajectory's point abandons the rest of that trajectory
        and is reported as a fault naming what the point asked."""
        sock = self._motion
        self._awaiting_reply_since = time.monotonic()
        try:
            self._await_reply(sock, point, trajectory, start)
        finally:
            self._awaiting_reply_since = None

    def _await_reply(self, sock: socket.socket, point: JointTrajPt | JointTrajPtFull, trajectory: int,
                     start: Sequence[float] | None) -> None:
        """Send ``point`` as a SERVICE_REQUEST on ``sock`` and handle its reply (see :meth:`_request`)."""
        sock.sendall(encode(point, CommType.SERVICE_REQUEST, big_endian=self.big_endian))
        reader = PacketReader(big_endian=self.big_endian)
        kind = MsgType.JOINT_TRAJ_PT_FULL if isinstance(point, JointTrajPtFull) else MsgType.JOINT_TRAJ_PT
        while True:
            data = sock.recv(4096)
            if not data:
                raise ConnectionError("the controller closed the motion connection")
            for packet in reader.feed(data):
                if packet.comm_type != CommType.SERVICE_REPLY or packet.msg_type != kind:
                    continue
                self.replies += 1
                if point.sequence == STOP_TRAJECTORY:
                    self._stop_answered_at = time.monotonic()
                elif trajectory != self._trajectory:
                    pass  # the answer to a point of a trajectory since replaced
                elif packet.reply_code != ReplyCode.SUCCESS:
                    self._drop_outbox()
                    self._unanswered = 0
                    self._refused_point = (point.sequence, time.monotonic(), self._asked(point, start))
                    self._refused_command = tuple(point.positions[: len(self.joint_names)])
                else:
                    self._point_done(trajectory)
                return

    def _asked(self, point: JointTrajPt | JointTrajPtFull, start: Sequence[float] | None) -> str:
        """What ``point`` asked of each joint: its position and the speed [per s] it asks, |Δq| from
        ``start`` over the segment's duration (JOINT_TRAJ_PT) or its velocity (JOINT_TRAJ_PT_FULL)."""
        items = []
        for i, name in enumerate(self.joint_names):
            q = point.positions[i]
            if isinstance(point, JointTrajPtFull):
                speed = abs(point.velocities[i])
            elif start is None:
                speed = None
            else:
                speed = abs(q - start[i]) / point.duration if point.duration > 0 else math.inf
            items.append(f"{name} {q:.6g}" + ("" if speed is None else f" at {speed:.6g}/s"))
        return "it asked " + ", ".join(items)

    def _reply_due(self) -> bool:
        """A point awaits its reply, and it was sent, or the controller's error first reported, less than
        ``ERROR_CODE_WAIT_S`` ago: the error is most likely that point's refusal, and its FAILURE reply, which
        names the point, is on its way (a controller may hold the reply for its flow control, then refuse the
        point when it takes it: the error STATUS then comes long after the request)."""
        since = self._awaiting_reply_since
        return since is not None and time.monotonic() < max(since, self._error_since) + ERROR_CODE_WAIT_S

    def _point_done(self, trajectory: int) -> None:
        """A point of trajectory number ``trajectory`` was answered (streaming) or sent (download):
        counted when that trajectory is the one in hand."""
        if trajectory == self._trajectory and self._unanswered > 0:
            self._unanswered -= 1
            if self._unanswered == 0:
                self._done_at = time.monotonic()
                self._rest_reports = 0

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
        self._trajectory += 1
        self._drop_outbox()
        self._unanswered = 0
        self._trajectory_end = None
        self._stop_answered_at = None
        self._stopping = True
        self.fault = STOPPING  # at once: nothing more is streamed in this cycle
        self._outbox.put((CommType.SERVICE_REQUEST, JointTrajPt(STOP_TRAJECTORY, (0.0,) * MAX_JOINTS, 0.0, 0.0),
                          self._trajectory, None))
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
        came_to_rest = self._stopping and self._stopped(status)
        if came_to_rest:
            # At rest there. The fault lasts this one more read, so that the executor takes this
            # position as its hold too: when it clears, the command is the rest and nothing is sent.
            self._stopping = False
            self._last_sent = list(self.position)
        after_refusal = self._after_refusal
        if after_refusal is not None and (status is None or (self._status_at > after_refusal[1]
                                                             and status.in_motion != TRISTATE_TRUE)):
            # At rest after the refusal (or no STATUS to say otherwise). The fault lasts this one more read,
            # so that the executor takes this position as its hold: when it clears, nothing is sent.
            self._after_refusal = None
        losses, motion_lost = self._motion_losses, self._motion_lost
        if motion_lost is None and losses != self._motion_losses_reported:
            motion_lost = self._last_motion_loss  # lost and re-opened since the last read: reported once
        refused_point = self._refused_point
        # The error code is a STATUS in error read after the FAILURE reply (a STATUS read after it but
        # sent before the refusal, still without the error, does not end the wait: the two ports race).
        coded = refused_point is not None and refused and self._status_at > refused_point[1]
        if refused_point is not None and (coded or time.monotonic() > refused_point[1] + ERROR_CODE_WAIT_S):
            # Reported until the controller reports the robot at rest: the goal aborts, the executor follows
            # the robot to where it comes to rest; the next motion starts a new trajectory (sequence 0), which
            # clears the controller's error.
            self._refused_point = None
            self._refusal_reported = True
            self._last_sent = None
            code = f"STATUS error_code {status.error_code}" if coded else "no error code reported"
            self.fault = (f"the controller refused point {refused_point[0]} of the trajectory (FAILURE; {code}): "
                          f"{refused_point[2]}")
            self._after_refusal = (self.fault, refused_point[1])
        elif motion_lost is not None:
            self.fault = motion_lost
            self._motion_losses_reported = losses
        elif self._stopping or came_to_rest:
            self.fault = STOPPING
        elif refused and not self._refusal_reported and refused_point is None and not self._reply_due():
            # (A refused point's own FAILURE reply, due or come, is reported above, naming the point.)
            # Reported until the controller reports the robot at rest, as above.
            self._refusal_reported = True
            self._last_sent = None
            self.fault = f"the controller refused a point (STATUS error_code {status.error_code})"
            self._after_refusal = (self.fault, self._status_at)
        elif self._state is None or age > self.stale_after_s:
            self.fault = (f"no joint state from {self.robot_ip}:{self.state_port} for {age:.1f} s"
                          if reported is not None else "no joint state yet")
            if age > self.stale_after_s:
                self.velocity[:] = [0.0] * len(self.velocity)
        elif after_refusal is not None:
            self.fault = after_refusal[0]
        else:
            self.fault = None
        if self.fault is not None:
            self._trajectory_end = None  # the executor follows the measured position now
        if not refused:
            self._refusal_reported = False

    def execute_trajectory(self, joint_indices: Sequence[int], times_s: Sequence[float],
                           positions: Sequence[Sequence[float]],
                           velocities: Sequence[Sequence[float]] | None = None,
                           accelerations: Sequence[Sequence[float]] | None = None) -> None:
        """Send a trajectory as ROS-I's client does (``hardware/ros_industrial_points.py``): each point
        with its speed fraction and its duration since the previous one (a first point at time 0 is
        where the robot is, and is not sent), as JOINT_TRAJ_PT or, with ``message="full"``,
        JOINT_TRAJ_PT_FULL (its time from the start, positions, velocities and accelerations). Streaming:
        requests with sequence 0, 1, 2..., each sent once the previous one was answered; download:
        topics from -1 to -3, a one-point trajectory twice. Joints not in ``joint_indices`` keep their
        last position command. :attr:`executing` is True until every point was answered (or sent) and
        the controller then reported the robot at rest."""
        base = list(self.command_buffer(POSITION))
        n = len(base)

        def rows(array, fill):
            if array is None:
                return None
            out = []
            for row in array:
                full = list(fill)
                for i, x in zip(joint_indices, row):
                    full[i] = float(x)
                out.append(full)
            return out

        points = wire_points(times_s, rows(positions, base), rows(velocities, [0.0] * n),
                             rows(accelerations, [0.0] * n), self.max_velocities, default_speed=self.default_speed)
        if not points:
            return
        self._trajectory += 1
        self._drop_outbox()
        self._refused_command = None
        if self.motion == "download":
            if len(points) == 1:
                points = points * 2
            last = len(points) - 1
            sequences = [START_TRAJECTORY_DOWNLOAD if k == 0 else END_TRAJECTORY if k == last else k
                         for k in range(len(points))]
        else:
            sequences = list(range(len(points)))
        self._unanswered = len(points)
        start = tuple(base)  # the first segment starts where the executor's command is: its plan's start
        for seq, point in zip(sequences, points):
            message = self._message(seq, point)
            comm = CommType.TOPIC if self.motion == "download" else CommType.SERVICE_REQUEST
            self._outbox.put((comm, message, self._trajectory, start))
            start = point.positions
        self._last_sent = list(points[-1].positions)
        self._trajectory_end = list(points[-1].positions)
        self._sequence = len(points)
        self._streaming = False

    def _message(self, seq: int, point: WirePoint) -> JointTrajPt | JointTrajPtFull:
        pad = (0.0,) * (MAX_JOINTS - len(point.positions))
        if self.message == "pt":
            return JointTrajPt(seq, point.positions + pad, point.speed_fraction, point.duration_s)
        fields = VALID_TIME | VALID_POSITION
        velocities = accelerations = (0.0,) * MAX_JOINTS
        if point.velocities is not None:
            fields |= VALID_VELOCITY
            velocities = point.velocities + pad
        if point.accelerations is not None:
            fields |= VALID_ACCELERATION
            accelerations = point.accelerations + pad
        return JointTrajPtFull(0, seq, fields, point.time_s, point.positions + pad, velocities, accelerations)

    @property
    def executing(self) -> bool:
        """True while the trajectory in hand has points not yet answered (or sent), and until the
        controller, after the last one, reported the robot at rest (twice: the ports race); a
        controller that never sent a STATUS is taken at its answers."""
        if self._unanswered > 0:
            return True
        if self.status is None or self._done_at == -float("inf"):
            return False
        return self._rest_reports < REST_REPORTS and not self._stopping

    def write(self) -> None:
        """Stream the position command, when no trajectory is in hand: every stream period, when it
        changed, as a point whose duration is the stream period and whose speed fraction is that of
        the critical joint's speed over the period (ROS-I's rule on velocities Δq / period)."""
        if self._time_s + 1e-9 < self._next_stream_s:
            return
        self._next_stream_s += self.stream_period_s
        command = self.command_buffer(POSITION)
        end = self._trajectory_end
        if end is not None:  # a trajectory in hand: the command is the executor's plan of it, not sent
            if all(abs(q - e) <= 1e-9 for q, e in zip(command, end)):
                self._trajectory_end = None  # the plan has reached its end
            return
        if command == self._last_sent or self.fault is not None:
            self._streaming = False  # a tick without a point: the motion (if any) has ended
            return
        refused = self._refused_command
        if refused is not None:
            if all(q == r or (math.isnan(q) and math.isnan(r)) for q, r in zip(command, refused)):
                self._streaming = False  # the command the controller refused: not sent again
                return
            self._refused_command = None
        if self._last_sent is None and all(abs(q - p) <= 1e-9 for q, p in zip(command, self.position)):
            # Holding where the robot is (after a refusal, the executor follows the measured position): no
            # motion, nothing to send; a motion from here starts a new trajectory (the robot is at rest).
            self._last_sent = list(command)
            self._streaming = False
            return
        if self._last_sent is None or not self._streaming and self._at_rest():
            self._sequence = 0  # a motion from rest: a new trajectory at the controller
        previous = self._last_sent if self._last_sent is not None else list(self.position)
        velocities = [(q - p) / self.stream_period_s for q, p in zip(command, previous)]
        point = WirePoint((self._sequence + 1) * self.stream_period_s, tuple(command), tuple(velocities), None,
                          speed_fraction(velocities, self.max_velocities, default=self.default_speed),
                          self.stream_period_s)
        self._outbox.put((CommType.SERVICE_REQUEST, self._message(self._sequence, point), self._trajectory,
                          tuple(previous)))
        self._sequence += 1
        self._last_sent = list(command)
        self._streaming = True

    def _at_rest(self) -> bool:
        status = self.status
        return status is not None and status.in_motion == 0

    def advance(self, period_s: float) -> None:
        self._time_s += period_s

    @property
    def connected(self) -> bool:
        """Both connections are open now (each is re-opened in the background after a loss)."""
        return self._state is not None and self._motion is not None and self._motion_lost is None

    @property
    def state_reports(self) -> int:
        """JOINT_POSITION packets received so far."""
        return self._state_reports


__all__ = ["MOTION_HANDSHAKES", "MOTION_PORT", "POINT_MESSAGES", "STATE_PORT", "STREAM_POINTS", "HardwareUnreachable",
           "IndustrialHardware"]

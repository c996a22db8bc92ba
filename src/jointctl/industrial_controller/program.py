"""The motion program of a simulated industrial controller: simple_message packets in, replies and joint references out.

Section 11.5 of the chapter: "write the equivalent of the example trajectory action server in the
native language of the target robot (and run it on the native robot controller)". This is that
program, free of sockets and of the simulator: :meth:`ControllerProgram.handle` takes one packet
of the MOTION connection and returns the reply to send (or None); :meth:`ControllerProgram.cycle`
advances the controller's own :class:`~jointctl.industrial_controller.interpolator.Interpolator` by one servo
period and returns the joint references for its servos. Both may run in different threads (a
connection's reader and the servo loop): they share one lock.

What it answers (ROS-Industrial's handshakes, facts §5 and §7):

- **Streaming** (``motion_streaming_interface``): JOINT_TRAJ_PT SERVICE_REQUESTs with sequence
  numbers 0, 1, 2...; each point is checked, queued and answered SUCCESS. While the queue is full
  the answer is held back (the sender waits for it: that is the flow control). Sequence 0 (or
  -2, START_TRAJECTORY_STREAMING) starts a new trajectory: the queue is forgotten and the motion
  continues from where the reference is.
- **Download** (``motion_download_interface``): JOINT_TRAJ_PT TOPICs from sequence -1
  (START_TRAJECTORY_DOWNLOAD, the first point) through the indices to -3 (END_TRAJECTORY, the
  last point), each checked on arrival and kept; nothing moves until -3, then the whole trajectory
  is executed as a new one. At most ``download_capacity`` points.
- **Stop** (sequence -4, STOP_TRAJECTORY, request or topic): the queue and any download are
  cleared and each joint decelerates to rest within its limits; a request is answered SUCCESS.
  Points of the stopped trajectory that arrive later (sequence > 0) are answered FAILURE and
  ignored: only a new trajectory moves the robot again.
- **PING** requests are answered SUCCESS; any other request FAILURE (an empty body, as
  ``MessageManager`` does); topics of other types are ignored.

Refusals. A point the interpolator refuses (wrong joint count, non-finite, outside a joint's range,
bad speed fraction or duration) or a JOINT_TRAJ_PT whose body cannot be decoded is answered
FAILURE and moves nothing: it stops the trajectory it belongs to (the queue is cleared and a
moving robot decelerates to rest, as on STOP), later points of that trajectory are answered
FAILURE, and STATUS reports ``in_error`` with :attr:`ControllerProgram.error_code` until a new
trajectory begins. A lost connection (:meth:`connection_lost`) stops the motion the same way.

Joint ``i`` of a packet is joint ``i`` of the limits given (the controller's joint order); the
packets' padding beyond the controller's joints is ignored. Units: rad or m, s.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable, Sequence

from jointctl.errors import MalformedPacket
from jointctl.industrial_controller.interpolator import Interpolator, JointLimits, Point, RefusedPoint
from jointctl.wire.simple_message import (
    END_TRAJECTORY,
    MODE_AUTO,
    START_TRAJECTORY_DOWNLOAD,
    START_TRAJECTORY_STREAMING,
    STOP_TRAJECTORY,
    TRISTATE_FALSE,
    TRISTATE_TRUE,
    VALID_TIME,
    VALID_VELOCITY,
    CommType,
    JointTrajPt,
    JointTrajPtFull,
    MsgType,
    Packet,
    PacketReader,
    ReplyCode,
    RobotStatus,
    decode,
    encode_reply,
)

#: STATUS ``error_code`` values beyond the interpolator's (1-5, ``jointctl.industrial_controller.interpolator``).
ERROR_MALFORMED_POINT = 6    # a JOINT_TRAJ_PT whose body cannot be decoded
ERROR_DOWNLOAD_FULL = 7      # a download longer than ``download_capacity`` points
ERROR_NO_DOWNLOAD = 8        # END_TRAJECTORY (-3) without START_TRAJECTORY_DOWNLOAD (-1) before it

#: How long a held reply waits between checks that its connection is still wanted [s].
FLOW_CONTROL_POLL_S = 0.05


class ControllerProgram:
    """The controller's motion program (see the module docstring). ``limits`` and ``start`` as for
    :class:`~jointctl.industrial_controller.interpolator.Interpolator`; ``capacity``: the streaming queue's
    size in points; ``download_capacity``: the longest download in points."""

    def __init__(self, limits: Sequence[JointLimits], start: Sequence[float], *, big_endian: bool = False,
                 capacity: int = 32, download_capacity: int = 10_000,
                 on_event: Callable[[str], None] | None = None) -> None:
        self.interpolator = Interpolator(limits, start, capacity=capacity)
        self.joint_count = len(self.interpolator.limits)
        self.big_endian = big_endian
        self.download_capacity = download_capacity
        self._lock = threading.Condition()
        self._waiting = 0                        # handlers holding a reply back (flow control)
        self._backlog: deque[Point] = deque()    # downloaded points waiting for room in the queue
        self._download: list[Point] | None = None
        self._time_s = 0.0                       # the trajectory's last FULL point's time [s]
        self._accepting = True                   # False after a refusal or a STOP, until a new trajectory
        #: The last refusal's code (``ERROR_*`` of the interpolator or of this module), 0 when none.
        self.error_code = 0
        #: Called with one line for each STOP and each refusal (the controller's log).
        self.on_event = on_event
        #: Points queued (streamed) or executed (downloaded) so far; and refused so far.
        self.accepted = 0
        self.refused = 0

    # -- the motion connection ----------------------------------------------------------------------
    def handle(self, packet: Packet, keep_waiting: Callable[[], bool] = lambda: True) -> bytes | None:
        """Act on one packet of the motion connection; the bytes to send back, or None.

        A streamed point that finds the queue full waits for room while ``keep_waiting()`` is true
        (checked every :data:`FLOW_CONTROL_POLL_S`); when it turns false the point is dropped and
        no reply is sent. Never raises for anything a packet holds."""
        request = packet.comm_type == CommType.SERVICE_REQUEST
        if packet.comm_type == CommType.SERVICE_REPLY:
            return None
        if packet.msg_type == MsgType.PING and request:
            return self._reply(packet, ReplyCode.SUCCESS if not packet.body else ReplyCode.FAILURE)
        if packet.msg_type not in (MsgType.JOINT_TRAJ_PT, MsgType.JOINT_TRAJ_PT_FULL):
            return self._reply(packet, ReplyCode.FAILURE, echo_body=False) if request else None
        try:
            message: JointTrajPt | JointTrajPtFull = decode(packet, big_endian=self.big_endian)
            if isinstance(message, JointTrajPtFull) and not message.valid_fields & VALID_TIME \
                    and message.sequence != STOP_TRAJECTORY:
                raise MalformedPacket("a JOINT_TRAJ_PT_FULL point needs its time (valid_fields bit 0x01)",
                                      field="valid_fields", value=message.valid_fields)
        except MalformedPacket as exc:
            with self._lock:
                self._refuse(ERROR_MALFORMED_POINT, str(exc))
            return self._reply(packet, ReplyCode.FAILURE) if request else None
        code = self._on_point(message, keep_waiting)
        if code is None or not request:
            return None
        return self._reply(packet, code)

    def connection_lost(self) -> None:
        """The motion client went away: stop as on STOP (decelerate to rest, forget queued points)."""
        with self._lock:
            self._stop()

    def _reply(self, packet: Packet, code: ReplyCode, *, echo_body: bool = True) -> bytes:
        return encode_reply(packet, code, echo_body=echo_body, big_endian=self.big_endian)

    def _point(self, message: JointTrajPt | JointTrajPtFull) -> Point:
        """The interpolator's point for a JOINT_TRAJ_PT (speed fraction and duration as sent) or a
        JOINT_TRAJ_PT_FULL (reached by its time since the trajectory's previous point, the joints'
        limits only; a cubic when its velocities are valid). Lock held."""
        n = self.joint_count
        positions = tuple(message.positions[:n])
        if isinstance(message, JointTrajPt):
            return Point(positions, message.velocity, message.duration)
        velocities = tuple(message.velocities[:n]) if message.valid_fields & VALID_VELOCITY else None
        return Point(positions, 1.0, message.time - self._time_s, velocities)

    def _on_point(self, message: JointTrajPt | JointTrajPtFull, keep_waiting: Callable[[], bool]) -> ReplyCode | None:
        seq = message.sequence
        with self._lock:
            if seq in (0, START_TRAJECTORY_STREAMING, START_TRAJECTORY_DOWNLOAD):
                self._time_s = 0.0  # a FULL point's time counts from its trajectory's start
            point = self._point(message)
            if isinstance(message, JointTrajPtFull) and seq >= 0:
                self._time_s = message.time
            if seq == STOP_TRAJECTORY:
                self._stop()
                self._log("STOP: decelerating to rest, queue cleared")
                return ReplyCode.SUCCESS
            if seq == START_TRAJECTORY_DOWNLOAD:
                self._new_trajectory()
                self._download = []
                return self._keep_downloaded(point)
            if seq == END_TRAJECTORY:
                if not self._accepting:
                    return ReplyCode.FAILURE
                if self._download is None:
                    self._refuse(ERROR_NO_DOWNLOAD, "END_TRAJECTORY (-3) without START_TRAJECTORY_DOWNLOAD (-1)")
                    return ReplyCode.FAILURE
                code = self._keep_downloaded(point)
                if code is ReplyCode.SUCCESS:
                    self._backlog.extend(self._download)
                    self.accepted += len(self._download)
                    self._download = None
                return code
            if seq < 0 and seq != START_TRAJECTORY_STREAMING:
                self._refuse(ERROR_MALFORMED_POINT, f"sequence: no such special value (got {seq})")
                return ReplyCode.FAILURE
            if seq in (0, START_TRAJECTORY_STREAMING):
                self._new_trajectory()
            elif not self._accepting:
                return ReplyCode.FAILURE
            if self._download is not None:
                return self._keep_downloaded(point)
            return self._queue(point, keep_waiting)

    def _queue(self, point: Point, keep_waiting: Callable[[], bool]) -> ReplyCode | None:
        """Queue a streamed point, holding the reply while the queue is full (lock held)."""
        interpolator = self.interpolator
        try:
            interpolator.check(point)
        except RefusedPoint as refusal:
            self._refuse(refusal.error_code, str(refusal))
            return ReplyCode.FAILURE
        self._waiting += 1
        try:
            while interpolator.full or self._backlog:
                if not keep_waiting():
                    return None
                self._lock.wait(FLOW_CONTROL_POLL_S)
                if not self._accepting:  # stopped or refused while this point waited
                    return ReplyCode.FAILURE
        finally:
            self._waiting -= 1
        interpolator.push(point)
        self.accepted += 1
        return ReplyCode.SUCCESS

    def _keep_downloaded(self, point: Point) -> ReplyCode:
        """Check a downloaded point and keep it for END_TRAJECTORY (lock held)."""
        if not self._accepting:
            return ReplyCode.FAILURE
        try:
            self.interpolator.check(point)
        except RefusedPoint as refusal:
            self._refuse(refusal.error_code, str(refusal))
            return ReplyCode.FAILURE
        if len(self._download) >= self.download_capacity:
            self._refuse(ERROR_DOWNLOAD_FULL, f"a download holds at most {self.download_capacity} points")
            return ReplyCode.FAILURE
        self._download.append(point)
        return ReplyCode.SUCCESS

    def _new_trajectory(self) -> None:
        self.interpolator.new_trajectory()
        self._backlog.clear()
        self._download = None
        self._accepting = True
        self.error_code = 0
        self._lock.notify_all()

    def _stop(self) -> None:
        self.interpolator.stop()
        self._backlog.clear()
        self._download = None
        self._accepting = False
        self._lock.notify_all()

    def _refuse(self, error_code: int, why: str) -> None:
        self.refused += 1
        self.error_code = error_code
        self._stop()
        self._log(f"refused a point (error_code {error_code}): {why}; the trajectory is stopped")

    def _log(self, line: str) -> None:
        if self.on_event is not None:
            self.on_event(line)

    # -- the servo loop -----------------------------------------------------------------------------
    def cycle(self, period_s: float) -> tuple[list[float], list[float], list[float]]:
        """Advance the interpolator by ``period_s`` [s]: the (positions, velocities, accelerations)
        references of the joints [rad or m, per s, per s²]. Downloaded points move into the queue as
        it has room, and a reply held back for room is released."""
        with self._lock:
            interpolator, backlog = self.interpolator, self._backlog
            while backlog and not interpolator.full:
                interpolator.push(backlog.popleft())
            positions, velocities = interpolator.step(period_s)
            if self._waiting and not interpolator.full:
                self._lock.notify_all()
            return positions, velocities, interpolator.acceleration

    # -- STATUS ------------------------------------------------------------------------------------
    @property
    def in_motion(self) -> bool:
        """True while the interpolator moves the references or has points to go to."""
        with self._lock:
            return self.interpolator.in_motion or bool(self._backlog)

    def status(self, joints_moving: bool = False) -> RobotStatus:
        """The STATUS to report: drives on, no e-stop, AUTO, motion possible; ``in_motion`` when the
        references move or ``joints_moving`` (the measured joints still settle); ``in_error`` and
        ``error_code`` after a refusal, until a new trajectory."""
        in_motion = self.in_motion or joints_moving
        error = self.error_code
        return RobotStatus(drives_powered=TRISTATE_TRUE, e_stopped=TRISTATE_FALSE, error_code=error,
                           in_error=TRISTATE_TRUE if error else TRISTATE_FALSE,
                           in_motion=TRISTATE_TRUE if in_motion else TRISTATE_FALSE, mode=MODE_AUTO,
                           motion_possible=TRISTATE_TRUE)


class MotionConnection:
    """One client's byte stream on the motion port, framed and answered by ``program``.

    :meth:`feed` takes the bytes received and returns the replies to send, in order. A packet whose
    header is invalid is skipped (framing is intact); a length prefix out of range loses the
    framing for good: :attr:`closed` turns true and the connection must be closed (the client
    reconnects). Never raises for anything the bytes hold."""

    def __init__(self, program: ControllerProgram, keep_waiting: Callable[[], bool] = lambda: True) -> None:
        self.program = program
        self.keep_waiting = keep_waiting
        self._reader = PacketReader(big_endian=program.big_endian)
        #: True once the stream's framing is lost.
        self.closed = False
        #: Packets skipped for an invalid header.
        self.skipped = 0

    def feed(self, data: bytes) -> list[bytes]:
        replies: list[bytes] = []
        while not self.closed:
            try:
                packets = self._reader.feed(data)
            except MalformedPacket:
                if self._reader.poisoned:
                    self.closed = True
                    break
                self.skipped += 1
                data = b""
                continue  # the packets after the bad one come with the next feed
            for packet in packets:
                reply = self.program.handle(packet, self.keep_waiting)
                if reply is not None:
                    replies.append(reply)
            if not packets:
                break
            data = b""  # a bad header may wait behind these packets, and good ones behind it
        return replies


__all__ = ["ERROR_DOWNLOAD_FULL", "ERROR_MALFORMED_POINT", "ERROR_NO_DOWNLOAD", "FLOW_CONTROL_POLL_S",
           "ControllerProgram", "MotionConnection"]

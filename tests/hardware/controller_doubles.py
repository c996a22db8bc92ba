"""Robot controllers of the kinds users own, as simple_message peers on loopback, built from the
reference behaviour (simple-message-facts.md §7-§10), not from jointctl's own conventions:

- ``"duration"``: a controller program on ROS-I's reference ``simple_message`` library that reaches
  each JOINT_TRAJ_PT over its ``duration`` by linear interpolation, on a 100 Hz interpolation tick:
  each point costs one 10 ms tick on top of its duration (the tick on which it is taken from the
  queue). The speed fraction is ignored.
- ``"speed"``: a controller that moves only by the speed fraction, as most industrial motion
  programs do (``MOVJ ... VJ=fraction``): each segment takes ``max_i |Δq_i| / (fraction · v_max,i)``;
  the duration is ignored; a fraction of 0 (or less, or above 1) is answered FAILURE with STATUS
  ``in_error`` and an error code, and stops the trajectory until a new one begins.
- ``"full"``: a controller that takes JOINT_TRAJ_PT_FULL points by their ``time`` (from the
  trajectory's start, linear between points); a JOINT_TRAJ_PT is answered FAILURE.

All of them: the STATE port pushes JOINT_POSITION and STATUS (TOPIC) every 10 ms with a truthful
``in_motion``; the MOTION port takes points as SERVICE_REQUESTs (sequence 0 starts a new
trajectory), queues up to ``capacity`` and holds the reply while the queue is full (the flow
control); STOP (-4) clears the queue, the joints stop where they are, and is answered. Every point
received is kept in ``points`` (the decoded message) with the double's clock when it arrived.
Download (ROS-I's ``motion_download_interface``, facts §7): points sent as TOPIC from sequence -1
(a new trajectory) to -3 are collected, checked as above, and executed only after the -3; a refused
one gets no reply (a topic has none): the refusal is only the STATUS error.

Options: ``error_status=False``, a controller that answers FAILURE without ever reporting the error in
its STATUS (``in_error`` 0, ``error_code`` 0; the reference relays STATUS as the controller sends it);
``state_period_s=None``, a STATE port that sends one report on connect and then one per
:meth:`report` call (the test decides when each report leaves).
"""

from __future__ import annotations

import math
import queue
import socket
import threading
import time
from collections import deque

from jointctl.wire.simple_message import (
    END_TRAJECTORY,
    START_TRAJECTORY_DOWNLOAD,
    STOP_TRAJECTORY,
    CommType,
    JointPosition,
    JointTrajPt,
    JointTrajPtFull,
    PacketReader,
    ReplyCode,
    RobotStatus,
    decode,
    encode,
    encode_reply,
)

KINDS = ("duration", "speed", "full")
TICK_S = 0.01           # the reference library's interpolation tick (100 Hz)
ERROR_BAD_SPEED = 21    # STATUS error_code of the "speed" double for a fraction outside (0, 1]
ERROR_NOT_FULL = 22     # STATUS error_code of the "full" double for a JOINT_TRAJ_PT


class ControllerDouble:
    """One of :data:`KINDS` (see the module docstring) for joints with ``max_velocities`` [rad/s],
    starting at ``positions``."""

    def __init__(self, kind: str, positions, max_velocities, *, capacity: int = 8,
                 period_s: float = 0.01, failure_reply_delay_s: float = 0.0,
                 stale_status_after_failure: bool = False, error_status: bool = True,
                 state_period_s: float | None = 0.01) -> None:
        assert kind in KINDS
        self.kind, self.capacity, self.period_s = kind, capacity, period_s
        #: Whether a refusal sets STATUS ``in_error`` and ``error_code`` (False: FAILURE replies only).
        self.error_status = error_status
        #: The STATE port's period [s]; None: one report on connect, then one per :meth:`report`.
        self.state_period_s = state_period_s
        self._reports: queue.SimpleQueue = queue.SimpleQueue()
        self._download: list | None = None  # the download trajectory's points being collected
        #: How long a FAILURE reply waits after its STATUS error is reported [s] (a controller that says
        #: the error on the state port before it answers the request).
        self.failure_reply_delay_s = failure_reply_delay_s
        #: A STATUS without the error arrives after the FAILURE reply: it was on its way on the state port
        #: when the point was refused (the two ports race); the error follows in the next STATUS.
        self.stale_status_after_failure = stale_status_after_failure
        self._masked = False     # the error is not in the STATUS yet (the stale ones)
        self._reply_out = False  # ... and the FAILURE reply has been sent: one more stale STATUS, then the error
        self.max_velocities = list(max_velocities)
        self.positions = list(map(float, positions))
        self.points: list[tuple[float, JointTrajPt | JointTrajPtFull]] = []
        self.stops = 0
        self.error_code = 0
        self._queue: deque = deque()       # (target positions, segment length [s])
        self._segment = None               # [start, target, length, elapsed]
        self._last_time = 0.0              # the trajectory's previous FULL point's time
        self._accepting = True
        self._clock = time.monotonic()
        self.lock = threading.Condition()
        self.closing = threading.Event()
        self.servers = [socket.create_server(("127.0.0.1", 0)) for _ in range(2)]
        self.motion_port, self.state_port = (s.getsockname()[1] for s in self.servers)
        self._connections: list[socket.socket] = []
        self._threads = [threading.Thread(target=self._state, daemon=True),
                         threading.Thread(target=self._motion, daemon=True)]
        for thread in self._threads:
            thread.start()

    # -- motion (under self.lock) ------------------------------------------------------------------
    def _advance(self) -> None:
        now = time.monotonic()
        left, self._clock = now - self._clock, now
        while left > 0:
            if self._segment is None:
                if not self._queue:
                    break
                target, length = self._queue.popleft()
                self._segment = [list(self.positions), target, length, 0.0]
            start, target, length, elapsed = self._segment
            take = min(left, length - elapsed)
            elapsed += take
            left -= take
            s = 1.0 if elapsed >= length else elapsed / length
            self.positions = [a + (b - a) * s for a, b in zip(start, target)]
            self._segment[3] = elapsed
            if s >= 1.0:
                self._segment = None
        self.lock.notify_all()

    @property
    def in_motion(self) -> bool:
        with self.lock:
            return bool(self._queue) or self._segment is not None

    def _length(self, target, message) -> float | None:
        """The segment's length [s] to ``target`` by this kind's rule; None: refused."""
        if self.kind == "duration":
            return message.duration + TICK_S
        if self.kind == "speed":
            fraction = message.velocity
            if not 0.0 < fraction <= 1.0:
                return None
            start = self._queue[-1][0] if self._queue else (self._segment[1] if self._segment else self.positions)
            return max((abs(b - a) / (fraction * v) for a, b, v in zip(start, target, self.max_velocities)),
                       default=0.0)
        length = message.time - self._last_time
        self._last_time = message.time
        return max(length, 0.0)

    def _on_point(self, message) -> ReplyCode:
        n = len(self.positions)
        with self.lock:
            self._advance()
            if message.sequence == STOP_TRAJECTORY:
                self.stops += 1
                self._queue.clear()
                self._segment = None  # the joints stop where they are
                self._accepting = False
                return ReplyCode.SUCCESS
            if message.sequence == 0:
                self._queue.clear()
                self._segment = None
                self._last_time = 0.0
                self._accepting = True
                self.error_code = 0
            elif not self._accepting:
                return ReplyCode.FAILURE
            if (self.kind == "full") != isinstance(message, JointTrajPtFull):
                self.error_code, self._accepting = ERROR_NOT_FULL, False
                self._masked = self.stale_status_after_failure
                return ReplyCode.FAILURE
            target = list(message.positions[:n])
            length = self._length(target, message)
            if length is None:
                self.error_code, self._accepting = ERROR_BAD_SPEED, False
                self._queue.clear()
                self._segment = None
                return ReplyCode.FAILURE
            while len(self._queue) >= self.capacity and not self.closing.is_set():
                self.lock.wait(self.period_s)  # flow control: the reply waits for room
                self._advance()
            self._queue.append((target, length))
            return ReplyCode.SUCCESS

    # -- sockets -----------------------------------------------------------------------------------
    def _accept(self, server: socket.socket) -> socket.socket | None:
        while not self.closing.is_set():
            try:
                server.settimeout(0.1)
                conn, _ = server.accept()
            except TimeoutError:
                continue
            except OSError:
                return None
            self._connections.append(conn)
            return conn
        return None

    def _state(self) -> None:
        while (conn := self._accept(self.servers[1])) is not None:
            try:
                while not self.closing.is_set():
                    with self.lock:
                        self._advance()
                        positions = tuple(self.positions)
                        moving = bool(self._queue) or self._segment is not None
                        error = 0 if self._masked else self.error_code
                        if self._masked and self._reply_out:
                            self._masked = self._reply_out = False
                    if not self.error_status:
                        error = 0
                    status = RobotStatus(1, 0, error, 1 if error else 0, int(moving), 2, 1)
                    conn.sendall(encode(JointPosition(0, positions)) + encode(status))
                    if self.state_period_s is not None:
                        self.closing.wait(self.state_period_s)
                        continue
                    while not self.closing.is_set():
                        try:
                            self._reports.get(timeout=0.1)
                            break
                        except queue.Empty:
                            continue
            except OSError:
                continue

    def _motion(self) -> None:
        while (conn := self._accept(self.servers[0])) is not None:
            reader = PacketReader()
            try:
                while not self.closing.is_set():
                    data = conn.recv(4096)
                    if not data:
                        break
                    for packet in reader.feed(data):
                        message = decode(packet)
                        self.points.append((time.monotonic(), message))
                        if packet.comm_type == CommType.TOPIC:
                            self._on_download(message)
                            continue
                        assert packet.comm_type == CommType.SERVICE_REQUEST
                        code = self._on_point(message)
                        if code == ReplyCode.FAILURE and self.failure_reply_delay_s:
                            self.closing.wait(self.failure_reply_delay_s)
                        conn.sendall(encode_reply(packet, code))
                        with self.lock:
                            self._reply_out = self._masked
            except OSError:
                continue
            with self.lock:
                self._queue.clear()
                self._segment = None

    def _on_download(self, message) -> None:
        """A point of a download (TOPIC): -1 begins a trajectory, -3 ends it and starts its execution."""
        with self.lock:
            self._advance()
            if message.sequence == START_TRAJECTORY_DOWNLOAD:
                self._queue.clear()
                self._segment = None
                self._last_time = 0.0
                self._accepting = True
                self.error_code = 0
                self._download = []
            if self._download is None or not self._accepting:
                return
            if (self.kind == "full") != isinstance(message, JointTrajPtFull):
                self.error_code, self._accepting, self._download = ERROR_NOT_FULL, False, None
                return
            target = list(message.positions[: len(self.positions)])
            start = self._download[-1][0] if self._download else self.positions
            if self.kind == "speed" and not 0.0 < message.velocity <= 1.0:
                self.error_code, self._accepting, self._download = ERROR_BAD_SPEED, False, None
                return
            if self.kind == "speed":
                length = max((abs(b - a) / (message.velocity * v) for a, b, v in
                              zip(start, target, self.max_velocities)), default=0.0)
            else:
                length = self._length(target, message)
            self._download.append((target, length))
            if message.sequence == END_TRAJECTORY:
                self._queue.extend(self._download)
                self._download = None

    def report(self) -> None:
        """With ``state_period_s=None``: send one JOINT_POSITION and STATUS now (from the state thread)."""
        self._reports.put(True)

    def trajectory_points(self) -> list:
        """The points received since the last sequence 0 (or -1, a download's first), STOPs left out."""
        messages = [m for _, m in self.points if m.sequence != STOP_TRAJECTORY]
        starts = [k for k, m in enumerate(messages) if m.sequence in (0, START_TRAJECTORY_DOWNLOAD)]
        return messages[starts[-1]:] if starts else []

    def close(self) -> None:
        self.closing.set()
        for conn in self._connections:
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            conn.close()
        for server in self.servers:
            server.close()
        for thread in self._threads:
            thread.join(2.0)


def ros_i_fraction(velocities, max_velocities, default: float = 0.1) -> float:
    """ROS-I's ``calc_velocity`` written again from simple-message-facts.md §7, for the tests'
    expectations (independent of jointctl's implementation)."""
    if not velocities:
        return default
    ratios = [abs(v / m) if math.isfinite(m) and m > 0 else -1.0 for v, m in zip(velocities, max_velocities)]
    best = max(ratios)
    fraction = best if best > 0 else default
    return min(1.0, max(0.0, fraction))

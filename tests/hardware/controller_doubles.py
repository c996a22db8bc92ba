"""A robot controller as a simple_message peer on loopback, built from the reference behaviour
(simple-message-facts.md §7-§10: what a controller must do for ROS-I's stock client; §9: how
``industrial_robot_simulator`` moves and refuses), not from jointctl's own conventions. One double,
with options for the kinds users own:

- ``"duration"``: a controller program on ROS-I's reference ``simple_message`` library that reaches
  each JOINT_TRAJ_PT over its ``duration`` by linear interpolation, on an interpolation tick of
  ``tick_s`` (10 ms, 100 Hz): each point costs one tick on top of its duration (the tick on which it
  is taken from the queue). The speed fraction is ignored. A point whose segment asks a joint for
  more than its speed limit (``|Δq| / duration > max_velocity``) is refused.
- ``"speed"``: a controller that moves only by the speed fraction, as most industrial motion
  programs do (``MOVJ ... VJ=fraction``): each segment takes ``max_i |Δq_i| / (fraction · v_max,i)``;
  the duration is ignored; a fraction of 0 (or less, or above 1) is refused.
- ``"full"``: a controller that takes JOINT_TRAJ_PT_FULL points by their ``time`` (from the
  trajectory's start, linear between points); a JOINT_TRAJ_PT is refused, and so is a point whose
  velocity exceeds a joint's speed limit (MotoROS's ``Ros_MotionServer_AddTrajPointFull``:
  ``|vel_i| > maxSpeed_i``, INVALID_DATA_SPEED).

Every kind checks each point against its joints' ``ranges`` (the controller's soft limits, which may
be narrower than the URDF's) as ``lower <= q <= upper``, so that a NaN, for which every comparison is
false, is refused too. A refused point is answered FAILURE (its body echoed, as the reference's
``toReply``), sets STATUS ``in_error`` and an ``error_code`` (``ERROR_*`` below), and stops the
trajectory it belongs to, as ``industrial_robot_simulator`` stops on a trajectory it refuses: the
queue is dropped, the interpolator halts where it is, and later points of that trajectory are answered
FAILURE until a new one begins (sequence 0), which clears the error.

All kinds: the STATE port pushes JOINT_POSITION and STATUS (TOPIC) every ``state_period_s`` while
``publishing`` is set, with a truthful ``in_motion`` (points queued, a segment running, or a joint
not yet settled); the MOTION port takes points as SERVICE_REQUESTs (sequence 0 starts a new
trajectory, from where the interpolator is), queues up to ``capacity`` and holds the reply while the
queue is full (the flow control) and while ``hold`` is set, and checks a point when it takes it into
the queue (as MotoROS answers BUSY before it checks); STOP (-4) drops the queue, halts the
interpolator where it is, and is answered; a client gone mid-motion stops it the same way.
Download (ROS-I's ``motion_download_interface``, facts §7): points sent as TOPIC from sequence -1
(a new trajectory) to -3 are collected, checked as above, and executed only after the -3; a refused
one gets no reply (a topic has none): the refusal is only the STATUS error.

Servo lag: the measured joints (``positions``, what JOINT_POSITION reports) follow the interpolator's
output through a first-order lag of time constant ``lag_s``, solved exactly over each piece of the
piecewise-linear reference: on a ramp of speed v they trail the reference by v·lag_s once the
transient has died out (within e^(-t/lag_s) of it t after the ramp began); after the reference stops
they settle onto it (a joint halted at speed v comes to rest up to v·lag_s beyond where it was
measured), and are reported at rest once within ``SETTLED`` of it.

Records: every point received in ``points`` (the decoded message) and, with the index of the motion
connection it came on and its arrival (``time.monotonic()``), in ``received``; every state report in
``reports`` as (``time.time()``, positions, in_motion); ``stops`` counts STOPs; ``halts`` keeps where the
joints were and where the interpolator halted at each STOP and refusal.

Options: ``error_status=False``, a controller that answers FAILURE without ever reporting the error in
its STATUS (``in_error`` 0, ``error_code`` 0; the reference relays STATUS as the controller sends it);
``state_period_s=None``, a STATE port that sends one report on connect and then one per
:meth:`report` call (the test decides when each report leaves); ``failure_reply_delay_s``, a FAILURE
reply that leaves that long after its STATUS error; ``stale_status_after_failure``, one STATUS
without the error read after the FAILURE reply (it was on its way when the point was refused);
``big_endian``, the ``_bswap`` nodes' byte order; ``step_per_report``, added to the first joint
after each report (reports told apart by their value).
"""

from __future__ import annotations

import math
import queue
import re
import socket
import threading
import time
from collections import deque

import numpy as np

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
LAG_S = 0.05            # the servo lag's time constant [s]
ERROR_BAD_SPEED = 21    # STATUS error_code: a speed fraction outside (0, 1] ("speed")
ERROR_NOT_FULL = 22     # STATUS error_code: a JOINT_TRAJ_PT sent to the "full" controller
ERROR_RANGE = 23        # STATUS error_code: a position outside the joint's range, or not a number
ERROR_TOO_FAST = 24     # STATUS error_code: a joint asked for more than its speed limit
#: The float32 rounding the speed check allows: positions and durations cross the wire as float32.
_F32 = float(np.finfo(np.float32).eps)


def _too_fast(start, target, seconds: float, limits) -> bool:
    """Whether going from ``start`` to ``target`` in ``seconds`` asks a joint for more than its limit
    [rad/s or m/s], allowing the float32 rounding of both ends and of the duration."""
    for a, b, limit in zip(start, target, limits):
        slack = 4 * _F32 * (abs(a) + abs(b) + limit * seconds)
        if not abs(b - a) <= limit * seconds + slack:
            return True
    return False


class ControllerDouble:
    """One of :data:`KINDS` (see the module docstring) for joints with ``max_velocities`` [rad/s or
    m/s; None: no limit] and ``ranges`` ((lower, upper) per joint; None: no soft limits, only the
    NaN check), starting at rest at ``positions``."""

    SETTLED = 1e-6  # |measured - reference| below which a joint at rest has settled [rad or m]

    def __init__(self, kind: str = "duration", positions=(0.1, -0.2), max_velocities=None, *, ranges=None,
                 capacity: int = 8, lag_s: float = LAG_S, tick_s: float = TICK_S,
                 state_period_s: float | None = 0.01, big_endian: bool = False, error_status: bool = True,
                 failure_reply_delay_s: float = 0.0, stale_status_after_failure: bool = False) -> None:
        assert kind in KINDS
        n = len(positions)
        self.kind, self.capacity, self.lag_s, self.tick_s = kind, capacity, lag_s, tick_s
        self.max_velocities = list(max_velocities) if max_velocities is not None else [math.inf] * n
        self.ranges = [tuple(r) for r in ranges] if ranges is not None else [(-math.inf, math.inf)] * n
        assert len(self.max_velocities) == n and len(self.ranges) == n
        self.big_endian = big_endian
        #: Whether a refusal sets STATUS ``in_error`` and ``error_code`` (False: FAILURE replies only).
        self.error_status = error_status
        #: The STATE port's period [s]; None: one report on connect, then one per :meth:`report`.
        self.state_period_s = state_period_s
        self.failure_reply_delay_s = failure_reply_delay_s
        self.stale_status_after_failure = stale_status_after_failure
        self.step_per_report = 0.0
        self.positions = list(map(float, positions))   # measured
        self._reference = list(self.positions)         # the interpolator's output
        self.points: list[JointTrajPt | JointTrajPtFull] = []
        self.received: list[tuple[int, float, JointTrajPt | JointTrajPtFull]] = []
        self.reports: list[tuple[float, tuple[float, ...], int]] = []
        self.stops = 0
        #: (measured, reference) at each STOP and each refusal: where the joints were and where the
        #: interpolator halted (the joints then settle onto it).
        self.halts: list[tuple[list[float], list[float]]] = []
        self.error_code = 0
        self._queue: deque = deque()       # (target positions, segment length [s])
        self._segment = None               # [start, target, length, elapsed]
        self._last_time = 0.0              # the trajectory's previous FULL point's time
        self._accepting = True
        self._download: list | None = None  # the download trajectory's points being collected
        self._masked = False     # the error is not in the STATUS yet (the stale ones)
        self._reply_out = False  # ... and the FAILURE reply has been sent: one more stale STATUS, then the error
        self._reports: queue.SimpleQueue = queue.SimpleQueue()
        self._clock = time.monotonic()
        self.lock = threading.Condition()
        self.hold = threading.Event()
        self.publishing = threading.Event()
        self.publishing.set()
        self.closing = threading.Event()
        self.servers = [socket.create_server(("127.0.0.1", 0)) for _ in range(2)]
        self.motion_port, self.state_port = (s.getsockname()[1] for s in self.servers)
        self.connections: list[socket.socket] = []
        self.motion_connections: list[socket.socket] = []
        self._threads = [threading.Thread(target=self._state, daemon=True),
                         threading.Thread(target=self._motion, daemon=True)]
        for thread in self._threads:
            thread.start()

    # -- motion (under self.lock) ------------------------------------------------------------------
    def _follow(self, start, end, seconds: float) -> None:
        """The measured joints over ``seconds`` while the reference goes linearly from ``start`` to
        ``end``: the first-order lag's exact response, q' = (r - q) / lag_s."""
        if seconds <= 0:
            return
        if self.lag_s <= 0:
            self.positions = list(end)
            return
        decay = math.exp(-seconds / self.lag_s)
        out = []
        for q, a, b in zip(self.positions, start, end):
            trail = (b - a) / seconds * self.lag_s  # the ramp's steady lag
            out.append(b - trail + (q - a + trail) * decay)
        self.positions = out

    def _advance(self) -> None:
        now = time.monotonic()
        left, self._clock = now - self._clock, now
        while left > 0:
            if self._segment is None:
                if not self._queue:
                    self._follow(self._reference, self._reference, left)
                    break
                target, length = self._queue.popleft()
                self._segment = [list(self._reference), target, length, 0.0]
            start, target, length, elapsed = self._segment
            take = min(left, length - elapsed)
            elapsed += take
            left -= take
            s = 1.0 if elapsed >= length else elapsed / length
            before = self._reference
            self._reference = [a + (b - a) * s for a, b in zip(start, target)]
            self._follow(before, self._reference, take)
            self._segment[3] = elapsed
            if s >= 1.0:
                self._segment = None
        if self._segment is None and not self._queue and all(
                abs(q - r) <= self.SETTLED for q, r in zip(self.positions, self._reference)):
            self.positions = list(self._reference)  # settled
        self.lock.notify_all()

    @property
    def moving(self) -> bool:
        """The truthful in_motion: points queued, a segment running, or a joint not yet settled."""
        with self.lock:
            self._advance()
            return bool(self._queue) or self._segment is not None or self.positions != self._reference

    @property
    def reference(self) -> list[float]:
        """The interpolator's output now (what the servos are commanded)."""
        with self.lock:
            self._advance()
            return list(self._reference)

    def place(self, positions) -> None:
        """Put the joints at ``positions`` at rest (the robot moved by hand, say)."""
        with self.lock:
            self._advance()
            self.positions, self._reference = list(map(float, positions)), list(map(float, positions))

    def _halt(self) -> None:
        """Drop the queue and halt the interpolator where it is: the joints settle onto it."""
        self._queue.clear()
        self._segment = None

    def _new_trajectory(self) -> None:
        self._halt()
        self._last_time = 0.0
        self._accepting = True
        self.error_code = 0

    def _start(self, collected=None) -> list[float]:
        """Where the next point's segment starts: the last point queued (or ``collected``), else the
        running segment's target, else where the interpolator is."""
        if collected:
            return collected[-1][0]
        if self._queue:
            return self._queue[-1][0]
        return self._segment[1] if self._segment is not None else self._reference

    def _check(self, message, collected=None) -> tuple[int, list[float] | None, float]:
        """(error code or 0, target, segment length [s]) of a point of this kind."""
        n = len(self.positions)
        if (self.kind == "full") != isinstance(message, JointTrajPtFull):
            return ERROR_NOT_FULL, None, 0.0
        target = [float(q) for q in message.positions[:n]]
        if not all(lower <= q <= upper for q, (lower, upper) in zip(target, self.ranges)):
            return ERROR_RANGE, None, 0.0
        start = self._start(collected)
        if self.kind == "duration":
            if _too_fast(start, target, message.duration, self.max_velocities):
                return ERROR_TOO_FAST, None, 0.0
            return 0, target, message.duration + self.tick_s
        if self.kind == "speed":
            fraction = message.velocity
            if not 0.0 < fraction <= 1.0:
                return ERROR_BAD_SPEED, None, 0.0
            return 0, target, max((abs(b - a) / (fraction * v) for a, b, v in zip(start, target, self.max_velocities)),
                                  default=0.0)
        if not all(abs(v) <= limit for v, limit in zip(message.velocities[:n], self.max_velocities)):
            return ERROR_TOO_FAST, None, 0.0
        length = message.time - self._last_time
        self._last_time = message.time
        return 0, target, max(length, 0.0)

    def _refuse(self, code: int) -> ReplyCode:
        self.error_code, self._accepting = code, False
        self._masked = self.stale_status_after_failure
        self.halts.append((list(self.positions), list(self._reference)))
        self._halt()
        return ReplyCode.FAILURE

    def _on_point(self, message) -> ReplyCode:
        with self.lock:
            self._advance()
            if message.sequence == STOP_TRAJECTORY:
                self.stops += 1
                self.halts.append((list(self.positions), list(self._reference)))
                self._halt()
                self._accepting = False
                return ReplyCode.SUCCESS
            if message.sequence == 0:
                self._new_trajectory()
            elif not self._accepting:
                return ReplyCode.FAILURE
            while len(self._queue) >= self.capacity and not self.closing.is_set():
                self.lock.wait(0.01)  # flow control: the reply waits for room
                self._advance()
            code, target, length = self._check(message)  # taken into the queue: checked
            if code:
                return self._refuse(code)
            self._queue.append((target, length))
            return ReplyCode.SUCCESS

    def _on_download(self, message) -> None:
        """A point of a download (TOPIC): -1 begins a trajectory, -3 ends it and starts its execution."""
        with self.lock:
            self._advance()
            if message.sequence == START_TRAJECTORY_DOWNLOAD:
                self._new_trajectory()
                self._download = []
            if self._download is None or not self._accepting:
                return
            code, target, length = self._check(message, self._download)
            if code:
                self._refuse(code)
                self._download = None
                return
            self._download.append((target, length))
            if message.sequence == END_TRAJECTORY:
                self._queue.extend(self._download)
                self._download = None

    # -- sockets -----------------------------------------------------------------------------------
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
                        self._send_report(conn)
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

    def _send_report(self, conn: socket.socket) -> None:
        with self.lock:
            self._advance()
            positions = tuple(self.positions)
            moving = int(bool(self._queue) or self._segment is not None or self.positions != self._reference)
            error = 0 if self._masked or not self.error_status else self.error_code
            if self._masked and self._reply_out:
                self._masked = self._reply_out = False
        status = RobotStatus(1, 0, error, 1 if error else 0, moving, 2, 1)
        conn.sendall(encode(JointPosition(0, positions), big_endian=self.big_endian)
                     + encode(status, big_endian=self.big_endian))
        self.reports.append((time.time(), positions, moving))
        if self.step_per_report:
            with self.lock:
                self.positions[0] += self.step_per_report
                self._reference[0] = self.positions[0]

    def _motion(self) -> None:
        while (conn := self._accept(self.servers[0])) is not None:
            self.motion_connections.append(conn)
            index = len(self.motion_connections) - 1
            reader = PacketReader(big_endian=self.big_endian)
            try:
                while not self.closing.is_set():
                    data = conn.recv(4096)
                    if not data:
                        break
                    for packet in reader.feed(data):
                        message = decode(packet, big_endian=self.big_endian)
                        self.points.append(message)
                        self.received.append((index, time.monotonic(), message))
                        if packet.comm_type == CommType.TOPIC:
                            self._on_download(message)
                            continue
                        assert packet.comm_type == CommType.SERVICE_REQUEST
                        code = self._on_point(message)
                        while self.hold.is_set() and not self.closing.is_set():
                            self.closing.wait(0.005)
                        if code == ReplyCode.FAILURE and self.failure_reply_delay_s:
                            self.closing.wait(self.failure_reply_delay_s)
                        conn.sendall(encode_reply(packet, code, big_endian=self.big_endian))
                        with self.lock:
                            self._reply_out = self._masked
            except OSError:
                continue
            with self.lock:
                self._advance()
                self._halt()  # a client gone mid-motion: the robot stops

    def report(self) -> None:
        """With ``state_period_s=None``: send one JOINT_POSITION and STATUS now (from the state thread)."""
        self._reports.put(True)

    def trajectory_points(self) -> list:
        """The points received since the last sequence 0 (or -1, a download's first), STOPs left out."""
        messages = [m for m in self.points if m.sequence != STOP_TRAJECTORY]
        starts = [k for k, m in enumerate(messages) if m.sequence in (0, START_TRAJECTORY_DOWNLOAD)]
        return messages[starts[-1]:] if starts else []

    def drop_motion(self) -> None:
        """Close the motion connection only (the state goes on)."""
        for conn in self.motion_connections:
            _shut(conn)

    def drop_connections(self) -> None:
        for conn in self.connections:
            _shut(conn)
        self.connections.clear()

    def close(self) -> None:
        self.closing.set()
        self.drop_connections()
        for server in self.servers:
            server.close()
        for thread in self._threads:
            thread.join(2.0)
            assert not thread.is_alive(), "the double's thread did not end"


def _shut(conn: socket.socket) -> None:
    """Close ``conn`` with a FIN now: close() alone sends none while another thread blocks in recv on it."""
    try:
        conn.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    conn.close()


def asked_values(fault: str, joints) -> dict[str, tuple[float, float]]:
    """What jointctl's refusal ``fault`` says the refused point asked of each of ``joints``: name ->
    (position, speed [per s]), from its "NAME POSITION at SPEED/s" items."""
    found = {}
    for name in joints:
        match = re.search(rf"(?<![\w.-]){re.escape(name)} (\S+) at (\S+)/s", fault)
        assert match is not None, f"{name} is not named in {fault!r}"
        found[name] = (float(match.group(1)), float(match.group(2)))
    return found


def ros_i_fraction(velocities, max_velocities, default: float = 0.1) -> float:
    """ROS-I's ``calc_velocity`` written again from simple-message-facts.md §7, for the tests'
    expectations (independent of jointctl's implementation)."""
    if not velocities:
        return default
    ratios = [abs(v / m) if math.isfinite(m) and m > 0 else -1.0 for v, m in zip(velocities, max_velocities)]
    best = max(ratios)
    fraction = best if best > 0 else default
    return min(1.0, max(0.0, fraction))

"""A simulated industrial robot controller: the robot in MuJoCo, its own interpolator, simple_message on TCP.

``jointctl controller ROBOT`` stands where a real controller (a cabinet running the vendor's
ROS-Industrial server program) would: the ROS side (``jointctl serve ROBOT --hardware industrial``,
or ROS-Industrial's own ``robot_state`` and motion interfaces) connects to it as to the real thing.

Inside, one loop paced to the wall clock at the scenario's rate (1 kHz) runs the robot under
jointctl's joint position controllers (the robot's ``position`` controller file: effort PIDs, the
"servos"), whose references come from the controller's own motion program
(:class:`~jointctl.industrial_controller.program.ControllerProgram`, its interpolator stepped once a cycle).

Outside, two TCP servers (ROS-I's ``TcpServer``: one client at a time, re-accepting after a
disconnect, TCP_NODELAY):

- the **state port** (11002): JOINT_POSITION (the measured positions, in the controller's joint
  order: the robot's movable joints) and STATUS (``in_motion`` true while the references move or
  a joint still moves faster than ``moving_threshold``), both TOPIC, ``state_rate_hz`` times a
  second of wall-clock time;
- the **motion port** (11000): the streaming and download handshakes, STOP and PING, answered by
  the motion program. A packet stream whose framing is lost (a length prefix out of range) is
  closed; the robot then decelerates to rest, as when the client disconnects.

Nothing a client sends can raise out of the servers: a connection that fails is closed, the
servers accept the next client, and the loop runs on.
"""

from __future__ import annotations

import socket
import sys
import threading
import time
from collections.abc import Sequence

from jointctl.control.joint_controllers import JointPositionController
from jointctl.errors import ConfigError, JointCtlError
from jointctl.industrial_controller.interpolator import JointLimits
from jointctl.industrial_controller.program import ControllerProgram, MotionConnection
from jointctl.wire.simple_message import JointPosition, encode
from jointctl.scenario.session import Session
from jointctl.scenario.spec import Scenario

MOTION_PORT = 11000
STATE_PORT = 11002
#: How often blocking socket calls wake up to check for shutdown [s].
POLL_S = 0.1
#: The GIL hand-over interval while serving [s]: the loop thread gets it back soon after each sleep.
SWITCH_INTERVAL_S = 2e-4


class ControllerUnavailable(JointCtlError):
    """A port of the controller cannot be opened (in use, not permitted)."""

    code = "port"


class SimulatedController:
    """The robot of ``scenario`` behind simple_message servers (see the module docstring).

    ``scenario`` must start a :class:`JointPositionController` for every movable joint (the
    robot's ``position`` controller file does). ``host``: the address to listen on;
    ``motion_port``/``state_port``: 0 picks free ports (see :attr:`motion_port`); ``state_rate_hz``:
    state reports per second; ``queue_capacity``: streamed points the controller buffers;
    ``stop_time_s``: a joint at full speed stops within it [s]; ``speed``: loop time per wall-clock
    time; ``moving_threshold``: joint speed [rad/s or m/s] above which STATUS says in motion.
    """

    def __init__(self, scenario: Scenario, *, host: str = "0.0.0.0", motion_port: int = MOTION_PORT,
                 state_port: int = STATE_PORT, big_endian: bool = False, state_rate_hz: float = 50.0,
                 queue_capacity: int = 32, stop_time_s: float = 0.2, speed: float = 1.0,
                 moving_threshold: float = 1e-3, package_path: Sequence[str] = ()) -> None:
        if not 0 < state_rate_hz <= 1000:
            raise JointCtlError("must be in (0, 1000] reports per second", field="state_rate_hz",
                                value=state_rate_hz)
        if not speed > 0:
            raise JointCtlError("must be positive", field="speed", value=speed)
        self.session = Session(scenario, realtime=True, speed=speed, package_path=tuple(package_path))
        robot, manager, hardware = self.session.robot, self.session.manager, self.session.hardware
        #: The controller's joint order (ROS-I's controller_joint_names): the robot's movable joints.
        self.joint_names = tuple(j.name for j in robot.movable_joints)
        servos = []
        for name in self.joint_names:
            servo = manager.commanding(name)
            if not isinstance(servo, JointPositionController):
                raise ConfigError("every joint needs a started effort_controllers/JointPositionController "
                                  "(the controller's servos)", source=str(scenario.source), field="joint",
                                  value=name)
            servos.append(servo)
        self._set_references = [servo.set_reference for servo in servos]
        self._indices = [hardware.joint_index(name) for name in self.joint_names]
        hardware.read()
        start = [hardware.position[i] for i in self._indices]
        self.program = ControllerProgram(JointLimits.from_model(robot, self.joint_names, stop_time_s=stop_time_s),
                                         start, big_endian=big_endian, capacity=queue_capacity, on_event=_log)
        self.big_endian = big_endian
        self.state_period_s = 1.0 / state_rate_hz
        self.moving_threshold = moving_threshold
        self._latest = (tuple(start), False)  # (measured positions, any joint moving), swapped whole
        self._closing = threading.Event()
        self._stop_asked = threading.Event()  # set by stop(), kept: run() honours a stop asked before it began
        self._threads: list[threading.Thread] = []
        #: State reports sent and motion connections accepted so far.
        self.reports_sent = 0
        self.motion_clients = 0
        loop = self.session.loop
        loop.add_input(self._cycle)
        loop.add_observer(self._measure)
        self._servers = []
        try:
            self._motion_server = self._listen(host, motion_port, "motion")
            self._state_server = self._listen(host, state_port, "state")
        except ControllerUnavailable:
            self.close()
            raise
        self.motion_port = self._motion_server.getsockname()[1]
        self.state_port = self._state_server.getsockname()[1]

    def _listen(self, host: str, port: int, what: str) -> socket.socket:
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ControllerUnavailable("must be a TCP port, 0 to 65535 (0: any free port)", field=f"{what}_port",
                                        value=port)
        try:
            server = socket.create_server((host, port), backlog=1)
        except OSError as exc:
            raise ControllerUnavailable(f"cannot listen for the {what} connection ({exc.strerror or exc})",
                                        field=f"{what}_port", value=f"{host}:{port}") from None
        server.settimeout(POLL_S)
        self._servers.append(server)
        return server

    # -- the loop (its thread) -------------------------------------------------------------------------
    def _cycle(self, time_s: float) -> None:
        if self._closing.is_set():  # closed before or while run() started
            self.session.loop.request_stop()
        positions, velocities, accelerations = self.program.cycle(self.session.loop.period_s)
        for set_reference, q, v, a in zip(self._set_references, positions, velocities, accelerations):
            set_reference(q, v, a)

    def _measure(self, time_s: float) -> None:
        hardware, threshold = self.session.hardware, self.moving_threshold
        position, velocity = hardware.position, hardware.velocity
        self._latest = (tuple([position[i] for i in self._indices]),
                        any(abs(velocity[i]) > threshold for i in self._indices))

    def run(self, duration_s: float | None = None) -> None:
        """Serve and run the robot for ``duration_s`` of loop time (default: until :meth:`stop`)."""
        self.start()
        previous = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        loop = self.session.loop

        def honour_stop(_time_s: float) -> None:  # a stop asked before the loop began (a SIGTERM at start-up)
            if self._stop_asked.is_set():
                loop.request_stop()

        loop.add_observer(honour_stop)
        try:
            if not self._stop_asked.is_set():
                loop.run(duration_s)
        finally:
            loop.remove_observer(honour_stop)
            sys.setswitchinterval(previous)

    def start(self) -> None:
        """Start the two servers' threads (idempotent)."""
        if self._threads:
            return
        for target, name in ((self._serve_motion, "motion"), (self._serve_state, "state")):
            thread = threading.Thread(target=target, name=f"jointctl-controller-{name}", daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self) -> None:
        """Ask :meth:`run` to return after the current cycle (thread-safe; also when asked before it began)."""
        self._stop_asked.set()
        self.session.loop.request_stop()

    def close(self) -> None:
        """Stop serving: close the servers and their connections, join the threads."""
        self._closing.set()
        self.session.loop.request_stop()
        for thread in self._threads:
            thread.join(timeout=2.0)
        for server in self._servers:
            server.close()
        self.session.close()

    def __enter__(self) -> SimulatedController:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- the servers (their threads) -------------------------------------------------------------------
    def _accept(self, server: socket.socket) -> socket.socket | None:
        """The next client, or None when closing."""
        while not self._closing.is_set():
            try:
                conn, _ = server.accept()
            except TimeoutError:
                continue
            except OSError:
                if self._closing.is_set():
                    return None
                time.sleep(POLL_S)
                continue
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn.settimeout(POLL_S)
            return conn
        return None

    def _serve_motion(self) -> None:
        while (conn := self._accept(self._motion_server)) is not None:
            self.motion_clients += 1
            peer = _peer(conn)
            _log(f"motion client {peer} connected")
            why = "disconnected"
            try:
                why = self._motion_connection(conn)
            except Exception as exc:  # noqa: BLE001  (nothing a client does may stop the server)
                why = f"connection failed ({exc})"
            finally:
                conn.close()
                self.program.connection_lost()
                _log(f"motion client {peer} {why}; the robot decelerates to rest")

    def _motion_connection(self, conn: socket.socket) -> str:
        """Answer one client's packets until it disconnects, its framing is lost, or closing; why it ended."""
        alive = [True]
        connection = MotionConnection(self.program, lambda: alive[0] and not self._closing.is_set())
        while not self._closing.is_set() and not connection.closed:
            try:
                data = conn.recv(4096)
            except TimeoutError:
                continue
            if not data:
                alive[0] = False
                return "disconnected"
            for reply in connection.feed(data):
                conn.sendall(reply)
        return "sent a length prefix out of range (framing lost): closed" if connection.closed else "closed"

    def _serve_state(self) -> None:
        while (conn := self._accept(self._state_server)) is not None:
            peer = _peer(conn)
            _log(f"state client {peer} connected")
            try:
                self._state_connection(conn)
            except OSError:
                pass  # the client went away: accept the next one
            finally:
                conn.close()
                _log(f"state client {peer} gone")

    def _state_connection(self, conn: socket.socket) -> None:
        """Push JOINT_POSITION and STATUS every ``state_period_s`` of wall-clock time."""
        period, big = self.state_period_s, self.big_endian
        next_s = time.monotonic()
        sequence = 0
        while not self._closing.is_set():
            positions, moving = self._latest
            status = self.program.status(joints_moving=moving)
            conn.sendall(encode(JointPosition(sequence, positions), big_endian=big)
                         + encode(status, big_endian=big))
            sequence = (sequence + 1) & 0x7FFFFFFF
            self.reports_sent += 1
            next_s += period
            delay = next_s - time.monotonic()
            if delay > 0:
                self._closing.wait(delay)
            else:
                next_s = time.monotonic()  # fell behind: report now, and keep the rate from here


def _peer(conn: socket.socket) -> str:
    try:
        host, port = conn.getpeername()[:2]
        return f"{host}:{port}"
    except OSError:
        return "?"


def _log(line: str) -> None:
    """One line of the controller's log, on stderr."""
    print(f"jointctl controller: {line}", file=sys.stderr, flush=True)


__all__ = ["MOTION_PORT", "STATE_PORT", "ControllerUnavailable", "SimulatedController"]

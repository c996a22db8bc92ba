"""The channels of ``run.mcap``, live: a running loop streamed over Foxglove's WebSocket protocol.

:class:`FoxgloveLive` serves the channels of :mod:`jointctl.recording.foxglove_messages` with the Foxglove
SDK's WebSocket server (``jointctl tune --foxglove``, ``jointctl serve --foxglove``): open Foxglove, *Open
connection* -> *Foxglove WebSocket*, ``ws://127.0.0.1:8766``, and import the layout
:data:`~jointctl.recording.foxglove_layout.LAYOUT_FILE`.

It is a loop observer, like the ROS node's publishers: every ``1 / rate_hz`` of loop time it sends the
per-cycle channels (joint states, references, the joints by name, wrenches) of that cycle, and every
``1 / SCENE_RATE_HZ`` the robot's frames (``/tf``, from the robot's own kinematics at the measured
positions) and the spawned objects; events (spawns, removals, controller failures) as they happen. Each
client subscribing to ``/robot_description`` gets the URDF at once. Messages are stamped with the
wall-clock time at loop time zero plus loop time [ns]. Meshes that the URDF names by ``package://`` are
served to the 3D panel from the robot's packages (only those the URDF names).
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import foxglove
from foxglove.websocket import ServerListener

from jointctl.errors import JointCtlError
from jointctl.model.package_paths import PackageResolver
from jointctl.recording.foxglove_messages import (
    ERROR, EVENTS, INFO, OBJECTS, ROBOT_DESCRIPTION, SCENE_RATE_HZ, TF, RecordFormat, RobotFrames,
    decimation, description_message, log_message, object_entity, object_events, reference_kinds, scene_update)
from jointctl.recording.mcap_record import open_channels

#: The port ``--foxglove`` listens on when none is given (the tuning page has 8765, Foxglove's usual one).
DEFAULT_PORT = 8766
#: How often the per-cycle channels are sent [Hz of loop time] (at most the loop's rate).
LIVE_RATE_HZ = 250.0


def check_port(value) -> int:
    """``--foxglove``'s port: an integer 0 to 65535 (0: any free port)."""
    try:
        port = int(str(value), 10)
    except ValueError:
        port = None
    if port is None or not 0 <= port <= 65535:
        raise JointCtlError("must be a TCP port, 0 to 65535", field="--foxglove", value=value)
    return port


class FoxgloveLive:
    """A WebSocket server streaming ``loop``'s robot (``hardware``, ``manager``'s references) to Foxglove.

    ``robot`` is the RobotModel (for the frames and the units), ``urdf`` its description's text,
    ``package_path`` where its meshes' packages are. ``stop()`` ends it. The server is the Foxglove SDK's;
    it runs on its own threads, and the loop thread only formats and hands over messages.
    """

    def __init__(self, *, robot, hardware, manager, loop, urdf: str, port: int = DEFAULT_PORT,
                 host: str = "127.0.0.1", rate_hz: float = LIVE_RATE_HZ, package_path: tuple[str, ...] = (),
                 context=None) -> None:
        if not rate_hz > 0:
            raise JointCtlError("must be positive", field="rate_hz", value=rate_hz)
        self.loop = loop
        self.hardware = hardware
        self.references = manager.references
        joints = tuple(hardware.joint_names)
        self.format = RecordFormat(robot, joints, reference_kinds(manager, joints), hardware.sensor_names)
        self.frames = RobotFrames(robot, joints)
        self.urdf = urdf
        #: The SDK's context the channels log to (a test may give one with an MCAP sink of its own).
        self.context = context if context is not None else foxglove.Context()
        self.channels = open_channels(self.context, self.format)
        self._cycle_channels = [self.channels[t] for t in self.format.cycle_topics()]
        self._every = decimation(rate_hz, loop.period_s)
        self._scene_every = decimation(SCENE_RATE_HZ, loop.period_s)
        self._count = 0
        self._wrenches = tuple(hardware.wrenches[s] for s in hardware.sensor_names)
        #: The wall-clock time at loop time zero [ns], set at the first cycle streamed.
        self.origin_ns: int | None = None
        self._assets = _mesh_uris(urdf)
        self._resolver = PackageResolver(package_path)
        self.sim = hardware.simulation
        self._shown: set[str] = set()
        self._spawned = {o.name for o in self.sim.spawned} if self.sim is not None else set()
        self.server = None
        try:
            self.server = foxglove.start_server(
                name=f"jointctl {robot.name}", host=host, port=port, context=self.context,
                server_listener=_Listener(self), asset_handler=self._asset)
        except (RuntimeError, OverflowError, OSError) as exc:
            self._close_channels()
            raise JointCtlError(f"cannot listen for Foxglove on {host}:{port} ({exc})", field="--foxglove",
                                value=port) from None
        if self.sim is not None:
            self.sim.on_rebuild(self._on_rebuild)
        manager.add_failure_listener(
            lambda f: self._event(f.time_s, f"controller {f.controller} {f.error().message}", ERROR))
        loop.add_observer(self)

    @property
    def port(self) -> int:
        """The port the server listens on."""
        return self.server.port

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}"

    def _stamp(self, time_s: float) -> int:
        if self.origin_ns is None:
            self.origin_ns = time.time_ns() - round(time_s * 1e9)
        return self.origin_ns + round(time_s * 1e9)

    # -- the loop's side ------------------------------------------------------------------------------
    def __call__(self, time_s: float) -> None:
        count = self._count
        self._count = count + 1
        if count % self._every and count % self._scene_every:
            return
        ns = self._stamp(time_s)
        hw = self.hardware
        positions = hw.position
        if count % self._every == 0:
            row = [time_s, *self.references, *positions, *hw.velocity, *hw.effort]
            for wrench in self._wrenches:
                row += wrench
            for channel, message in zip(self._cycle_channels, self.format.row_messages(row, ns)):
                channel.log(message, log_time=ns)
        if count % self._scene_every == 0:
            self.channels[TF].log(self.frames.messages([ns], [list(positions)])[0], log_time=ns)
            self._objects(ns)

    def _objects(self, ns: int) -> None:
        if self.sim is None:
            return
        spawned = self.sim.spawned
        if not spawned and not self._shown:
            return
        state = self.sim.body_state
        entities = [object_entity(spec, *state(spec.name)[:2], ns) for spec in spawned]
        names = {spec.name for spec in spawned}
        self.channels[OBJECTS].log(scene_update(entities, sorted(self._shown - names), ns), log_time=ns)
        self._shown = names

    def _on_rebuild(self) -> None:
        now = {o.name for o in self.sim.spawned}
        for text in object_events(self._spawned, now):
            self._event(self.loop.time_s, text)
        self._spawned = now

    def _event(self, time_s: float, text: str, level: int = INFO) -> None:
        ns = self._stamp(time_s)
        self.channels[EVENTS].log(log_message(text, ns, level), log_time=ns)

    # -- the server's side ----------------------------------------------------------------------------
    def send_description(self) -> None:
        """Send the URDF on ``/robot_description`` (to every subscriber)."""
        ns = self._stamp(self.loop.time_s)
        self.channels[ROBOT_DESCRIPTION].log(description_message(self.urdf), log_time=ns)

    def _asset(self, uri: str) -> bytes | None:
        """A mesh the URDF names, for the 3D panel; None for anything else."""
        if uri not in self._assets:
            return None
        try:
            return Path(self._resolver.resolve_uri(uri)).read_bytes()
        except (JointCtlError, OSError):
            return None

    def stop(self) -> None:
        """Stop streaming and close the server."""
        self.loop.remove_observer(self)
        if self.server is not None:
            self.server.stop()
            self.server = None
        self._close_channels()

    def _close_channels(self) -> None:
        for channel in self.channels.values():
            channel.close()


class _Listener(ServerListener):
    """The server's callbacks: a new subscriber to ``/robot_description`` gets the URDF."""

    def __init__(self, live: FoxgloveLive) -> None:
        self.live = live

    def on_subscribe(self, client, channel) -> None:
        if channel.topic == ROBOT_DESCRIPTION:
            self.live.send_description()


def _mesh_uris(urdf: str) -> set[str]:
    """The mesh files a URDF names (``<mesh filename="..."``)."""
    return set(re.findall(r'<mesh\b[^>]*\bfilename\s*=\s*"([^"]+)"', urdf))


def live_for_session(session, *, port: int, host: str = "127.0.0.1", package_path: tuple[str, ...] = ()):
    """A :class:`FoxgloveLive` of a Session's robot and loop."""
    from jointctl.model.loader import description_text

    return FoxgloveLive(robot=session.robot, hardware=session.hardware, manager=session.manager, loop=session.loop,
                        urdf=description_text(session.robot, package_path), port=port, host=host,
                        package_path=package_path)


__all__ = ["DEFAULT_PORT", "LIVE_RATE_HZ", "FoxgloveLive", "check_port", "live_for_session"]

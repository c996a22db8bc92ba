"""``run.mcap``: a run's record for Foxglove and PlotJuggler, written beside ``trace.csv``.

:class:`McapRecorder` writes the channels of :mod:`jointctl.recording.foxglove_messages` (joint states,
references, the joints by name with units, wrenches, the robot description, TF, the spawned objects and
the run's events) into an MCAP file with the Foxglove SDK's writer (zstd-compressed chunks, indexed). The
JSON channels have JSON schemas; ``/joint_states`` is ROS 2's ``sensor_msgs/msg/JointState`` in CDR with its
``ros2msg`` schema, a raw channel of the SDK. The header names no profile: ROS 2's (``ros2``) would say that
every channel is CDR.

It costs the loop almost nothing: the per-cycle messages are made after the run, from the rows
:class:`~jointctl.recording.trace.TraceRecorder` formats into ``trace.csv`` (the same rows and the very
numbers trace.csv prints, in one pass over its spool), and TF from the recorded joint positions through the
robot's own kinematics. During the run it only keeps what the trace has not: the spawned objects' poses (at most
:data:`~jointctl.recording.foxglove_messages.SCENE_RATE_HZ`, only while objects exist) and the events
(spawns and removals, controller failures; the session adds its trajectory goals before closing).
Messages are written in time order, stamped with loop time from zero [ns].
"""

from __future__ import annotations

import bisect
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import foxglove
import numpy as np
from foxglove.mcap import MCAPWriteOptions

from jointctl import __version__
from jointctl.recording.foxglove_messages import (
    ERROR, EVENTS, INFO, OBJECTS, WARNING, ROBOT_DESCRIPTION, SCENE_RATE_HZ, TF, ChannelSpec, RecordFormat,
    RobotFrames, decimation, description_message, log_message, nanoseconds, object_entity, object_events,
    reference_kinds, scene_update)

MCAP_FILE = "run.mcap"


def open_channels(context, record: RecordFormat) -> dict[str, Any]:
    """One channel per topic of ``record`` on ``context`` (a ``foxglove.Context``)."""
    return {spec.topic: _channel(context, spec) for spec in record.channels()}


def _channel(context, spec: ChannelSpec):
    """A JSON channel with its JSON schema, or a channel of ``spec.message_encoding`` with a schema given as text
    (ROS 2's joint states: CDR, ros2msg)."""
    if isinstance(spec.schema, dict):
        return foxglove.Channel(spec.topic, schema=spec.schema, context=context, metadata=spec.metadata)
    schema = foxglove.Schema(name=spec.schema.name, encoding=spec.schema.encoding, data=spec.schema.text.encode())
    return foxglove.Channel(spec.topic, schema=schema, message_encoding=spec.message_encoding, context=context,
                            metadata=spec.metadata)


def _log_of(channel):
    """``channel``'s log(message bytes, log time [ns]): the SDK channel's own, without the checks of the
    Python wrapper (a message a row per channel: a microsecond each)."""
    base = getattr(channel, "base", None)
    return base.log if base is not None else (lambda message, ns: channel.log(message, log_time=ns))


class ObjectTrack:
    """A loop observer keeping the spawned objects' poses every ``every`` cycles while there are any:
    (loop time [s], ((spec, position [m], quaternion w x y z), ...)) per sample. The poses are the
    simulation door's, as the simulator last computed them (at the start of the physics step before the
    cycle: up to one step behind the cycle's time)."""

    def __init__(self, simulation, every: int) -> None:
        self.simulation = simulation
        self.every = max(1, every)
        self.samples: list[tuple[float, tuple]] = []
        self._countdown = 0
        self._shown = False

    def __call__(self, time_s: float) -> None:
        if self._countdown:
            self._countdown -= 1
            return
        self._countdown = self.every - 1
        spawned = self.simulation.spawned
        if not spawned and not self._shown:
            return
        state = self.simulation.body_state
        self.samples.append((time_s, tuple((spec, *state(spec.name)[:2]) for spec in spawned)))
        self._shown = bool(spawned)


class McapRecorder:
    """Writes ``path`` (``run.mcap``) for a run of ``robot`` on ``hardware`` under ``manager``'s controllers.

    Give it the trace's rows with :meth:`add_rows` (a :class:`~jointctl.recording.trace.TraceRecorder`
    chunk reader), then :meth:`close`. ``every`` is the trace's decimation (one cycle in ``every``);
    ``urdf`` the robot description's text; ``metadata`` strings kept in the file's ``jointctl`` metadata.
    """

    def __init__(self, path: str | Path, *, robot, hardware, manager, loop, urdf: str, every: int = 1,
                 metadata: dict[str, str] | None = None) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        joints = tuple(hardware.joint_names)
        self.format = RecordFormat(robot, joints, reference_kinds(manager, joints), hardware.sensor_names)
        self.frames = RobotFrames(robot, joints)
        self._context = foxglove.Context()
        self._writer = foxglove.open_mcap(self.path, allow_overwrite=True, context=self._context,
                                          writer_options=MCAPWriteOptions(compression_threads=0))
        self.channels = open_channels(self._context, self.format)
        self._cycle_logs = [_log_of(self.channels[t]) for t in self.format.cycle_topics()]
        period = loop.period_s * every
        #: Rows between two TF messages (TF at most SCENE_RATE_HZ).
        self.scene_every = decimation(SCENE_RATE_HZ, period)
        self.rows = 0
        self.closed = False
        self._events: list[tuple[int, int, str]] = []  # (stamp [ns], level, text)
        self._loop = loop
        self._positions = slice(1 + len(joints), 1 + 2 * len(joints))
        self._pending: list[tuple[int, int, Any]] = []  # what is not per cycle, merged in time order
        self._shown_objects: set[str] = set()
        self.objects: ObjectTrack | None = None
        sim = hardware.simulation
        if sim is not None:
            self.objects = ObjectTrack(sim, decimation(SCENE_RATE_HZ, loop.period_s))
            loop.add_observer(self.objects)
            self._spawned = {o.name for o in sim.spawned}
            sim.on_rebuild(lambda: self._on_rebuild(sim))
        manager.add_failure_listener(
            lambda f: self.add_event(f.time_s, f"controller {f.controller} {f.error().message}", ERROR))
        self.channels[ROBOT_DESCRIPTION].log(description_message(urdf), log_time=0)
        self._writer.write_metadata("jointctl", {"jointctl_version": __version__, "robot": robot.name,
                                                 "joints": json.dumps(list(joints)), "time": "loop time from 0",
                                                 "loop_period_s": repr(loop.period_s), "record_every": str(every),
                                                 **(metadata or {})})
        self._writer.attach(log_time=0, create_time=0, name="robot.urdf", media_type="application/xml",
                            data=urdf.encode())

    # -- during the run -------------------------------------------------------------------------------
    def _on_rebuild(self, sim) -> None:
        now = {o.name for o in sim.spawned}
        for text in object_events(self._spawned, now):
            self.add_event(self._loop.time_s, text)
        self._spawned = now

    def add_event(self, time_s: float, text: str, level: int = INFO) -> None:
        """An event at loop time ``time_s`` [s] on ``/jointctl/events`` (before :meth:`add_rows` passes it)."""
        self._events.append((nanoseconds(time_s), level, text))

    def add_goal_events(self, goals: Iterable, controller: str | None = None) -> None:
        """Each trajectory goal's start and end (GoalHandles of ``controller``), a rejected one's refusal,
        as events ("<controller>: goal 2 rejected: ..."; a warning unless it succeeded)."""
        prefix = f"{controller}: " if controller else ""
        for goal in goals:
            validated = goal.validated
            if validated is not None:
                self.add_event(validated.start_time_s, f"{prefix}goal {goal.id} starts ({len(validated.times_s)} "
                                                       f"points, {validated.duration_s:.3f} s)")
            result = goal.result
            if result is not None:
                level = INFO if result.status.value == "succeeded" else WARNING
                detail = f": {result.error_string}" if result.error_string else ""
                self.add_event(result.time_s, f"{prefix}goal {goal.id} {result.status.value}{detail}", level)

    # -- after the run --------------------------------------------------------------------------------
    def _merge_pending(self) -> None:
        """The events and object samples, as messages to merge into the rows, in time order."""
        pending: list[tuple[int, int, Any]] = [(ns, 0, (EVENTS, log_message(text, ns, level)))
                                               for ns, level, text in sorted(self._events)]
        if self.objects is not None:
            pending += [(nanoseconds(t), 1, (OBJECTS, objects)) for t, objects in self.objects.samples]
            self.objects.samples = []
        pending.sort(key=lambda item: (item[0], item[1]))
        self._pending = pending
        self._events = []

    def add_rows(self, rows: np.ndarray, lines: list[str] | None = None) -> None:
        """Write the per-cycle messages of trace rows (rows x columns, trace.csv's order; ``lines``: the
        same rows as trace.csv's text, whose numbers are then used as written), TF every
        :attr:`scene_every` rows, and the events and object poses up to the last row's time."""
        if self.rows == 0 and not self._pending:
            self._merge_pending()
        rows = np.asarray(rows, dtype=float)
        first = self.rows
        self.rows += len(rows)
        cycle = self.format.cycle_messages(rows, lines)
        tf_rows = np.arange((-first) % self.scene_every, len(rows), self.scene_every)
        tf = dict(zip(tf_rows.tolist(), self.frames.messages([cycle[k][0] for k in tf_rows],
                                                               rows[tf_rows, self._positions])))
        logs, tf_log = self._cycle_logs, _log_of(self.channels[TF])
        pending = self._pending
        stamps = [item[0] for item in pending]
        start = 0
        for k, (ns, messages) in enumerate(cycle):
            stop = bisect.bisect_right(stamps, ns, lo=start)
            if stop > start:
                self._write_pending(pending[start:stop])
                start = stop
            for log, message in zip(logs, messages):
                log(message, ns)
            message = tf.get(k)
            if message is not None:
                tf_log(message, ns)
        del pending[:start]

    def _write_pending(self, items) -> None:
        for ns, _, (topic, payload) in items:
            if topic == OBJECTS:
                entities = [object_entity(spec, position, quat, ns) for spec, position, quat in payload]
                names = {spec.name for spec, _, _ in payload}
                self.channels[OBJECTS].log(scene_update(entities, sorted(self._shown_objects - names), ns),
                                           log_time=ns)
                self._shown_objects = names
            else:
                self.channels[topic].log(payload, log_time=ns)

    def close(self) -> None:
        """Write what is left (events after the last row) and finish the file."""
        if self.closed:
            return
        if self.rows == 0:
            self._merge_pending()
        self._write_pending(self._pending)
        late = sorted(self._events)  # added after the rows were written
        self._write_pending([(ns, 0, (EVENTS, log_message(text, ns, level))) for ns, level, text in late])
        self._pending, self._events = [], []
        self._writer.close()
        for channel in self.channels.values():
            channel.close()
        self.closed = True


__all__ = ["MCAP_FILE", "McapRecorder", "ObjectTrack", "open_channels"]

"""A running session as the tuning page sees it: checked requests in, snapshots out.

:class:`Tuner` builds the scenario's :class:`~jointctl.scenario.session.Session` and adds two
things to its loop: a door (an input run at the start of every cycle that applies the changes
queued since the last cycle and feeds each command source to its controller) and a
:class:`~jointctl.tuning.live_buffer.LiveBuffer` (an observer). Requests arrive on another thread
through :meth:`Tuner.handle`: each is checked there, completely, before anything is queued, so a
refused request changes nothing; an accepted one is applied by the loop thread at the next
cycle. Pausing and resetting stop the loop between cycles; :mod:`jointctl.tuning.runner` runs it.

Command sources start when they are applied: a step's ``at``, a sine's phase and an expression's
``i`` and ``t`` count from that cycle.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

from jointctl.control.joint_controllers import JointPositionController, JointVelocityController
from jointctl.errors import ConfigError
from jointctl.scenario.session import Session, object_spawner
from jointctl.scenario.spec import Scenario
from jointctl.sim.objects import ObjectSpec, object_from_config
from jointctl.commands.limits import check_within_limits
from jointctl.commands.sources import CommandSource, command_source_from_config
from jointctl.visuals.video import robot_camera
from jointctl.tuning.gains import GainGroup, gain_groups, gains_yaml
from jointctl.tuning.live_buffer import LiveBuffer
from jointctl.tuning.measurements import SourceRun, measure
from jointctl.tuning.requests import Control, RequestError, SelectJoint, SetGain, SetGravity, SetSource
from jointctl.tuning.scene_view import SceneTap

DEFAULT_WINDOW_S = 60.0  # loop time kept for plots and measurements [s]
#: Late cycles (finished after their deadline) count as too many above this share of the cycles, over
#: the whole run or over the last LATE_RECENT_S of wall-clock time (the page highlights them then).
LATE_SHARE_LIMIT = 0.01
LATE_RECENT_S = 5.0


@dataclasses.dataclass
class _Feed:
    """A command source feeding a controller since loop time ``started_s``."""

    controller: Any
    source: CommandSource
    started_s: float


class Tuner:
    """The session, its doors and what the page reads."""

    def __init__(self, scenario: Scenario, *, out_dir: str | Path = "out/tune", window_s: float = DEFAULT_WINDOW_S,
                 package_path: tuple[str, ...] = ()) -> None:
        # The tuner feeds the scenario's commands and spawns its objects itself: both start
        # over on reset, which the session's one-shot inputs cannot.
        self.session = Session(dataclasses.replace(scenario, commands={}, objects=()), package_path=package_path)
        self.scenario = scenario
        self.out_dir = Path(out_dir)
        session = self.session
        self.loop, self.hardware, self.manager = session.loop, session.hardware, session.manager
        #: The hardware's simulation door: gravity, the drop weight and scenario objects need it.
        self.sim = session.hardware.simulation
        self.period_s = self.loop.period_s
        self.groups: dict[str, GainGroup] = {g.name: g for g in gain_groups(self.manager, session.robot)}
        self.commandable = {c.name: c for c in self.manager.active
                            if isinstance(c, (JointPositionController, JointVelocityController))
                            and self.manager.command_owner(c.name) is None}
        self.buffer = LiveBuffer(self.hardware, self.manager.references, capacity=round(window_s / self.period_s))
        tuning = scenario.robot.extras.get("tune") or {}
        self.drop_object: ObjectSpec | None = None
        if tuning.get("drop") is not None:
            self.drop_object = object_from_config(tuning["drop"], field="tune.drop",
                                                  source=str(scenario.robot.folder / "robot.yaml"),
                                                  floor=scenario.floor)
        for k, obj in enumerate((*scenario.objects, *([self.drop_object] if self.drop_object else []))):
            if self.sim is not None and self.sim.has_body(obj.name):
                raise ConfigError("a link of the robot already has that name", source=scenario.source,
                                  field=f"objects[{k}].name", value=obj.name)
        self.default_joint = self._default_joint(tuning.get("joint"), str(scenario.robot.folder / "robot.yaml"))
        self._pending: deque[Callable[[float], None]] = deque()
        self._feeds: dict[str, _Feed] = {}
        self.runs: dict[str, SourceRun] = {}
        self.scenario_sources: set[str] = set()  # controllers fed by the scenario's own source now
        self._measured: dict[tuple, dict[str, Any]] = {}  # final measurements, by (epoch, controller, start)
        #: (late cycles, cycles) of the runner's earlier pacing clocks, and the last of them.
        self._timing_closed: tuple[int, int, Any] = (0, 0, None)
        self.last_commanded: str | None = None
        self._spawn_objects = self._objects_spawner()  # replaced on reset: they come again
        self.weight_dropped = False
        self.paused = False
        self.reset_wanted = False
        self.shutdown = False
        self.epoch = 0
        self.loop.add_input(self._cycle_start)
        self.loop.add_observer(self.buffer)
        #: The 3D view's source: the world's visible shapes and poses (None on real hardware).
        self.scene: SceneTap | None = None
        if session.world is not None:
            camera = robot_camera(scenario.robot.extras, source=str(scenario.robot.folder / "robot.yaml"))
            self.scene = SceneTap(session.world, camera=dataclasses.asdict(camera))
            self.loop.add_observer(self.scene)
        for name, config in scenario.commands.items():
            source = command_source_from_config(config, field=f"commands.{name}", source=scenario.source)
            self._set_source(SetSource(name, source, dict(config)), origin="scenario")
        self.apply_pending()

    # -- what the page is told when it connects ------------------------------------------------
    def _default_joint(self, joint: Any, source: str) -> str:
        names = self.hardware.joint_names
        if joint is not None:
            if joint not in names:
                raise ConfigError(f"no such joint (joints: {', '.join(names)})", source=source, field="tune.joint",
                                  value=joint)
            return joint
        commanded = [c.joint for c in self.commandable.values()]
        return commanded[0] if commanded else names[0]

    def describe(self) -> dict[str, Any]:
        robot = self.session.robot
        return {
            "robot": robot.name,
            "scenario": self.scenario.name,
            "period_s": self.period_s,
            "window_s": self.buffer.capacity * self.period_s,
            "joints": [{"name": j, "prismatic": robot.joint(j).is_prismatic} for j in self.hardware.joint_names],
            "joint": self.default_joint,
            "sensors": list(self.hardware.sensor_names),
            "controllers": [{"name": c.name, "joint": c.joint, "quantity": c.controlled,
                             "reference": self._reference_now(c)} for c in self.commandable.values()],
            "gains": [g.describe() for g in self.groups.values()],
            "can_drop": self.drop_object is not None,
            "gravity_z_m_s2": self._gravity_z(),
            "controller_file": str(self.scenario.controller_file),
            "sources": self._sources(),
            "late_share_limit": LATE_SHARE_LIMIT,
            "late_recent_s": LATE_RECENT_S,
        }

    def _sources(self) -> dict[str, dict[str, Any]]:
        """The source feeding each commanded controller: its description and ``origin`` ("scenario":
        the scenario's own commands, "page": applied from the page)."""
        return {name: {**run.description, "origin": "scenario" if name in self.scenario_sources else "page"}
                for name, run in self.runs.items()}

    def timing(self) -> tuple[int, int]:
        """(late cycles, paced cycles) since the page started: a cycle is late when it finished after
        its deadline on the wall clock (the pacer then does not wait). Simulated loops count none."""
        late, cycles, closed = self._timing_closed
        clock = self.loop.clock
        if clock is closed:  # between two runs
            return late, cycles
        return late + getattr(clock, "overruns", 0), cycles + getattr(clock, "cycles", 0)

    def close_timing(self, clock) -> None:
        """Add a pacing clock the loop no longer runs on to :meth:`timing` (the runner, after each run)."""
        late, cycles, _ = self._timing_closed
        self._timing_closed = (late + clock.overruns, cycles + getattr(clock, "cycles", 0), clock)

    def _reference_now(self, controller) -> float:
        given = controller.reference_input
        return float(given[0] if isinstance(given, tuple) else given)

    def status(self) -> dict[str, Any]:
        status = {"time_s": self.loop.time_s, "paused": self.paused, "epoch": self.epoch,
                  "gravity_z_m_s2": self._gravity_z(), "weight_dropped": self.weight_dropped,
                  "sources": {name: run.description for name, run in self.runs.items()},
                  "source_origins": {name: s["origin"] for name, s in self._sources().items()}}
        status["late_cycles"], status["cycles"] = self.timing()
        status["overruns"] = status["late_cycles"]  # the earlier name
        failures = self.manager.failures
        if failures:  # a controller failed: the page says which and what was done
            status["error"] = f"controller {failures[-1].controller!r} {failures[-1].error().message}"
        return status

    def measurement(self) -> dict[str, Any]:
        """Measurements of the most recently applied source."""
        name = self.last_commanded
        run = self.runs.get(name) if name else None
        key = (self.epoch, name, run.started_s if run else None)
        if key in self._measured:  # final: the record may since have left the buffer
            return dict(self._measured[key])
        result = measure(self.buffer, run, self.loop.time_s, self.period_s)
        result["controller"] = name
        result["epoch"] = self.epoch
        if run is not None:
            result["source"] = self._sources().get(name)
        if result.get("complete") and result.get("values"):
            self._measured = {key: dict(result)}
        return result

    def joint_index(self, joint: Any) -> int:
        names = self.hardware.joint_names
        if not isinstance(joint, str) or joint not in names:
            raise RequestError(f"no such joint (joints: {', '.join(names)})", field="joint", value=joint)
        return names.index(joint)

    # -- requests (another thread) -----------------------------------------------------------------
    def handle(self, request) -> dict[str, Any]:
        """Check ``request`` and queue its change for the next cycle; a reply for the page.
        Raises :class:`~jointctl.errors.JointCtlError` (nothing queued) when it is refused."""
        if isinstance(request, SetGain):
            group = self.groups.get(request.controller)
            if group is None:
                raise RequestError(f"no controller with gains of that name (tunable: {', '.join(self.groups)})",
                                   field="controller", value=request.controller)
            change = group.prepare(request.name, request.value)
            self._pending.append(lambda t: change())
            return {"type": "ok", "request": "gain", "controller": request.controller, "name": request.name,
                    "value": float(request.value)}
        if isinstance(request, SetSource):
            self._set_source(request)
            return {"type": "ok", "request": "source", "controller": request.controller,
                    "source": request.description}
        if isinstance(request, SelectJoint):
            self.joint_index(request.joint)
            return {"type": "ok", "request": "joint", "joint": request.joint}
        if isinstance(request, SetGravity):
            self._require_simulation("changing gravity", "gravity")
            gravity = (0.0, 0.0, request.z_m_s2)
            self._pending.append(lambda t: self._set_gravity(gravity))
            return {"type": "ok", "request": "gravity", "value": request.z_m_s2}
        if isinstance(request, Control):
            return self._control(request.action)
        raise RequestError("not a request", field="type", value=type(request).__name__)

    def _set_source(self, request: SetSource, origin: str = "page") -> None:
        controller = self.commandable.get(request.controller)
        if controller is None:
            raise RequestError(f"no controller takes commands by that name (commandable: "
                               f"{', '.join(self.commandable) or 'none'})", field="controller",
                               value=request.controller)
        name = request.controller
        if request.source is not None:  # a value the controller would clamp is refused, as a scenario's is
            page = origin == "page"
            check_within_limits(request.source, controller, self.session.robot,
                                field="source" if page else f"commands.{name}",
                                source_file=None if page else self.scenario.source)

        def apply(t: float) -> None:
            if request.source is None:
                self._feeds.pop(name, None)
            else:
                request.source.reset()
                self._feeds[name] = _Feed(controller, request.source, t)
            self.runs[name] = SourceRun(controller.joint, controller.controlled, request.description, t)
            if origin == "scenario":
                self.scenario_sources.add(name)
            else:
                self.scenario_sources.discard(name)
            self.last_commanded = name

        self._pending.append(apply)

    def _set_gravity(self, gravity: tuple[float, float, float]) -> None:
        self.sim.set_gravity(gravity)
        self.manager.context.set_gravity(gravity)

    def _gravity_z(self) -> float | None:
        """Gravity along z [m/s²] where the hardware is simulated; None on a real robot."""
        return self.sim.gravity_m_s2[2] if self.sim is not None else None

    def _require_simulation(self, what: str, field: str) -> None:
        if self.sim is None:
            raise RequestError(f"{what} needs a simulated robot; this hardware "
                               f"({type(self.hardware).__name__}) is real", field=field, value=what)

    def _objects_spawner(self):
        if self.sim is None or not self.scenario.objects:
            return lambda time_s: None
        return object_spawner(self.sim, self.scenario.objects)

    def _control(self, action: str) -> dict[str, Any]:
        if action == "pause":
            self.paused = True
        elif action == "resume":
            self.paused = False
        elif action == "reset":
            self.reset_wanted = True
        elif action == "drop_weight":
            obj = self.drop_object
            if obj is None:
                raise RequestError("this robot has no weight to drop (robot.yaml: tune.drop)", field="drop_weight",
                                   value=self.session.robot.name)
            if self.weight_dropped:
                raise RequestError("the weight is already in the world: reset first", field="drop_weight",
                                   value=obj.name)
            self._require_simulation("dropping a weight", "drop_weight")
            self.weight_dropped = True
            self._pending.append(lambda t: self.sim.spawn(obj))
        elif action == "save_gains":
            return self.save_gains()
        return {"type": "ok", "request": action}

    def save_gains(self) -> dict[str, Any]:
        """Write the running gains into a copy of the controller YAML file, in the chapter's format."""
        source = self.scenario.controller_file
        header = (f"# {source.name} with the gains tuned by jointctl tune ({self.session.robot.name}, "
                  f"{time.strftime('%Y-%m-%d %H:%M:%S')})\n")
        text = gains_yaml(source, list(self.groups.values()), header)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        path = self.out_dir / source.name
        path.write_text(text)
        return {"type": "saved", "path": str(path.resolve()), "yaml": text}

    # -- the loop side --------------------------------------------------------------------------------
    def _cycle_start(self, time_s: float) -> None:
        pending = self._pending
        while pending:
            pending.popleft()(time_s)
        self._spawn_objects(time_s)
        for feed in self._feeds.values():
            feed.controller.set_reference(feed.source.sample(time_s - feed.started_s))
        if self.paused or self.reset_wanted or self.shutdown:
            self.loop.request_stop()

    def at_next_cycle(self, change: Callable[[float], None]) -> None:
        """Run ``change(loop_time_s)`` in the loop thread at the start of the next cycle (or at once
        when paused, by :meth:`apply_pending`)."""
        self._pending.append(change)

    def apply_pending(self) -> None:
        """Apply queued changes while the loop is not running (paused)."""
        pending, t = self._pending, self.loop.time_s
        while pending:
            pending.popleft()(t)

    def reset(self) -> None:
        """Back to the initial state, the loop stopped: physics, controllers, loop time 0, spawned
        objects removed, every source restarted. Gains and gravity stay as set."""
        self.apply_pending()
        if self.sim is not None:
            self.sim.remove_spawned()
        self.hardware.reset()
        names = [c.name for c in self.manager.active]
        self.manager.stop(names)
        self.manager.start(names)
        self.loop.cycle = 0
        self.buffer.clear()
        self._spawn_objects = self._objects_spawner()
        self.weight_dropped = False
        for name, feed in self._feeds.items():
            feed.source.reset()
            feed.started_s = 0.0
        self.runs = {name: dataclasses.replace(run, started_s=0.0) for name, run in self.runs.items()}
        self.epoch += 1
        self.reset_wanted = False

    def close(self) -> None:
        self.session.close()


def stream_columns(buffer: LiveBuffer, joint: str) -> list[tuple[str, int]]:
    """The series the page plots for ``joint``: (name, buffer column) pairs."""
    columns = [(q, buffer.column(f"{joint}.{q}")) for q in ("reference", "position", "velocity", "effort")]
    columns += [(f"force:{s}", buffer.column(f"{s}.force_z")) for s in buffer.sensor_names]
    return columns

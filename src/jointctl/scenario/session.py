"""Assemble a scenario into a running stack: model -> world -> hardware -> controllers -> loop.

The hardware is a MuJoCo simulation of the scenario's robot, unless another hardware (a real
robot's, e.g. :class:`~jointctl.hardware.industrial.IndustrialHardware`) is given.

The simulated robot may differ from the robot its controllers know, as a real robot differs from its model:
the scenario's ``payload_kg`` and ``model.*`` make the robot simulated (:func:`simulated_robot`: a heavier
link, more damping), while the controllers and their feed-forward keep the nominal model; its
``latency_cycles`` and ``noise`` put the simulated hardware behind
:class:`~jointctl.hardware.imperfect.ImperfectHardware` (commands that arrive late, noisy sensors) before the
controllers are given its handles. Given hardware has its own: these settings are refused with it.

A session is built whole for each run, or (a sweep's many runs) from a robot model and a world kept from an
earlier run of the same robot (:func:`world_key` says which runs share a world): the world restarts as a new one
starts (:meth:`~jointctl.sim.world.MujocoWorld.restart`), every other part (hardware, controllers, sources,
loop, recorder) is built anew.

A :class:`Session` owns every part of one run and wires the edges to the loop:
each command source feeds its controller at the start of a cycle, and the
recorder, when an output folder is given, observes the end of each cycle (and, with ``mcap``, the
``run.mcap`` recorder keeps what the trace does not).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from jointctl.control.manager import ControllerManager, read_yaml
from jointctl.errors import ConfigError
from jointctl.hardware.imperfect import ImperfectHardware
from jointctl.hardware.mujoco_hardware import MujocoHardware
from jointctl.metrics.step_loop import holding_effort
from jointctl.model.dynamics import RobotDynamics
from jointctl.model.loader import description_text, load_robot_model
from jointctl.model.robot_model import RobotModel
from jointctl.runtime.clock import SimulatedClock, WallClockPacer
from jointctl.runtime.goal_sender import GoalSender
from jointctl.runtime.loop import ControlLoop
from jointctl.runtime.spawner import ObjectSpawner
from jointctl.scenario.plant import payload_link, varied_plant
from jointctl.scenario.spec import Scenario
from jointctl.sim.mjcf_builder import WorldSettings
from jointctl.hardware.interface import HardwareInterface, SimulationDoor
from jointctl.sim.world import MujocoWorld
from jointctl.commands.limits import check_within_limits
from jointctl.commands.sources import CommandSource, SourceFeed, command_source_from_config
from jointctl.recording.mcap_record import MCAP_FILE, McapRecorder
from jointctl.recording.trace import Trace, TraceRecorder
from jointctl.commands.sine_trajectory import coarse_sine
from jointctl.trajectory.errors import InvalidTrajectory
from jointctl.trajectory.executor import TrajectoryExecutor
from jointctl.trajectory.messages import JointTrajectory

TRACE_FILE = "trace.csv"


def simulated_robot(robot: RobotModel, scenario: Scenario) -> RobotModel:
    """The robot ``scenario`` simulates: ``robot`` with its ``model.*`` changes and its payload at the payload link
    (robot.yaml's ``payload_link``, else the last link); ``robot`` itself when it changes nothing. ConfigError
    naming the scenario and the field when the robot has no such link or joint."""
    if not scenario.changes_robot:
        return robot
    manifest = str(scenario.robot.manifest) if scenario.robot.manifest else None
    link = payload_link(robot, scenario.robot.extras, manifest) if scenario.payload_kg else None
    return varied_plant(robot, scenario.model_changes, scenario.payload_kg, link, scenario.source)


def world_key(scenario: Scenario) -> tuple:
    """What the simulated world of ``scenario`` is built from, as a key: two scenarios with the same key simulate
    the same compiled model (the robot's files, its ``model.*`` changes and payload, the physics step, gravity,
    the floor); everything else a scenario sets (controllers, gains, commands, initial pose, durations, latency,
    noise, objects spawned as it runs) is set on a world restarted as new."""
    robot = scenario.robot
    return (str(robot.description), str(robot.manifest or ""), tuple(sorted(scenario.model_changes.items())),
            float(scenario.payload_kg or 0.0), float(scenario.timestep_s),
            tuple(float(g) for g in scenario.gravity_m_s2), bool(scenario.floor))


def simulated_world(robot: RobotModel, scenario: Scenario) -> MujocoWorld:
    """The simulated world of ``scenario`` (its :func:`simulated_robot` under its settings), built at its initial
    positions."""
    settings = WorldSettings(scenario.timestep_s, scenario.gravity_m_s2, scenario.floor)
    return MujocoWorld(simulated_robot(robot, scenario), settings, initial_positions=scenario.initial_positions,
                       source=scenario.source)


class Session:
    """Everything one scenario run needs, built and validated before anything moves.

    ``robot`` and ``world`` (a sweep's, kept from an earlier run): the robot's model as loaded from the scenario's
    description, and a world :func:`simulated_world` built of it for a scenario of the same :func:`world_key`;
    the session restarts the world at this scenario's initial positions and owns it for the run. Without an
    ``out_dir``, ``keep_trace`` records the trace in memory (:meth:`trace`) instead of to a file.
    """

    def __init__(
        self,
        scenario: Scenario,
        *,
        out_dir: str | Path | None = None,
        realtime: bool = False,
        speed: float = 1.0,
        package_path: tuple[str, ...] = (),
        hardware: HardwareInterface | None = None,
        mcap: bool = False,
        robot: RobotModel | None = None,
        world: MujocoWorld | None = None,
        keep_trace: bool = False,
    ) -> None:
        self.scenario = scenario
        #: The robot's model: what the controllers (and their feed-forward) know.
        self.robot: RobotModel = robot if robot is not None else load_robot_model(scenario.robot.description,
                                                                                   search_path=package_path)
        #: The robot simulated (:func:`simulated_robot`): the robot's model itself unless the scenario changes it.
        self.plant: RobotModel = self.robot
        #: The simulated world (None when the session drives given ``hardware``, e.g. a real robot).
        self.world: MujocoWorld | None = None
        if hardware is None:
            if world is not None:
                world.restart(scenario.initial_positions, source=scenario.source)
            else:
                world = simulated_world(self.robot, scenario)
            self.world = world
            self.plant = world.robot
            hardware = MujocoHardware(self.world)
            if scenario.imperfect:
                hardware = ImperfectHardware(hardware, latency_cycles=scenario.latency_cycles,
                                             position_noise=scenario.noise.position,
                                             velocity_noise=scenario.noise.velocity, seed=scenario.noise.seed)
        elif world is not None:
            raise ValueError("a session drives either given hardware or a simulated world, not both")
        elif scenario.robot_settings():
            name, value = next(iter(scenario.robot_settings().items()))
            raise ConfigError("is a setting of the simulated robot; this hardware is given (a real robot has its "
                              "own)", source=scenario.source, field=name, value=value)
        elif scenario.objects:
            raise ConfigError("objects need a simulated robot; this hardware has no simulation door",
                              source=scenario.source, field="objects", value=[o.name for o in scenario.objects])
        for k, obj in enumerate(scenario.objects):
            if self.world.has_body(obj.name):
                raise ConfigError("a link of the robot already has that name", source=scenario.source,
                                  field=f"objects[{k}].name", value=obj.name)
        self.hardware = hardware
        #: What :meth:`dynamics` and :meth:`holding_effort` keep: the world's (kept with it), else this session's.
        self._derived: dict = self.world.derived if self.world is not None else {}
        self.manager = ControllerManager(self.hardware, self.robot, scenario.gravity_m_s2)
        self.manager.load_file(scenario.controller_file, scenario.controller_overrides)
        # Command sources are checked before any controller starts: nothing moves on bad input.
        self.sources: dict[str, CommandSource] = {
            name: command_source_from_config(cfg, field=f"commands.{name}", source=scenario.source)
            for name, cfg in scenario.commands.items()
        }
        for name in scenario.start_controllers:
            self.manager.load(name)
        for name, source in self.sources.items():
            source.sample(0.0)  # the first sample must evaluate, or the run is refused
            # A value the controller would clamp to the joint's limits is refused, not clamped silently.
            check_within_limits(source, self.manager.controller(name), self.robot, field=f"commands.{name}",
                                source_file=scenario.source)
        self.manager.start(scenario.start_controllers)
        for name in self.sources:
            owner = self.manager.command_owner(name)
            if owner is not None:
                raise ConfigError(f"controller {owner.name!r} already commands it", source=scenario.source,
                                  field=f"commands.{name}", value=name)
        clock = WallClockPacer(speed) if realtime else SimulatedClock()
        self.loop = ControlLoop(self.hardware, self.manager, period_s=scenario.loop_period_s, clock=clock)
        if scenario.loop == "auto":  # the compiled cycle when every part of the run has one
            from jointctl.compiled.plan import compile_loop

            self.loop.compiler = compile_loop
        else:
            self.loop.mode_reason = "the scenario asks for it (loop: python)"
        for name, source in self.sources.items():
            self.loop.add_input(SourceFeed(source, self.manager.controller(name)))
        if scenario.objects:
            self.loop.add_input(object_spawner(self.hardware.simulation, scenario.objects))
        #: Handles of the scenario's trajectory goals, in the order they were sent.
        self.goals: list = []
        #: The goals their executor refused when sent (the loop carries on without them).
        #: Scenario goals the executor refused: (loop time [s], the refusal); nothing moved for them.
        self.rejected_goals: list[tuple[float, InvalidTrajectory]] = []
        if scenario.goals:
            goals = []
            for k, g in enumerate(scenario.goals):
                executor = self.manager.controller(g["controller"])
                if not isinstance(executor, TrajectoryExecutor):
                    raise ConfigError("must name a trajectory executor", source=scenario.source,
                                      field=f"goals[{k}].controller", value=g["controller"])
                goals.append((g["at_s"], executor, _goal_maker(g, scenario.source, k, executor)))
            self.loop.add_input(_goal_sender(self, goals))
        self.recorder: TraceRecorder | None = None
        self.out_dir = Path(out_dir) if out_dir is not None else None
        if self.out_dir is not None or keep_trace:
            self.recorder = TraceRecorder(self.out_dir / TRACE_FILE if self.out_dir is not None else None,
                                          self.hardware, self.manager.references, every=scenario.record_every)
            self.loop.add_observer(self.recorder)
        #: ``run.mcap`` beside the trace (with ``mcap``): the same rows and more for Foxglove and PlotJuggler.
        self.mcap: McapRecorder | None = None
        if self.out_dir is not None and mcap:
            self.mcap = McapRecorder(
                self.out_dir / MCAP_FILE, robot=self.robot, hardware=self.hardware, manager=self.manager,
                loop=self.loop, urdf=description_text(self.robot, package_path), every=scenario.record_every,
                metadata={"scenario": scenario.name})
            self.recorder.chunk_readers.append(self.mcap.add_rows)

    @property
    def trace_path(self) -> Path | None:
        return self.recorder.path if self.recorder is not None else None

    def dynamics(self, robot: RobotModel, joints=None) -> RobotDynamics:
        """The :class:`~jointctl.model.dynamics.RobotDynamics` of ``robot`` (the session's ``robot`` or ``plant``)
        under the scenario's gravity, for ``joints`` (default: all movable joints): one object for whoever asks in
        this session and, on a world kept for a sweep's runs, in the runs that follow. Its answers are those of the
        pose last set: set the pose before reading it (as a new one needs too)."""
        names = tuple(j.name for j in robot.movable_joints) if joints is None else tuple(joints)
        gravity = tuple(float(g) for g in self.scenario.gravity_m_s2)
        key = ("dynamics", id(robot), gravity, names)
        found = self._derived.get(key)
        if found is None:  # (the robot kept beside it: its id stays its own)
            found = self._derived[key] = (robot, RobotDynamics(robot, gravity, joints=names))
        return found[1]

    def holding_effort(self, robot: RobotModel, joint: str, pose: dict):
        """:func:`~jointctl.metrics.step_loop.holding_effort` of ``joint`` of ``robot`` (the session's ``robot`` or
        ``plant``) under the scenario's gravity, kept as :meth:`dynamics` is."""
        return holding_effort(robot, joint, pose, self.scenario.gravity_m_s2, memo=self._derived)

    def trace(self) -> Trace:
        """The trace kept in memory (``keep_trace``, no ``out_dir``), once the session is closed."""
        if self.recorder is None:
            raise RuntimeError("this session records no trace")
        return self.recorder.trace()

    def run(self, duration_s: float | None = None) -> float:
        """Run for ``duration_s`` (default: the scenario's); returns the real-time factor."""
        duration = self.scenario.duration_s if duration_s is None else duration_s
        wall_before = self.loop.wall_time_s
        cycles = self.loop.run(duration)
        wall = self.loop.wall_time_s - wall_before
        return cycles * self.loop.period_s / wall if wall > 0 else math.inf

    def close(self) -> None:
        """Write the records: ``trace.csv`` (and ``run.mcap``)."""
        try:
            if self.mcap is not None and not self.mcap.closed:
                # Every executor's goals: the scenario's and those of ROS clients (served), refusals too.
                for controller in self.manager.loaded():
                    if isinstance(controller, TrajectoryExecutor):
                        self.mcap.add_goal_events(controller.goals.history, controller.name)
            if self.recorder is not None:
                self.recorder.close()
        finally:
            if self.mcap is not None:
                self.mcap.close()

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def object_spawner(simulation: SimulationDoor, objects) -> ObjectSpawner:
    """A loop input that adds each object through the hardware's simulation door once loop time
    reaches its spawn time."""
    return ObjectSpawner(simulation, objects)


def goal_trajectory(goal: dict, source: str, index: int) -> JointTrajectory:
    """The JointTrajectory a scenario goal describes."""
    field = f"goals[{index}]"
    try:
        if "coarse_sine" in goal:
            return coarse_sine(**goal["coarse_sine"])
        data = goal["trajectory"] if "trajectory" in goal else read_yaml(goal["file"])
        return JointTrajectory.from_dict(data)
    except (TypeError, ValueError, AttributeError) as exc:
        raise ConfigError(f"cannot build the trajectory: {exc}", source=source, field=field) from None


def _goal_maker(goal: dict, source: str, index: int, executor: TrajectoryExecutor):
    """A function of the executor giving the goal's trajectory when it is sent: a ``path`` is
    timed from the executor's desired pose at that moment; anything else is built now. Both are
    checked here, before the run starts."""
    if "path" not in goal:
        trajectory = goal_trajectory(goal, source, index)
        return lambda executor: trajectory
    spec = goal["path"]
    field = f"goals[{index}].path"
    if not isinstance(spec, dict):
        raise ConfigError("must be a mapping {points, timing}", source=source, field=field, value=spec)
    points, timing = spec.get("points"), spec.get("timing", "ruckig")
    if timing not in ("chapter", "ruckig"):
        raise ConfigError("must be chapter or ruckig", source=source, field=f"{field}.timing", value=timing)
    try:
        array = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        array = None
    if array is None or array.ndim != 2 or not np.isfinite(array).all():
        raise ConfigError("must be a list of joint-angle lists", source=source, field=f"{field}.points",
                          value=points)
    if array.shape[1] != len(executor.joint_names):
        raise ConfigError(f"each point needs {len(executor.joint_names)} values "
                          f"({', '.join(executor.joint_names)})", source=source, field=f"{field}.points",
                          value=points)
    return lambda executor: executor.plan_path(array, timing=timing)


def _goal_sender(session: Session, goals) -> GoalSender:
    """A loop input that submits each goal to its executor once loop time reaches ``at_s``;
    a refused goal is kept in ``session.rejected_goals``, not raised into the loop."""
    return GoalSender(goals, session.goals, session.rejected_goals)

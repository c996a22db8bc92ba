"""Read and validate a scenario file.

A scenario names what to run and for how long; jointctl's additions to the
robot's own files (gravity, initial positions, loop rate, command sources)
live here::

    name: one_dof_step
    robot: one_dof                  # a folder under robots/, or a robot.yaml / .xacro / .urdf path
    controller_file: position       # a key of the robot's robot.yaml, or a YAML path
    controllers:                    # optional overrides of the controller file's values
      joint1_position_controller: {pid: {p: 800}}
    start_controllers: [joint_state_controller, joint1_position_controller]
    gravity: -9.81                  # m/s² along z, or [gx, gy, gz]
    timestep_s: 0.001               # physics step; the loop runs at loop_rate_hz (default 1/timestep, or a
                                    # ROS 2 controller file's controller_manager update_rate)
    initial_positions: {joint1: -0.2}
    duration_s: 3.0
    commands:
      joint1_position_controller: {type: step, from: -0.2, to: -0.5, at: 0.5}
    objects:                        # rigid bodies spawned at a given time
      - {name: weight, shape: cylinder, radius_m: 0.05, length_m: 0.2, mass_kg: 10,
         xyz: [0, 0, 4], spawn_at_s: 1.0}
    record: {every: 1}
    analysis: {type: step_response, joint: joint1}
    # The simulated robot as a real one may be: the controllers keep the robot's nominal model.
    payload_kg: 2.5                 # a point mass at the payload link (robot.yaml payload_link, else the last link)
    model:                          # the simulated robot's links and joints (model.LINK.FIELD, model.JOINT.FIELD)
      link2: {mass: 1.2}            # mass [kg] (the inertia scaled with it), ixx iyy izz ixy ixz iyz [kg·m²]
      joint1: {damping: 12}         # damping [N·s/m or N·m·s/rad], friction [N or N·m], armature [kg or kg·m²]
    latency_cycles: 2               # commands reach the robot this many control cycles late
    noise: {position: 1.0e-4, velocity: 1.0e-3, seed: 0}   # white noise on each measured position, velocity
    loop: auto                      # auto: the compiled cycle when every part has one (same numbers); python

``--set key=value`` overrides any field before validation (``value`` is read
as YAML: ``--set gravity=-5``, ``--set controllers.joint1_position_controller.pid.p=800``).
Numbers read as written, the YAML 1.2 way (:class:`jointctl.control.manager.YamlLoader`, the
loader of the files too): ``800``, ``1_000``, ``2.5``, ``.5``, ``1e3``, ``1E-3``, ``-2.5e+2``;
``true``/``false``, ``[0, 0, -5]`` and ``{p: 800}`` as in YAML; anything else is a string.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from jointctl.control.manager import load_yaml_text, read_yaml, ros2_update_rate, set_dotted
from jointctl.control.params import unknown_field_message
from jointctl.control.ros2_parameters import controller_entries
from jointctl.errors import ConfigError
from jointctl.paths import robots_dir, scenarios_dir
from jointctl.scenario.plant import JOINT_FIELDS, LINK_FIELDS, PAYLOAD, check_model_value, check_payload
from jointctl.sim.objects import ObjectSpec, object_from_config
from jointctl.sim.steps import physics_steps
from jointctl.validate import checked_number

_KEYS = {
    "name", "description", "robot", "controller_file", "controllers", "start_controllers",
    "gravity", "timestep_s", "loop_rate_hz", "floor", "initial_positions", "duration_s",
    "commands", "record", "analysis", "objects", "goals", "payload_kg", "model", "latency_cycles", "noise", "loop",
}
#: Every top-level field a scenario may have (what ``--set`` reaches).
SCENARIO_FIELDS = frozenset(_KEYS)
#: The fields of the simulated robot a real robot leaves uncertain (the controllers keep the nominal model):
#: the payload [kg], the model's links and joints, the commands' latency [control cycles], the sensors' noise.
LATENCY = "latency_cycles"
NOISE_FIELDS = ("position", "velocity", "seed")
ROBOT_SETTINGS = (PAYLOAD, "model", LATENCY, "noise")
_GOAL_SOURCES = ("trajectory", "file", "coarse_sine", "path")
#: The loop paths a scenario may ask for (``loop``): the compiled cycle where it can (auto), or Python always.
LOOP_MODES = ("auto", "python")
_DESCRIPTION_SUFFIXES = (".xacro", ".urdf")


@dataclass(frozen=True)
class RobotFiles:
    """Where a robot's description and controller files are."""

    name: str
    description: Path
    controller_files: dict[str, Path]
    folder: Path
    #: The manifest's other sections (``serve``: defaults for ``jointctl serve``; ``ros``: actions).
    extras: dict[str, Any] = field(default_factory=dict)
    #: The robot.yaml it was read from (None for a bare description).
    manifest: Path | None = None

    @property
    def reference(self) -> str:
        """What a scenario's ``robot:`` field says to name this robot again: the manifest's or the
        description's absolute path."""
        return str(self.manifest or self.description)


@dataclass(frozen=True)
class SensorNoise:
    """White Gaussian noise on each measured joint position and velocity: standard deviations [m or rad, m/s or
    rad/s], drawn from a generator seeded with ``seed`` (a whole number or a tuple of them): the same seed, the same
    run."""

    position: float = 0.0
    velocity: float = 0.0
    seed: int | tuple[int, ...] = 0

    @property
    def any(self) -> bool:
        return self.position > 0 or self.velocity > 0


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. Paths are absolute; numbers SI. ``payload_kg``, ``model_changes``
    (``model.NAME.FIELD`` -> value), ``latency_cycles`` and ``noise`` describe the simulated robot only."""

    name: str
    source: str
    robot: RobotFiles
    controller_file: Path
    controller_overrides: dict[str, Any]
    start_controllers: tuple[str, ...]
    gravity_m_s2: tuple[float, float, float]
    timestep_s: float
    loop_period_s: float
    floor: bool
    initial_positions: dict[str, float]
    duration_s: float
    commands: dict[str, dict[str, Any]]
    objects: tuple[ObjectSpec, ...]
    goals: tuple[dict[str, Any], ...]
    record_every: int
    analysis: dict[str, Any] | None
    description: str = ""
    raw: dict[str, Any] = field(default_factory=dict, repr=False)
    payload_kg: float = 0.0
    model_changes: dict[str, float] = field(default_factory=dict)
    latency_cycles: int = 0
    noise: SensorNoise = SensorNoise()
    #: ``auto``: the compiled cycle when every part of the run has a compiled form; ``python``: the Python loop.
    loop: str = "auto"

    @property
    def changes_robot(self) -> bool:
        """Whether the simulated robot differs from the robot's model (a payload, a changed link or joint)."""
        return bool(self.model_changes) or self.payload_kg != 0.0

    @property
    def imperfect(self) -> bool:
        """Whether commands arrive late or the sensors are noisy."""
        return self.latency_cycles != 0 or self.noise.any

    def robot_settings(self) -> dict[str, Any]:
        """The settings of the simulated robot this scenario gives, by the names ``--set`` uses."""
        settings: dict[str, Any] = {PAYLOAD: self.payload_kg} if self.payload_kg else {}
        settings.update(self.model_changes)
        if self.latency_cycles:
            settings[LATENCY] = self.latency_cycles
        settings.update({f"noise.{k}": v for k, v in (("position", self.noise.position),
                                                     ("velocity", self.noise.velocity)) if v})
        return settings


def builtin_scenarios() -> dict[str, Path]:
    """Built-in scenario names and their files."""
    return {p.stem: p for p in sorted(scenarios_dir().glob("*.yaml"))}


def builtin_robots() -> dict[str, Path]:
    """Built-in robot names and their folders."""
    return {p.parent.name: p.parent for p in sorted(robots_dir().glob("*/robot.yaml"))}


def load_scenario(name_or_path: str | Path, overrides: Iterable[str] = ()) -> Scenario:
    """Load a built-in scenario by name, or a scenario file, applying ``--set`` overrides."""
    path = Path(name_or_path)
    if not path.suffix and str(name_or_path) in builtin_scenarios():
        path = builtin_scenarios()[str(name_or_path)]
    elif not path.is_file():
        known = ", ".join(builtin_scenarios())
        raise ConfigError(f"no such scenario file or built-in scenario (built-in: {known})",
                          source=str(name_or_path))
    source = str(path)
    raw = read_yaml(path)
    if not isinstance(raw, dict):
        raise ConfigError("a scenario must be a mapping of fields", source=source, value=raw)
    for item in overrides:
        key, value = parse_override(item)
        set_dotted(raw, key, value, source="--set")
    return _Validator(raw, source, path.parent).scenario()


def parse_override(item: str) -> tuple[str, Any]:
    """``"a.b=1.5"`` -> ``("a.b", 1.5)``; the value is read as YAML, numbers as in YAML 1.2
    (``1e3`` -> 1000.0, see :class:`~jointctl.control.manager.YamlLoader`)."""
    key, sep, text = item.partition("=")
    key = key.strip()
    if not sep or not key or any(not part for part in key.split(".")):
        raise ConfigError("expected KEY=VALUE with a dotted KEY", source="--set", value=item)
    try:
        value = load_yaml_text(text) if text.strip() else ""
    except yaml.YAMLError:
        raise ConfigError("the value is not valid YAML", source="--set", field=key, value=text) from None
    return key, value


def check_robot_setting(field: str, value: Any, source: str | None = None) -> None:
    """Check one setting of the simulated robot (a field under :data:`ROBOT_SETTINGS`: ``payload_kg``,
    ``model.NAME.FIELD``, ``latency_cycles``, ``noise.*``) as the scenario loader checks it, without a scenario
    (ConfigError naming ``source``, the field and the value). Whether the robot has the link or joint is the
    session's check."""
    raw: dict[str, Any] = {}
    set_dotted(raw, field, value, source=source)
    checks = _Validator(raw, source, Path.cwd())
    check_payload(raw.get(PAYLOAD, 0.0), source)
    checks.model_changes()
    checks.latency_cycles()
    checks.noise()


def flatten(mapping: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}``."""
    flat: dict[str, Any] = {}
    for key, value in mapping.items():
        dotted = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, Mapping) and value:
            flat.update(flatten(value, dotted))
        else:
            flat[dotted] = value
    return flat


class _Validator:
    def __init__(self, raw: dict[str, Any], source: str, base: Path) -> None:
        self.raw = raw
        self.source = source
        self.base = base

    def error(self, message: str, field: str, value: Any = None, *, with_value: bool = True):
        if with_value:
            return ConfigError(message, source=self.source, field=field, value=value)
        return ConfigError(message, source=self.source, field=field)

    def number(self, key: str, default: Any = None, *, positive: bool = False) -> float:
        value = self.raw.get(key, default)
        if value is None:
            raise self.error("is required", key, with_value=False)
        return self.check_number(value, key, positive=positive)

    def check_number(self, value: Any, field: str, *, positive: bool = False) -> float:
        return checked_number(value, lambda message: self.error(message, field, value), positive=positive)

    def mapping(self, key: str) -> dict[str, Any]:
        value = self.raw.get(key) or {}
        if not isinstance(value, dict):
            raise self.error("must be a mapping", key, value)
        return value

    def scenario(self) -> Scenario:
        raw = self.raw
        for key in raw:
            if key not in _KEYS:
                raise self.error(unknown_field_message(str(key), _KEYS), str(key), raw[key])
        robot = self.robot_files(raw.get("robot"))
        controller_file = self.controller_file(robot)
        overrides = self.mapping("controllers")
        start = raw.get("start_controllers")
        if not isinstance(start, list) or not start or not all(isinstance(s, str) for s in start):
            raise self.error("must be a non-empty list of controller names", "start_controllers", start)
        timestep = self.number("timestep_s", 0.001, positive=True)
        update_rate = ros2_update_rate(controller_file) if "loop_rate_hz" not in raw else None
        if update_rate is not None:  # a ROS 2 file: the controller manager's rate is the loop's
            rate, rate_field = update_rate
            steps = physics_steps(1.0 / rate, timestep, source=str(controller_file), field=rate_field, value=rate)
        else:
            rate = self.number("loop_rate_hz", 1.0 / timestep, positive=True)
            steps = physics_steps(1.0 / rate, timestep, source=self.source, field="loop_rate_hz", value=rate)
        floor = raw.get("floor", True)
        if not isinstance(floor, bool):
            raise self.error("must be true or false", "floor", floor)
        initial = self.mapping("initial_positions")
        for joint, value in initial.items():
            self.check_number(value, f"initial_positions.{joint}")
        commands = self.mapping("commands")
        for name, cfg in commands.items():
            if name not in start:
                raise self.error("commands a controller that is not started", f"commands.{name}", name)
            if not isinstance(cfg, dict):
                raise self.error("must be a mapping describing a command source", f"commands.{name}", cfg)
        record = self.mapping("record")
        every = record.get("every", 1)
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise self.error("must be a whole number of at least 1", "record.every", every)
        analysis = raw.get("analysis")
        if analysis is not None and not (isinstance(analysis, dict) and isinstance(analysis.get("type"), str)):
            raise self.error("must be a mapping with a 'type'", "analysis", analysis)
        loop = raw.get("loop", "auto")
        if loop not in LOOP_MODES:
            raise self.error(f"must be one of {', '.join(LOOP_MODES)}", "loop", loop)
        name = raw.get("name") or Path(self.source).stem
        return Scenario(
            name=str(name),
            source=self.source,
            robot=robot,
            controller_file=controller_file,
            controller_overrides=flatten(overrides),
            start_controllers=tuple(start),
            gravity_m_s2=self.gravity(raw.get("gravity", -9.81)),
            timestep_s=timestep,
            loop_period_s=steps * timestep,
            floor=floor,
            initial_positions=dict(initial),
            duration_s=self.number("duration_s", positive=True),
            commands=commands,
            objects=self.objects(floor),
            goals=self.goals(start),
            record_every=every,
            analysis=analysis,
            description=str(raw.get("description", "")).strip(),
            raw=raw,
            payload_kg=check_payload(raw.get(PAYLOAD, 0.0), self.source),
            model_changes=self.model_changes(),
            latency_cycles=self.latency_cycles(),
            noise=self.noise(),
            loop=loop,
        )

    def model_changes(self) -> dict[str, float]:
        """``model: {NAME: {FIELD: value}}`` -> ``{"model.NAME.FIELD": value}``, each field a link's or a joint's
        (:data:`~jointctl.scenario.plant.LINK_FIELDS`, :data:`~jointctl.scenario.plant.JOINT_FIELDS`) with a value it
        takes. Whether the robot has the link or joint is checked when the session reads the robot."""
        value = self.raw.get("model")
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.error("must be a mapping of links and joints to their fields", "model", value)
        known = sorted(set(LINK_FIELDS) | set(JOINT_FIELDS))
        changes = {}
        for name, fields in value.items():
            if not isinstance(fields, dict) or not fields:
                raise self.error("must be a mapping of the link's or joint's fields (model.LINK.FIELD)",
                                 f"model.{name}", fields)
            for attribute, number in fields.items():
                dotted = f"model.{name}.{attribute}"
                if attribute not in known:
                    raise self.error(unknown_field_message(str(attribute), known), dotted, number)
                changes[dotted] = check_model_value(dotted, attribute, number, self.source)
        return changes

    def latency_cycles(self) -> int:
        value = self.raw.get(LATENCY, 0)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or value != int(value):
            raise self.error("must be a whole number of control cycles", LATENCY, value)
        if value < 0:
            raise self.error("must not be negative", LATENCY, value)
        return int(value)

    def noise(self) -> SensorNoise:
        value = self.raw.get("noise")
        if value is None:
            return SensorNoise()
        if not isinstance(value, dict):
            raise self.error("must be a mapping of position, velocity and seed", "noise", value)
        for key in value:
            if key not in NOISE_FIELDS:
                raise self.error(unknown_field_message(str(key), NOISE_FIELDS), f"noise.{key}", value[key])
        sigmas = []
        for key in ("position", "velocity"):
            sigma = value.get(key, 0.0)
            if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not math.isfinite(sigma) or sigma < 0:
                raise self.error("must be a standard deviation, 0 or more", f"noise.{key}", sigma)
            sigmas.append(float(sigma))
        seed = value.get("seed", 0)
        parts = seed if isinstance(seed, list) and seed else [seed]
        if not all(isinstance(p, int) and not isinstance(p, bool) and p >= 0 for p in parts):
            raise self.error("must be a whole number, 0 or more, or a list of them", "noise.seed", seed)
        return SensorNoise(*sigmas, seed=tuple(seed) if isinstance(seed, list) else seed)

    def goals(self, started: list[str]) -> tuple[dict[str, Any], ...]:
        """Trajectory goals sent to a started executor at ``at_s``: one of ``trajectory`` (the
        message as data), ``file`` (a YAML/JSON file of it), ``coarse_sine`` (the chapter's client)
        or ``path`` ({points: [[...], ...], timing: chapter|ruckig}, timed when it is sent)."""
        value = self.raw.get("goals") or []
        if not isinstance(value, list):
            raise self.error("must be a list of goals", "goals", value)
        goals = []
        for k, goal in enumerate(value):
            field = f"goals[{k}]"
            if not isinstance(goal, dict):
                raise self.error("must be a mapping", field, goal)
            unknown = set(goal) - {"controller", "at_s", *_GOAL_SOURCES}
            if unknown:
                raise self.error("unknown field", f"{field}.{sorted(unknown)[0]}", goal[sorted(unknown)[0]])
            if goal.get("controller") not in started:
                raise self.error("must name a started trajectory controller", f"{field}.controller",
                                 goal.get("controller"))
            at = self.check_number(goal.get("at_s", 0.0), f"{field}.at_s")
            if at < 0:
                raise self.error("must not be negative", f"{field}.at_s", at)
            sources = [s for s in _GOAL_SOURCES if s in goal]
            if len(sources) != 1:
                raise self.error(f"needs exactly one of {', '.join(_GOAL_SOURCES)}", field, sorted(goal))
            source = sources[0]
            if not isinstance(goal[source], (dict, str)):
                raise self.error("must be a mapping" + (" or a path" if source == "file" else ""),
                                 f"{field}.{source}", goal[source])
            if source == "file":
                path = (self.base / goal["file"]).resolve()
                if not path.is_file():
                    raise self.error("file not found", f"{field}.file", goal["file"])
                goal = {**goal, "file": str(path)}
            goals.append({**goal, "at_s": at})
        return tuple(goals)

    def objects(self, floor: bool) -> tuple[ObjectSpec, ...]:
        value = self.raw.get("objects") or []
        if not isinstance(value, list):
            raise self.error("must be a list of objects", "objects", value)
        objects = tuple(object_from_config(cfg, field=f"objects[{k}]", source=self.source, floor=floor)
                        for k, cfg in enumerate(value))
        names = [o.name for o in objects]
        for k, name in enumerate(names):
            if name in names[:k]:
                raise self.error("two objects have the same name", f"objects[{k}].name", name)
        return objects

    def gravity(self, value: Any) -> tuple[float, float, float]:
        if isinstance(value, list):
            if len(value) != 3:
                raise self.error("must be a number (z) or a list of three numbers", "gravity", value)
            return tuple(self.check_number(v, f"gravity[{k}]") for k, v in enumerate(value))
        return (0.0, 0.0, self.check_number(value, "gravity"))

    def robot_files(self, ref: Any) -> RobotFiles:
        if not isinstance(ref, str) or not ref:
            raise self.error("must name a built-in robot or a robot file", "robot", ref)
        robots = builtin_robots()
        if ref in robots:
            return read_robot_manifest(robots[ref] / "robot.yaml")
        path = (self.base / ref).resolve()
        if path.is_dir() and (path / "robot.yaml").is_file():
            return read_robot_manifest(path / "robot.yaml")
        if path.is_file() and path.suffix in (".yaml", ".yml"):
            return read_robot_manifest(path)
        if path.is_file() and path.suffix in _DESCRIPTION_SUFFIXES:
            return RobotFiles(path.stem, path, {}, path.parent)
        raise self.error(f"no such robot (built-in: {', '.join(robots)}; or a robot.yaml, "
                         ".xacro or .urdf path)", "robot", ref)

    def controller_file(self, robot: RobotFiles) -> Path:
        ref = self.raw.get("controller_file")
        if not isinstance(ref, str) or not ref:
            raise self.error("must name a controller file", "controller_file", ref)
        if ref in robot.controller_files:
            return robot.controller_files[ref]
        path = (self.base / ref).resolve()
        if not path.is_file():
            known = ", ".join(robot.controller_files) or "none"
            raise self.error(f"no such controller file (robot {robot.name} has: {known})",
                             "controller_file", ref)
        return path


def read_robot_manifest(path: Path) -> RobotFiles:
    """Read a robot folder's ``robot.yaml``: ``description`` and named ``controllers`` files."""
    source = str(path)
    raw = read_yaml(path)
    if not isinstance(raw, dict):
        raise ConfigError("must be a mapping", source=source, value=raw)
    folder = path.parent
    desc = raw.get("description")
    if not isinstance(desc, str) or not (folder / desc).is_file():
        raise ConfigError("must name the robot's .xacro or .urdf file", source=source,
                          field="description", value=desc)
    controllers = raw.get("controllers") or {}
    if not isinstance(controllers, dict):
        raise ConfigError("must map names to controller YAML files", source=source,
                          field="controllers", value=controllers)
    files = {}
    for key, rel in controllers.items():
        if not isinstance(rel, str) or not (folder / rel).is_file():
            raise ConfigError("controller file not found", source=source,
                              field=f"controllers.{key}", value=rel)
        files[str(key)] = (folder / rel).resolve()
    extras = {k: v for k, v in raw.items() if k not in ("description", "controllers")}
    return RobotFiles(folder.name, (folder / desc).resolve(), files, folder.resolve(), extras, path.resolve())


def scenario_for_robot(robot: str | RobotFiles, controllers: str, overrides: Iterable[str] = ()) -> Scenario:
    """A scenario that brings up a robot (a built-in name, or its files) with every controller of one
    of its controller files (a manifest key or a YAML path), as the chapter's launch files do, at the
    manifest's ``serve`` defaults, until stopped."""
    if isinstance(robot, RobotFiles):
        files = robot
    else:
        robots = builtin_robots()
        if robot not in robots:
            raise ConfigError(f"no such robot (built-in: {', '.join(robots)})", field="robot", value=robot)
        files = read_robot_manifest(robots[robot] / "robot.yaml")
    if controllers in files.controller_files:
        controller_path = files.controller_files[controllers]
    elif Path(controllers).is_absolute() and Path(controllers).is_file():
        controller_path = Path(controllers)
    else:
        raise ConfigError(f"the robot has no such controller file (it has: {', '.join(files.controller_files)})",
                          field="--controllers", value=controllers)
    tree = read_yaml(controller_path)
    if not isinstance(tree, dict):
        raise ConfigError("must map controller names (under one namespace) to their parameters",
                          source=str(controller_path), value=tree)
    defaults = files.extras.get("serve") or {}
    name = robot if isinstance(robot, str) else files.name
    raw = {
        "name": f"{name}_{controller_path.stem if controllers not in files.controller_files else controllers}",
        "robot": robot if isinstance(robot, str) else files.reference, "controller_file": str(controllers),
        "start_controllers": list(controller_entries(tree)),
        "gravity": defaults.get("gravity", -9.81), "initial_positions": defaults.get("initial_positions", {}),
        "duration_s": 1e9, "record": {"every": 1},
    }
    for item in overrides:
        key, value = parse_override(item)
        set_dotted(raw, key, value, source="--set")
    return _Validator(raw, str(files.manifest or controller_path), files.folder).scenario()

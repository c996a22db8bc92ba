"""What a command's robot argument names, and the scenario it becomes.

Every command that takes a robot (``run``, ``tune``, ``serve``, ``controller``, ``identify``,
``bode``, ``autotune``) reads its target through :func:`resolve_target`, which accepts:

==========================  ===========================================================================
the target                  taken as
==========================  ===========================================================================
``one_dof``                 a built-in robot (``jointctl list``), with ``--controllers NAME``
``one_dof_step``            a built-in scenario
``DIR/`` (has robot.yaml)   a robot folder: its ``robot.yaml`` names the description and controller files
``robot.yaml``              a robot manifest (any YAML whose fields are ``description``, ``controllers``...)
``arm.urdf``, ``arm.xacro`` a robot description, with ``--controllers FILE.yaml`` (a ros_control YAML)
``step.yaml``               a scenario (a YAML with ``robot:``)
==========================  ===========================================================================

A robot (anything but a scenario) is brought up as the chapter's launch files do: every controller of
the controller file started, at the manifest's ``serve`` defaults. ``--controllers`` names one of the
manifest's controller files or a YAML path. :attr:`Target.taken_as` is the one line a command prints
to say what it took the argument for. A ros_control controller file given as the target is refused
with a message saying where it goes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import yaml

from jointctl.control.manager import read_yaml
from jointctl.errors import ConfigError
from jointctl.scenario.spec import (
    RobotFiles,
    Scenario,
    builtin_robots,
    builtin_scenarios,
    load_scenario,
    read_robot_manifest,
    scenario_for_robot,
)

#: Suffixes of a robot description.
DESCRIPTION_SUFFIXES = (".urdf", ".xacro")
#: The manifest's own fields (robot.yaml): a YAML holding these and no ``robot`` is a manifest.
MANIFEST_FIELDS = frozenset({"description", "controllers", "serve", "ros", "tune", "video", "industrial",
                             "payload_link"})


@dataclass(frozen=True)
class Target:
    """A command's target: the scenario to run and the line saying what the argument was taken for."""

    scenario: Scenario
    taken_as: str
    #: The robot's files (None for a scenario, whose robot is ``scenario.robot``).
    robot: RobotFiles | None = None

    @property
    def is_robot(self) -> bool:
        return self.robot is not None


def robot_files(ref: str) -> tuple[RobotFiles, str] | None:
    """(the robot's files, what ``ref`` was taken for) when ``ref`` names a robot (a built-in name, a
    folder with a robot.yaml, a manifest, a .urdf/.xacro); None when it names something else."""
    robots = builtin_robots()
    if ref in robots:
        return read_robot_manifest(robots[ref] / "robot.yaml"), "a built-in robot"
    path = Path(ref)
    if path.is_dir():
        if (path / "robot.yaml").is_file():
            return read_robot_manifest(path / "robot.yaml"), f"a robot folder ({path / 'robot.yaml'})"
        raise ConfigError("a folder without a robot.yaml (write one with 'jointctl init ROBOT.urdf')",
                          field="target", value=ref)
    if path.suffix in DESCRIPTION_SUFFIXES and not path.is_file():
        raise ConfigError("no such robot description file", field="target", value=ref)
    if path.is_file() and path.suffix in DESCRIPTION_SUFFIXES:
        resolved = path.resolve()
        taken = f"a robot description ({path.suffix[1:].upper()})"
        return RobotFiles(resolved.stem, resolved, {}, resolved.parent), taken
    if path.is_file() and path.suffix in (".yaml", ".yml") and _yaml_kind(path) == "manifest":
        return read_robot_manifest(path), "a robot manifest"
    return None


def resolve_target(target: str, *, controllers: str | None = None, default_controllers: str = "position",
                   overrides: Iterable[str] = (), robot_defaults: Iterable[str] = (),
                   robot_overrides: Iterable[str] = ()) -> Target:
    """The scenario ``target`` names (see the module docstring). ``controllers``: the robot's controller
    file (a manifest key or a YAML path; default ``default_controllers``, else the manifest's only
    file); ``overrides``: ``--set`` items; for a robot only, ``robot_defaults`` come before them (what
    a command assumes of a robot it brings up, e.g. a finite ``duration_s``) and ``robot_overrides``
    after (what it needs, e.g. only the joint_state_controller started)."""
    overrides = list(overrides)
    found = robot_files(target)
    if found is not None:
        files, taken = found
        chosen = _controller_file(files, controllers, default_controllers)
        scenario = scenario_for_robot(files, chosen, [*robot_defaults, *overrides, *robot_overrides])
        return Target(scenario, f"took {target} as {taken}, controllers {_shown(files, chosen)}", files)
    path = Path(target)
    if not path.suffix and target in builtin_scenarios():
        return Target(load_scenario(target, overrides), f"took {target} as the built-in scenario")
    if path.is_file() and path.suffix in (".yaml", ".yml"):
        kind = _yaml_kind(path)
        if kind == "controllers":
            raise ConfigError("is a ros_control controller file, not a robot or a scenario: give the robot (a "
                              ".urdf/.xacro, a robot folder or its robot.yaml) and this file with --controllers",
                              field="target", value=target)
        if controllers is not None:
            raise ConfigError("a scenario names its own controller file (controller_file:); --controllers goes "
                              "with a robot", field="--controllers", value=controllers)
        return Target(load_scenario(target, overrides), f"took {target} as a scenario")
    if path.is_file():
        raise ConfigError("is neither a robot (.urdf, .xacro, a robot folder, robot.yaml) nor a scenario (.yaml)",
                          field="target", value=target)
    raise ConfigError(f"no such file, robot or scenario (built-in robots: {', '.join(builtin_robots())}; "
                      f"scenarios: {', '.join(builtin_scenarios())})", field="target", value=target)


def _controller_file(files: RobotFiles, given: str | None, default: str) -> str:
    """The controller file a robot is brought up with: ``given`` (a manifest key or a path, made
    absolute), else ``default`` when the manifest has it, else its only file."""
    if given is not None:
        if given in files.controller_files:
            return given
        path = Path(given)
        if path.is_file():
            return str(path.resolve())
        known = ", ".join(files.controller_files) or "none; give a ros_control YAML file"
        raise ConfigError(f"no such controller file (the robot's: {known})", field="--controllers", value=given)
    if default in files.controller_files:
        return default
    if len(files.controller_files) == 1:
        return next(iter(files.controller_files))
    if not files.controller_files:
        raise ConfigError("a robot description needs its controllers: give a ros_control YAML with --controllers "
                          "(or write a robot folder with 'jointctl init')", field="--controllers")
    raise ConfigError(f"the robot has several controller files; pick one ({', '.join(files.controller_files)})",
                      field="--controllers")


def _shown(files: RobotFiles, chosen: str) -> str:
    return chosen if chosen in files.controller_files else Path(chosen).name


def _yaml_kind(path: Path) -> str:
    """``"manifest"``, ``"controllers"`` (a ros_control file: controllers with a ``type``, under one
    namespace or at the top) or ``"scenario"`` (anything else, validated as one)."""
    try:
        raw = read_yaml(path)
    except (ConfigError, yaml.YAMLError):
        return "scenario"  # its own error comes from loading it as one
    if not isinstance(raw, dict) or not raw:
        return "scenario"
    if "robot" not in raw and "description" in raw and set(raw) <= MANIFEST_FIELDS:
        return "manifest"
    if path.name == "robot.yaml" and "robot" not in raw:
        return "manifest"
    body = next(iter(raw.values())) if len(raw) == 1 else raw
    if isinstance(body, dict) and body and any(isinstance(c, dict) and "type" in c for c in body.values()) \
            and "robot" not in raw:
        return "controllers"
    return "scenario"


__all__ = ["Target", "resolve_target", "robot_files"]

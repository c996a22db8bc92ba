"""Fixtures of the control-layer tests: the chapter's 1-DOF model and a fake hardware.

:class:`FakeHardware` is a unit-test double of the :class:`HardwareInterface`
contract: its state lists can be set directly by a test, :meth:`read` only
counts calls (the state is already "read"), :meth:`write` latches the effort
commands and :meth:`advance` integrates a unit-mass double integrator
(semi-implicit Euler), so closed-loop tests run in microseconds.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from jointctl.hardware.interface import EFFORT, HardwareInterface
from jointctl.model import load_robot_model
from jointctl.model.robot_model import RobotModel
from jointctl.paths import robots_dir

ONE_DOF_DIR = robots_dir() / "one_dof"
ONE_DOF_XACRO = ONE_DOF_DIR / "urdf" / "one_dof_robot.xacro"
POSITION_YAML = ONE_DOF_DIR / "config" / "one_dof_pos_ctl_params.yaml"
VELOCITY_YAML = ONE_DOF_DIR / "config" / "one_dof_vel_ctl_params.yaml"
NAMESPACE = "one_DOF_robot"


class FakeHardware(HardwareInterface):
    """Settable joint state; effort-commanded unit masses when advanced."""

    def __init__(self, joint_names: tuple[str, ...] = ("joint1",), *,
                 effort_joints: tuple[str, ...] | None = None, mass_kg: float = 1.0) -> None:
        super().__init__(joint_names)
        self.effort_joints = frozenset(joint_names if effort_joints is None else effort_joints)
        self.mass_kg = mass_kg
        self.reads = 0
        self.writes = 0
        self.applied = [0.0] * len(self.joint_names)

    def command_interfaces(self, joint: str) -> frozenset[str]:
        return frozenset({EFFORT}) if joint in self.effort_joints else frozenset()

    def read(self) -> None:
        self.reads += 1

    def write(self) -> None:
        self.writes += 1
        self.applied = list(self.command_buffer(EFFORT))

    def advance(self, period_s: float) -> None:
        for k, force in enumerate(self.applied):
            self.velocity[k] += force / self.mass_kg * period_s
            self.position[k] += self.velocity[k] * period_s
            self.effort[k] = force

    def set_state(self, joint: str, position: float, velocity: float = 0.0) -> None:
        k = self.joint_index(joint)
        self.position[k] = position
        self.velocity[k] = velocity


@pytest.fixture(scope="session")
def robot() -> RobotModel:
    """The chapter's 1-DOF prismatic robot: joint1 in [-1, 0] m, 1000 N, 100 m/s."""
    return load_robot_model(ONE_DOF_XACRO)


@pytest.fixture
def hardware(robot: RobotModel) -> FakeHardware:
    """A fake hardware with the robot's movable joints (joint1 only), all effort-driven."""
    return FakeHardware(tuple(j.name for j in robot.movable_joints))


@pytest.fixture
def chapter_controllers() -> dict[str, dict[str, Any]]:
    """Both chapter files' controller entries, by controller name."""
    out: dict[str, dict[str, Any]] = {}
    for path in (POSITION_YAML, VELOCITY_YAML):
        out.update(yaml.safe_load(Path(path).read_text())[NAMESPACE])
    return out


@pytest.fixture
def write_yaml(tmp_path: Path):
    """Write text (or a data structure, dumped as YAML) to a file in tmp_path; returns its path."""

    def write(content: Any, name: str = "controllers.yaml") -> Path:
        path = tmp_path / name
        text = content if isinstance(content, str) else yaml.safe_dump(content, sort_keys=False)
        path.write_text(text)
        return path

    return write

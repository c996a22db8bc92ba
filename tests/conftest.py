"""Shared fixtures: the built-in 1-DOF robot and helpers to write small scenario files."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from jointctl.paths import robots_dir

ONE_DOF_XACRO = robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro"
POSITION_YAML = robots_dir() / "one_dof" / "config" / "one_dof_pos_ctl_params.yaml"
VELOCITY_YAML = robots_dir() / "one_dof" / "config" / "one_dof_vel_ctl_params.yaml"


def step_scenario(**changes) -> dict:
    """A short position-step scenario as a dict; keyword arguments replace fields."""
    scenario = {
        "name": "test_step",
        "robot": "one_dof",
        "controller_file": "position",
        "start_controllers": ["joint_state_controller", "joint1_position_controller"],
        "gravity": -9.81,
        "initial_positions": {"joint1": -0.2},
        "duration_s": 0.5,
        "commands": {"joint1_position_controller": {"type": "step", "from": -0.2, "to": -0.5, "at": 0.1}},
    }
    scenario.update(changes)
    return scenario


@pytest.fixture
def write_scenario(tmp_path: Path):
    """Write a scenario dict to a YAML file in tmp_path and return its path."""

    def write(data: dict, name: str = "scenario.yaml") -> Path:
        path = tmp_path / name
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        return path

    return write

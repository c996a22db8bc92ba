"""Copies of the 1-DOF robot with another joint damping or effort limit, for the safety tests: a robot
less damped than the plant the excitation is planned on resonates more than planned."""

from __future__ import annotations

from pathlib import Path

import yaml

from jointctl.paths import robots_dir
from jointctl.scenario.spec import load_scenario

#: The chapter's piston: its moving mass [kg], URDF damping [N·s/m], position gain [N/m].
MASS_KG, DAMPING, KP, G = 1.01, 10.0, 400.0, 9.81


def one_dof_variant(folder: Path, *, damping: float = DAMPING, effort: float = 1000.0, initial: float = -0.5,
                    overrides=()):
    """The 1-DOF robot with joint ``damping`` [N·s/m] and ``effort`` limit [N], its position controller
    file, resting at ``initial`` [m]: a scenario written into ``folder``."""
    source = (robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro").read_text()
    dynamics, limit = '<dynamics damping="10.0"/>', 'effort="1000.0"'
    assert dynamics in source and limit in source
    (folder / "robot.xacro").write_text(source.replace(dynamics, f'<dynamics damping="{damping}"/>')
                                        .replace(limit, f'effort="{effort}"'))
    (folder / "scenario.yaml").write_text(yaml.safe_dump({
        "name": "variant", "robot": "robot.xacro",
        "controller_file": str(robots_dir() / "one_dof" / "config" / "one_dof_pos_ctl_params.yaml"),
        "start_controllers": ["joint1_position_controller"], "initial_positions": {"joint1": initial},
        "duration_s": 1.0}))
    return load_scenario(folder / "scenario.yaml", list(overrides))


def plant(damping: float = DAMPING, mass: float = MASS_KG) -> dict:
    """An identification's metrics claiming ``mass`` [kg] and ``damping`` [N·s/m]."""
    return {"mass_kg": mass, "damping_n_s_m": damping}

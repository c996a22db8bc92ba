"""Every command that takes a robot or a scenario reaches the simulated robot's settings by the names a sweep varies
(``payload_kg``, ``model.*``, ``latency_cycles``, ``noise.*``) with ``--set``."""

from __future__ import annotations

import json

import pytest

from jointctl.cli import build_parser, main
from jointctl.cli.common import target_scenario

COMMANDS = {
    "run": [], "tune": [], "serve": [], "identify": ["--joint", "joint1"],
    "bode": ["--controller", "joint1_position_controller"],
    "autotune": ["--controller", "joint1_position_controller", "--zeta", "0.7", "--bandwidth-hz", "2"],
}


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_sets_the_simulated_robot_by_name(command):
    args = build_parser().parse_args([command, "one_dof", *COMMANDS[command], "--set", "payload_kg=5",
                                      "--set", "model.joint1.damping=3", "--set", "latency_cycles=1",
                                      "--set", "noise.position=1e-4"])
    scenario = target_scenario(args, say=False)
    assert (scenario.payload_kg, scenario.model_changes, scenario.latency_cycles, scenario.noise.position) == (
        5.0, {"model.joint1.damping": 3.0}, 1, 1e-4)


@pytest.mark.slow
def test_identify_measures_the_payload_it_was_given(tmp_path, capsys):
    # The piston and sensor disk move 1.01 kg; a 2 kg payload on the disk makes 3.01 kg. The tolerance is the nominal
    # identification's (tests/test_cli.py): the identified mass includes what MuJoCo's implicit damping adds (h·b).
    out = tmp_path / "identify"
    assert main(["identify", "one_dof", "--joint", "joint1", "--duration-s", "6", "--set", "payload_kg=2",
                 "--out", str(out)]) == 0, capsys.readouterr().err
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["mass_kg"] == pytest.approx(1.01 + 2.0, rel=0.02)
    assert metrics["model_mass_kg"] == pytest.approx(1.01)  # the controllers' (nominal) model

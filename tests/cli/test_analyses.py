"""identify, bode and autotune on the command line: the user's limits, --dry-run, and a stop's one line."""

from __future__ import annotations

import json

import pytest

from jointctl.cli import main


@pytest.fixture
def nothing_moves(monkeypatch):
    """Make creating a session, a loop, a simulated world or a served robot's connection fail the test."""
    def refuse(*args, **kwargs):
        raise AssertionError("something was built that could move the robot")

    import jointctl.cli.analyses as analyses
    import jointctl.runtime.loop as loop
    import jointctl.scenario.session as session
    import jointctl.sim.world as world

    monkeypatch.setattr(session.Session, "__init__", refuse)
    monkeypatch.setattr(loop.ControlLoop, "__init__", refuse)
    monkeypatch.setattr(world.MujocoWorld, "__init__", refuse)
    monkeypatch.setattr(analyses, "_served", refuse)


@pytest.mark.parametrize("argv, fragments", [
    (["identify", "one_dof", "--joint", "joint1", "--dry-run", "--max-effort", "40"],
     ["Chirp 0.2 to 3 Hz", "limit 40 N (--max-effort)", "Binding limit: effort"]),
    (["identify", "one_dof", "--joint", "joint1", "--hardware", "ros", "--dry-run"], ["Binding limit: position"]),
    (["bode", "one_dof", "--controller", "joint1_position_controller", "--dry-run", "--points", "4",
      "--workspace=-0.7:-0.3"], ["4 stepped sines", "window [-0.7, -0.3] m (the workspace)"]),
    (["bode", "one_dof", "--joint", "joint1", "--hardware", "industrial", "--dry-run", "--points", "3"],
     ["the reference alone", "3 stepped sines"]),
    (["autotune", "one_dof", "--controller", "joint1_position_controller", "--bandwidth-hz", "1", "--dry-run",
      "--max-velocity", "0.5"], ["Designed gains", "Check step", "limit 0.5 m/s (--max-velocity)"]),
    # A ros2_control robot's loop is planned on its simulated twin: the robot's ROS 2 file's pid_controller (an i
    # with pid_controller's default clamps 0/0 integrates nothing: the model's i is 0), never connecting.
    (["bode", "one_dof", "--hardware", "ros2", "--controller", "pid_controller", "--dry-run", "--points", "4",
      "--set", "controllers.pid_controller.gains.joint1.i=50.0"],
     ["controller pid_controller", "gains p 400, i 0, d 20, derivative on the error", "4 stepped sines"]),
    (["autotune", "one_dof", "--hardware", "ros2", "--controller", "pid_controller", "--bandwidth-hz", "5",
      "--dry-run"], ["controller pid_controller", "Designed gains", "(now p 400, i 0, d 20)", "Check step 0.1 m"]),
])
def test_a_dry_run_prints_the_plan_and_moves_nothing(nothing_moves, capsys, tmp_path, argv, fragments) -> None:
    assert main([*argv, "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{argv[0]} --dry-run: nothing moves. Joint joint1")
    for fragment in fragments:
        assert fragment in out, fragment
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("flags, field", [
    (["--workspace", "1:0"], "--workspace"), (["--workspace", "abc"], "--workspace"),
    (["--max-effort", "-5"], "--max-effort"), (["--max-velocity", "0"], "--max-velocity"),
    (["--max-effort", "nan"], "--max-effort"),
])
@pytest.mark.parametrize("command", [["identify", "one_dof", "--joint", "joint1"],
                                     ["bode", "one_dof", "--controller", "joint1_position_controller"],
                                     ["autotune", "one_dof", "--controller", "joint1_position_controller",
                                      "--bandwidth-hz", "5"]])
def test_malformed_limits_are_refused_in_one_line_before_anything_moves(nothing_moves, capsys, command, flags,
                                                                        field) -> None:
    assert main([*command, *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"jointctl: error: {field}: ")


def test_a_dry_run_of_a_recorded_trace_is_refused(capsys) -> None:
    assert main(["identify", "run.csv", "--joint", "joint1", "--robot", "one_dof", "--dry-run"]) == 2
    assert "--dry-run" in capsys.readouterr().err


def test_crossing_the_workspace_exits_2_naming_the_limit_the_value_and_the_time(capsys, tmp_path) -> None:
    from tests.identification.variants import one_dof_variant, plant

    one_dof_variant(tmp_path, damping=2.0)  # resonates ten times more than the plant file says
    (tmp_path / "plant.json").write_text(json.dumps(plant(damping=40.0)))
    code = main(["bode", str(tmp_path / "scenario.yaml"), "--controller", "joint1_position_controller",
                 "--f-min-hz", "3.0", "--f-max-hz", "3.17", "--points", "2", "--plant", str(tmp_path / "plant.json"),
                 "--workspace=-0.65:-0.35", "--out", str(tmp_path / "out")])
    assert code == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("jointctl: error: ")]
    assert len(errors) == 1
    assert errors[0].startswith("jointctl: error: --workspace: the joint's position reached -0.65")
    assert "at t = " in errors[0] and "ramped back to -0.5 m" in errors[0] and "at rest" in errors[0]


def test_a_step_faster_than_max_velocity_is_refused_before_anything_moves(nothing_moves, capsys, tmp_path) -> None:
    """A 5 Hz loop steps 0.1 m at up to 1.18 m/s (the model's peak): beyond --max-velocity 0.5, refused."""
    assert main(["autotune", "one_dof", "--controller", "joint1_position_controller", "--bandwidth-hz", "5",
                 "--dry-run", "--max-velocity", "0.5", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "--step: a step of 0.1 m would move at 1.18 m/s, beyond --max-velocity 0.5" in err

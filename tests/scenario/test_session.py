"""Building a session refuses bad input before anything moves."""

from __future__ import annotations

import pytest

from jointctl.errors import ConfigError, ControllerError, ExpressionError, ModelError
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from tests.conftest import step_scenario


def _build(write_scenario, tmp_path, **changes):
    return Session(load_scenario(write_scenario(step_scenario(**changes))), out_dir=tmp_path / "out")


def test_a_session_runs_and_the_step_moves_the_joint(write_scenario, tmp_path):
    with _build(write_scenario, tmp_path) as session:
        rtf = session.run()
        assert 0 < rtf  # reported (its size is make bench's business)
        assert session.hardware.position[0] < -0.4
    # Where a refused session below would have written its trace, a good one does.
    assert (tmp_path / "out" / "trace.csv").exists()


@pytest.mark.parametrize(("changes", "error", "text"), [
    ({"controllers": {"joint1_position_controller": {"pid": {"p": -1}}}}, ConfigError, "pid.p: must not be negative"),
    ({"controllers": {"joint1_position_controller": {"pid": {"p": ".inf"}}}}, ConfigError, "pid.p: must be a number"),
    ({"controllers": {"joint1_position_controller": {"type": "effort_controllers/Nope"}}}, ConfigError,
     "joint1_position_controller.type: unknown controller type"),
    ({"controllers": {"joint1_position_controller": {"joint": "joint9"}}}, ConfigError,
     "joint1_position_controller.joint: no such joint"),
    ({"controllers": {"ghost_controller": {"type": "x"}}}, ConfigError, "ghost_controller"),
    ({"start_controllers": ["joint1_position_controller", "ghost"]}, ControllerError, "ghost"),
    ({"initial_positions": {"joint1": 0.5}}, ConfigError, "initial_positions.joint1: outside"),
    ({"initial_positions": {"joint7": 0.0}}, ConfigError, "initial_positions.joint7"),
    ({"commands": {"joint1_position_controller": {"type": "expression", "expression": "__import__('os')"}}},
     ExpressionError, "__import__"),
    ({"commands": {"joint1_position_controller": {"type": "expression", "expression": "log(t)"}}},
     ExpressionError, "log"),
    ({"commands": {"joint1_position_controller": {"type": "sine", "amplitude": 0.1}}}, ConfigError,
     "frequency_hz"),
])
def test_bad_input_is_refused_before_anything_moves(write_scenario, tmp_path, changes, error, text):
    with pytest.raises(error) as err:
        _build(write_scenario, tmp_path, **changes)
    assert text in str(err.value)
    assert not (tmp_path / "out" / "trace.csv").exists()


def test_broken_robot_description_is_a_model_error(write_scenario, tmp_path):
    from tests.conftest import POSITION_YAML

    urdf = tmp_path / "broken.urdf"
    urdf.write_text("<robot name='r'><link name='a'/><joint name='j' type='prismatic'>"
                    "<parent link='a'/><child link='b'/></joint></robot>")
    with pytest.raises(ModelError, match=r"broken.urdf: joint\[j\]"):
        _build(write_scenario, tmp_path, robot=str(urdf), controller_file=str(POSITION_YAML))


def test_position_and_velocity_controllers_on_one_joint_are_refused(write_scenario, tmp_path):
    from tests.conftest import POSITION_YAML

    both = tmp_path / "both.yaml"
    both.write_text(POSITION_YAML.read_text() + """
  joint1_velocity_controller:
    type: effort_controllers/JointVelocityController
    joint: joint1
    pid: {p: 200.0, i: 0.0, d: 0.0}
""")
    with pytest.raises(ControllerError, match="'joint1' effort interface is already claimed"):
        _build(write_scenario, tmp_path, controller_file=str(both),
               start_controllers=["joint1_position_controller", "joint1_velocity_controller"])


def test_runtime_expression_errors_hold_the_last_value_and_are_counted(write_scenario, tmp_path):
    # 1/(i-3) fails at the fourth message only: the command holds and the run goes on.
    cmd = {"type": "expression", "expression": "-0.5 + 0.01/(i-3)", "rate_hz": 100}
    with _build(write_scenario, tmp_path, commands={"joint1_position_controller": cmd},
                duration_s=0.1) as session:
        session.run()
        assert session.sources["joint1_position_controller"].rejected_samples == 1


def test_metrics_json_is_strict_json_with_null_for_what_never_happened(tmp_path):
    import json

    from jointctl.recording.metrics_file import json_ready

    assert json_ready({"a": float("nan"), "b": [1.0, float("inf")], "c": {"d": -float("inf")}}) == {
        "a": None, "b": [1.0, None], "c": {"d": None}}
    json.dumps(json_ready({"x": float("nan")}), allow_nan=False)

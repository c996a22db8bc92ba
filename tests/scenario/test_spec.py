"""Scenario files: built-ins, --set overrides, and every refusal naming its field."""

from __future__ import annotations

import pytest

from jointctl.errors import ConfigError
from jointctl.scenario.spec import builtin_scenarios, flatten, load_scenario, parse_override
from tests.conftest import step_scenario


def test_builtin_scenarios_load():
    assert {"one_dof_step", "one_dof_sine", "one_dof_velocity_sine"} <= set(builtin_scenarios())
    scenario = load_scenario("one_dof_step")
    assert scenario.robot.name == "one_dof"
    assert scenario.controller_file.name == "one_dof_pos_ctl_params.yaml"
    assert scenario.gravity_m_s2 == (0.0, 0.0, -9.81)
    assert scenario.loop_period_s == 0.001
    assert scenario.initial_positions == {"joint1": -0.2}


def test_set_overrides_scalars_nested_fields_and_controller_gains():
    scenario = load_scenario("one_dof_step", [
        "gravity=-5", "controllers.joint1_position_controller.pid.p=800",
        "initial_positions.joint1=-0.3", "duration_s=1.5",
    ])
    assert scenario.gravity_m_s2 == (0.0, 0.0, -5.0)
    assert scenario.controller_overrides == {"joint1_position_controller.pid.p": 800}
    assert scenario.initial_positions == {"joint1": -0.3}
    assert scenario.duration_s == 1.5


def test_gravity_vector_and_loop_rate(write_scenario):
    scenario = load_scenario(write_scenario(step_scenario(gravity=[0, 1, -2], loop_rate_hz=500)))
    assert scenario.gravity_m_s2 == (0.0, 1.0, -2.0)
    assert scenario.loop_period_s == pytest.approx(0.002)


def test_parse_override_reads_yaml_values():
    assert parse_override("a.b=1.5") == ("a.b", 1.5)
    assert parse_override("flag=true") == ("flag", True)
    assert parse_override("g=[0, 0, -5]") == ("g", [0, 0, -5])


@pytest.mark.parametrize(("text", "expected"), [
    ("1e3", 1000.0), ("1E-3", 0.001), ("-2.5e+2", -250.0), ("+2e2", 200.0), (".5", 0.5), ("-.5", -0.5),
    ("1.", 1.0), ("1_000", 1000), ("1_000.5", 1000.5), ("2.5E3", 2500.0), ("800", 800),
    ("'1e3'", "1e3"), ("e3", "e3"), ("1e", "1e"), ("1e3x", "1e3x"), ("1.2.3", "1.2.3"),
])
def test_override_numbers_read_as_written(text, expected):
    """YAML 1.1 (PyYAML) reads 1e3, 1E-3 and -.5 as strings; a user means numbers (YAML 1.2)."""
    key, value = parse_override(f"controllers.c.pid.p={text}")
    assert key == "controllers.c.pid.p"
    assert value == expected and type(value) is type(expected)


def test_a_gain_in_exponent_notation_reaches_the_controller():
    scenario = load_scenario("one_dof_step", ["controllers.joint1_position_controller.pid.p=1e3",
                                              "controllers.joint1_position_controller.pid.d=2.5E1"])
    assert scenario.controller_overrides["joint1_position_controller.pid.p"] == 1000.0
    assert scenario.controller_overrides["joint1_position_controller.pid.d"] == 25.0


@pytest.mark.parametrize("item", ["novalue", "=3", "a..b=1", ".a=1"])
def test_malformed_override_is_refused(item):
    with pytest.raises(ConfigError) as err:
        parse_override(item)
    assert "--set" in str(err.value) and item in str(err.value)


def test_flatten():
    assert flatten({"a": {"b": 1, "c": {"d": 2}}, "e": 3}) == {"a.b": 1, "a.c.d": 2, "e": 3}


BAD_FIELDS = [
    ({"robot": "no_such_robot"}, "robot", "no_such_robot"),
    ({"robot": 3}, "robot", "3"),
    ({"controller_file": "nope"}, "controller_file", "nope"),
    ({"start_controllers": []}, "start_controllers", "[]"),
    ({"start_controllers": "joint1_position_controller"}, "start_controllers", "joint1_position_controller"),
    ({"gravity": "down"}, "gravity", "down"),
    ({"gravity": [0, 0]}, "gravity", "[0, 0]"),
    ({"gravity": float("nan")}, "gravity", "nan"),
    ({"timestep_s": 0}, "timestep_s", "0"),
    ({"loop_rate_hz": 300}, "loop_rate_hz", "300"),
    ({"duration_s": -1}, "duration_s", "-1"),
    ({"duration_s": True}, "duration_s", "True"),
    ({"floor": "yes"}, "floor", "yes"),
    ({"initial_positions": {"joint1": "low"}}, "initial_positions.joint1", "low"),
    ({"initial_positions": [1]}, "initial_positions", "[1]"),
    ({"commands": {"other_controller": {"type": "constant", "value": 0}}}, "commands.other_controller",
     "other_controller"),
    ({"commands": {"joint1_position_controller": 3}}, "commands.joint1_position_controller", "3"),
    ({"record": {"every": 0}}, "record.every", "0"),
    ({"analysis": {"joint": "joint1"}}, "analysis", "joint1"),
    ({"colour": "red"}, "colour", "red"),
]


@pytest.mark.parametrize(("change", "field", "value"), BAD_FIELDS)
def test_bad_field_is_refused_naming_file_field_and_value(write_scenario, change, field, value):
    path = write_scenario(step_scenario(**change))
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    message = str(err.value)
    assert str(path) in message
    assert f": {field}:" in message
    assert value in message


def test_a_misspelt_scenario_field_names_the_nearest_field(write_scenario):
    path = write_scenario(step_scenario(gravty=-5))
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    assert err.value.field == "gravty" and err.value.value == -5
    assert err.value.message.startswith("unknown field (did you mean 'gravity'? known: ")


def test_missing_duration_is_required(write_scenario):
    data = step_scenario()
    del data["duration_s"]
    with pytest.raises(ConfigError, match="duration_s: is required"):
        load_scenario(write_scenario(data))


def test_missing_file_and_unknown_builtin(tmp_path):
    with pytest.raises(ConfigError, match="no such scenario"):
        load_scenario(tmp_path / "absent.yaml")
    with pytest.raises(ConfigError, match="built-in: .*one_dof_step"):
        load_scenario("one_dof_stpe")


def test_malformed_yaml_names_the_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("name: x\nrobot: [one_dof\n")
    with pytest.raises(ConfigError, match=r"not valid YAML: line \d+"):
        load_scenario(path)


def test_scenario_that_is_not_a_mapping(tmp_path):
    path = tmp_path / "list.yaml"
    path.write_text("- a\n- b\n")
    with pytest.raises(ConfigError, match="mapping"):
        load_scenario(path)


def test_robot_by_path_to_xacro_and_controller_file_by_path(write_scenario, tmp_path):
    from tests.conftest import ONE_DOF_XACRO, POSITION_YAML

    scenario = load_scenario(write_scenario(step_scenario(robot=str(ONE_DOF_XACRO),
                                                          controller_file=str(POSITION_YAML))))
    assert scenario.robot.description == ONE_DOF_XACRO
    assert scenario.controller_file == POSITION_YAML

"""Gain groups: what each controller exposes, the checks, and the YAML written back."""

from __future__ import annotations

import dataclasses
import math

import pytest
import yaml

from jointctl.errors import ConfigError
from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot
from jointctl.tuning.gains import gain_groups, gains_yaml

POSITION = "joint1_position_controller"


@pytest.fixture(scope="module")
def session():
    s = Session(scenario_for_robot("one_dof", "position"))
    yield s
    s.close()


def group(session, name=POSITION):
    return next(g for g in gain_groups(session.manager, session.robot) if g.name == name)


def test_pid_group_lists_gains_with_units_and_the_yaml_values(session):
    described = group(session).describe()
    assert described["kind"] == "pid" and described["joints"] == ["joint1"]
    assert [(g["name"], g["unit"], g["value"]) for g in described["gains"]] == [
        ("p", "N/m", 400.0), ("i", "N/(m·s)", 0.0), ("d", "N·s/m", 0.0), ("i_clamp", "N", 1000.0)]


def test_velocity_and_revolute_units():
    s = Session(scenario_for_robot("arm7dof", "velocity"))
    try:
        g = group(s, "joint0_velocity_controller").describe()["gains"]
        assert [x["unit"] for x in g] == ["N·m·s/rad", "N·m/rad", "N·m·s²/rad", "N·m"]
    finally:
        s.close()


@pytest.mark.parametrize("name, value, words", [
    ("p", -1.0, "must not be below 0"), ("p", math.inf, "finite"), ("p", math.nan, "finite"),
    ("p", "400", "must be a number"), ("p", None, "must be a number"), ("i", False, "must be a number"),
    ("i_clamp", -3, "must not be below 0"), ("gain", 1, "no such gain"),
])
def test_pid_checks_refuse_before_anything_is_applied(session, name, value, words):
    g = group(session)
    with pytest.raises(ConfigError, match=words):
        g.prepare(name, value)
    assert session.manager.controller(POSITION).pid.gains.p == 400.0


def test_yaml_keeps_the_file_and_writes_i_clamp_only_when_it_is_set(session):
    controller = session.manager.controller(POSITION)
    original = controller.pid.gains
    try:
        text = gains_yaml(session.scenario.controller_file, [group(session)])
        assert "i_clamp" not in text  # the file had none and the running one is its default
        controller.set_gains(dataclasses.replace(original, i=5.0, i_clamp_min=-20.0, i_clamp_max=20.0))
        tree = yaml.safe_load(gains_yaml(session.scenario.controller_file, [group(session)], header="# h\n"))
        assert tree["one_DOF_robot"][POSITION]["pid"] == {"p": 400.0, "i": 5.0, "d": 0.0, "i_clamp": 20.0}
        assert tree["one_DOF_robot"]["joint_state_controller"] == {
            "type": "joint_state_controller/JointStateController", "publish_rate": 50}
        controller.set_gains(dataclasses.replace(original, i_clamp_min=-5.0, i_clamp_max=20.0))
        pid = yaml.safe_load(gains_yaml(session.scenario.controller_file, [group(session)]))["one_DOF_robot"][
            POSITION]["pid"]
        assert (pid["i_clamp_min"], pid["i_clamp_max"]) == (-5.0, 20.0) and "i_clamp" not in pid
    finally:
        controller.set_gains(original)

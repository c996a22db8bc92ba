"""robot.yaml's ``ros`` section is checked before the node starts: errors name the field."""

from __future__ import annotations

import pytest

from jointctl.errors import ConfigError
from jointctl.ros.node import check_actions, check_command_topics


def test_command_topics_map_topics_to_controllers():
    assert check_command_topics(None, "robot.yaml") == {}
    topics = {"/pos_cmd": "joint1_position_controller"}
    assert check_command_topics(topics, "robot.yaml") == topics


@pytest.mark.parametrize(("topics", "field"), [
    (["/pos_cmd"], "ros.command_topics"),
    ({"/pos_cmd": 3}, "ros.command_topics./pos_cmd"),
    ({"/pos_cmd": ""}, "ros.command_topics./pos_cmd"),
])
def test_bad_command_topics_are_refused_naming_the_field(topics, field):
    with pytest.raises(ConfigError) as caught:
        check_command_topics(topics, "robots/minimal_robot")
    assert caught.value.field == field and caught.value.source == "robots/minimal_robot"


def test_an_action_of_an_unknown_type_is_refused():
    with pytest.raises(ConfigError, match="traj, arm7dof_traj or follow_joint_trajectory") as caught:
        check_actions({"srv": {"type": "nope", "controller": "c"}}, "robot.yaml")
    assert caught.value.field == "ros.actions.srv"

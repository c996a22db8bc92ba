"""``joint_state_broadcaster/JointStateBroadcaster`` with ros2_controllers' parameters: a joint state every cycle,
the joints and interfaces asked for (the others NaN), extra joints at 0."""

from __future__ import annotations

import math

import pytest

from jointctl.control.joint_state_controller import JointStateBroadcaster
from jointctl.control.manager import ControllerManager
from jointctl.errors import ConfigError
from tests.control.conftest import FakeHardware
from tests.control.test_pid_controller import TWO_JOINTS


def broadcaster(write_yaml, **parameters) -> ControllerManager:
    hardware = FakeHardware(("joint1", "joint2"))
    manager = ControllerManager(hardware, TWO_JOINTS)
    manager.load_file(write_yaml({
        "controller_manager": {"ros__parameters": {"jsb": {"type": "joint_state_broadcaster/JointStateBroadcaster"}}},
        "jsb": {"ros__parameters": parameters}}))
    return manager


def test_every_joint_every_cycle_by_default(write_yaml):
    manager = broadcaster(write_yaml)
    manager.start(["jsb"])
    jsb = manager.controller("jsb")
    assert isinstance(jsb, JointStateBroadcaster)
    manager.hardware.set_state("joint2", 0.3, 0.1)
    for k in range(4):
        manager.update(k * 0.01, 0.01)
    assert jsb.published == 4 and jsb.latest.time_s == 0.03
    assert jsb.latest.name == ("joint1", "joint2") and jsb.latest.position == (0.0, 0.3)
    assert jsb.latest.velocity == (0.0, 0.1)


def test_joints_and_interfaces_select_and_extra_joints_are_zero(write_yaml):
    manager = broadcaster(write_yaml, joints=["joint2"], interfaces=["position"], extra_joints=["gripper"],
                          use_local_topics=True)
    manager.start(["jsb"])
    manager.hardware.set_state("joint2", 0.3, 0.1)
    manager.update(0.0, 0.01)
    sample = manager.controller("jsb").latest
    assert sample.name == ("joint2", "gripper") and sample.position == (0.3, 0.0)
    assert all(math.isnan(v) for v in sample.velocity + sample.effort)
    assert manager.controller("jsb").use_local_topics is True


@pytest.mark.parametrize(("parameters", "field", "value"), [
    ({"interfaces": ["position", "acceleration"], "joints": ["joint1"]}, "interfaces[1]", "acceleration"),
    ({"map_interface_to_joint_state": {"position": "position_filtered"}}, "map_interface_to_joint_state.position",
     "position_filtered"),
    ({"publish_rate": 50.0}, "publish_rate", 50.0),
    ({"joints": ["joint1"], "interfaces": ["position"], "extra_joints": ["joint1"]}, "extra_joints", "joint1"),
])
def test_what_jointctl_cannot_publish_is_refused(write_yaml, parameters, field, value):
    manager = broadcaster(write_yaml, **parameters)
    with pytest.raises(ConfigError) as info:
        manager.load("jsb")
    assert info.value.field == f"jsb.ros__parameters.{field}" and info.value.value == value

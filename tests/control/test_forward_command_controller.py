"""``forward_command_controller/ForwardCommandController`` and ``effort_controllers/JointGroupEffortController`` as
ros2_controllers 4.18 (``forward_controllers_base.cpp``): nothing until a command, then the last one every cycle;
the door refuses what the ROS 2 controller would error on."""

from __future__ import annotations

import math

import pytest

from jointctl.control.manager import ControllerManager
from jointctl.errors import ConfigError, InvalidCommand
from jointctl.hardware.interface import EFFORT
from tests.control.conftest import FakeHardware
from tests.control.test_pid_controller import TWO_JOINTS

H = 0.01


def manager_with(write_yaml, controller_type: str, parameters: dict) -> ControllerManager:
    manager = ControllerManager(FakeHardware(("joint1", "joint2")), TWO_JOINTS)
    manager.load_file(write_yaml({
        "controller_manager": {"ros__parameters": {"forward": {"type": controller_type}}},
        "forward": {"ros__parameters": parameters}}))
    return manager


@pytest.mark.parametrize(("controller_type", "parameters"), [
    ("forward_command_controller/ForwardCommandController",
     {"joints": ["joint2", "joint1"], "interface_name": "effort"}),
    ("effort_controllers/JointGroupEffortController", {"joints": ["joint2", "joint1"]}),
])
def test_commands_are_written_every_cycle_in_joint_order_from_the_first(write_yaml, controller_type, parameters):
    manager = manager_with(write_yaml, controller_type, parameters)
    manager.start(["forward"])
    effort = manager.hardware.command_buffer(EFFORT)
    effort[:] = [3.0, 4.0]  # what the hardware had: kept until the first command
    manager.update(0.0, H)
    assert effort == [3.0, 4.0]
    forward = manager.controller("forward")
    forward.set_commands([20.0, -10.0])
    for k in range(3):
        manager.update((k + 1) * H, H)
        assert effort == [-10.0, 20.0]
        effort[:] = [0.0, 0.0]


@pytest.mark.parametrize("values", [[1.0], [1.0, 2.0, 3.0], [1.0, math.nan], [math.inf, 1.0], ["1", 2.0], [True, 1.0]])
def test_a_wrong_count_or_a_value_that_is_not_a_finite_number_is_refused(write_yaml, values):
    manager = manager_with(write_yaml, "effort_controllers/JointGroupEffortController",
                           {"joints": ["joint1", "joint2"]})
    manager.start(["forward"])
    forward = manager.controller("forward")
    forward.set_commands([1.0, 2.0])
    with pytest.raises(InvalidCommand) as info:
        forward.set_commands(values)
    assert info.value.source == "forward" and info.value.field.startswith("commands")
    manager.update(0.0, H)
    assert manager.hardware.command_buffer(EFFORT) == [1.0, 2.0]


def test_the_effort_group_writes_zero_when_it_stops_and_forgets_its_command(write_yaml):
    manager = manager_with(write_yaml, "effort_controllers/JointGroupEffortController", {"joints": ["joint1"]})
    manager.start(["forward"])
    forward = manager.controller("forward")
    forward.set_commands([5.0])
    manager.update(0.0, H)
    manager.stop(["forward"])
    assert manager.hardware.command_buffer(EFFORT)[0] == 0.0
    manager.start(["forward"])
    assert forward.commands is None


@pytest.mark.parametrize(("controller_type", "parameters", "field", "value"), [
    ("forward_command_controller/ForwardCommandController", {"joints": ["joint1"]}, "interface_name", None),
    ("forward_command_controller/ForwardCommandController", {"joints": ["joint1"], "interface_name": "velocity"},
     "interface_name", "velocity"),
    ("effort_controllers/JointGroupEffortController", {"joints": ["joint1"], "interface_name": "position"},
     "interface_name", "position"),
    ("effort_controllers/JointGroupEffortController", {"joints": []}, "joints", []),
    ("effort_controllers/JointGroupEffortController", {"joints": ["joint7"]}, "joints[0]", "joint7"),
])
def test_bad_parameters_are_refused_naming_the_field(write_yaml, controller_type, parameters, field, value):
    manager = manager_with(write_yaml, controller_type, parameters)
    with pytest.raises(ConfigError) as info:
        manager.load("forward")
    assert info.value.field == f"forward.ros__parameters.{field}"
    assert (info.value.value == value) if value is not None else not info.value.has_value

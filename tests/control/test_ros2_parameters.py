"""ROS 2 controller_manager parameter files read as controller definitions: the control_demo file ros2_control_node
loads, and every refusal naming the file's field."""

from __future__ import annotations

import copy

import pytest

from jointctl.control.manager import ControllerManager, read_yaml, ros2_update_rate
from jointctl.control.ros2_parameters import controller_entries, is_ros2_parameters, read_ros2_controllers
from jointctl.errors import ConfigError
from tests.control.test_pid_controller import TWO_JOINTS
from tests.control.conftest import FakeHardware, POSITION_YAML
from tests.model.test_ros2_control import CONTROL_DEMO

DEMO_YAML = CONTROL_DEMO.parent / "controllers.yaml"

BASE = {
    "controller_manager": {"ros__parameters": {
        "update_rate": 100,
        "joint_state_broadcaster": {"type": "joint_state_broadcaster/JointStateBroadcaster"},
        "effort_controller": {"type": "effort_controllers/JointGroupEffortController"}}},
    "effort_controller": {"ros__parameters": {"joints": ["joint1"]}},
    "robot_state_publisher": {"ros__parameters": {"publish_frequency": 50.0}},  # another node's: skipped
}


def test_the_control_demo_file_reads_as_ros2_control_node_reads_it():
    tree = read_yaml(DEMO_YAML)
    assert is_ros2_parameters(tree) and not is_ros2_parameters(read_yaml(POSITION_YAML))
    ros2 = read_ros2_controllers(tree, str(DEMO_YAML))
    assert ros2.update_rate_hz == 100 and ros2.update_rate_field == "controller_manager.ros__parameters.update_rate"
    assert list(ros2.controllers) == ["joint_state_broadcaster", "pid_controller", "joint_trajectory_controller"]
    assert ros2.controllers["pid_controller"] == {
        "type": "pid_controller/PidController", "dof_names": ["joint1"], "command_interface": "velocity",
        "reference_and_state_interfaces": ["position"],
        "gains": {"joint1": {"p": 2.0, "i": 0.0, "d": 0.0, "i_clamp_max": 1.0, "i_clamp_min": -1.0}}}
    assert ros2.controllers["joint_state_broadcaster"] == {"type": "joint_state_broadcaster/JointStateBroadcaster"}
    assert ros2.fields["pid_controller"] == "pid_controller.ros__parameters"
    assert ros2.fields["joint_state_broadcaster"] == "joint_state_broadcaster.ros__parameters"
    assert ros2.type_fields["pid_controller"] == "controller_manager.ros__parameters.pid_controller.type"
    assert controller_entries(tree) == {"joint_state_broadcaster": "joint_state_broadcaster/JointStateBroadcaster",
                                        "pid_controller": "pid_controller/PidController",
                                        "joint_trajectory_controller":
                                            "joint_trajectory_controller/JointTrajectoryController"}
    assert ros2_update_rate(DEMO_YAML) == (100, "controller_manager.ros__parameters.update_rate")
    assert ros2_update_rate(POSITION_YAML) is None


def test_ros1_files_list_their_controllers_too():
    assert controller_entries(read_yaml(POSITION_YAML)) == {
        "joint_state_controller": "joint_state_controller/JointStateController",
        "joint1_position_controller": "effort_controllers/JointPositionController"}


def test_namespaced_sections_and_other_nodes(write_yaml):
    tree = copy.deepcopy(BASE)
    tree["/arm/controller_manager"] = tree.pop("controller_manager")
    tree["/arm/effort_controller"] = tree.pop("effort_controller")
    ros2 = read_ros2_controllers(tree, "c.yaml")
    assert ros2.manager_key == "/arm/controller_manager"
    assert ros2.controllers["effort_controller"]["joints"] == ["joint1"]
    assert ros2.fields["effort_controller"] == "/arm/effort_controller.ros__parameters"


def test_a_params_file_is_read_under_the_controllers_own_section(write_yaml):
    extra = write_yaml({"/**": {"ros__parameters": {"joints": ["joint2"]}},
                        "effort_controller": {"ros__parameters": {"interface_name": "effort"}}}, "extra.yaml")
    tree = copy.deepcopy(BASE)
    tree["controller_manager"]["ros__parameters"]["effort_controller"]["params_file"] = extra.name
    ros2 = read_ros2_controllers(tree, "c.yaml", base_dir=extra.parent, read=read_yaml)
    assert ros2.controllers["effort_controller"] == {"type": "effort_controllers/JointGroupEffortController",
                                                     "joints": ["joint1"], "interface_name": "effort"}


def test_the_controllers_generic_parameters_are_taken_out():
    tree = copy.deepcopy(BASE)
    tree["effort_controller"]["ros__parameters"].update(update_rate=100, is_async=False, thread_priority=50,
                                                        use_sim_time=True)
    assert read_ros2_controllers(tree, "c.yaml").controllers["effort_controller"] == {
        "type": "effort_controllers/JointGroupEffortController", "joints": ["joint1"]}


def _set(path: str, value):
    tree = copy.deepcopy(BASE)
    node = tree
    keys = path.split("/")
    for key in keys[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return tree


_DELETE = object()
M = "controller_manager/ros__parameters"
REFUSALS = [
    ("update rate not an integer", _set(f"{M}/update_rate", 100.0), "controller_manager.ros__parameters.update_rate",
     100.0),
    ("update rate zero", _set(f"{M}/update_rate", 0), "controller_manager.ros__parameters.update_rate", 0),
    ("unknown manager parameter", _set(f"{M}/upate_rate", 100), "controller_manager.ros__parameters.upate_rate", 100),
    ("declaration without a type", _set(f"{M}/effort_controller", {"typ": "x"}),
     "controller_manager.ros__parameters.effort_controller", {"typ": "x"}),
    ("unknown declaration key", _set(f"{M}/effort_controller/param_file", "x.yaml"),
     "controller_manager.ros__parameters.effort_controller.param_file", "x.yaml"),
    ("type not a string", _set(f"{M}/effort_controller/type", 3), "controller_manager.ros__parameters.effort_controller"
     ".type", 3),
    ("fallback controllers", _set(f"{M}/effort_controller/fallback_controllers", ["x"]),
     "controller_manager.ros__parameters.effort_controller.fallback_controllers", ["x"]),
    ("params file missing", _set(f"{M}/effort_controller/params_file", "nowhere.yaml"),
     "controller_manager.ros__parameters.effort_controller.params_file", "nowhere.yaml"),
    ("section without ros__parameters", _set("effort_controller", {"joints": ["joint1"]}), "effort_controller",
     {"joints": ["joint1"]}),
    ("misspelled section", {**_set("effort_controller", _DELETE), "efort_controller": {"ros__parameters": {}}},
     "efort_controller", "efort_controller"),
    ("a controller's own rate", _set("effort_controller/ros__parameters/update_rate", 50),
     "effort_controller.ros__parameters.update_rate", 50),
    ("asynchronous", _set("effort_controller/ros__parameters/is_async", True),
     "effort_controller.ros__parameters.is_async", True),
    ("type in the section", _set("effort_controller/ros__parameters/type", "x"),
     "effort_controller.ros__parameters.type", "x"),
]


PID = {"controller_manager": {"ros__parameters": {"pid": {"type": "pid_controller/PidController"}}},
       "pid": {"ros__parameters": {"dof_names": ["joint1"], "gains": {"joint1": {"p": 400, "antiwindup": True}}}}}
REFUSALS.append(("an integer gain", PID, "pid.ros__parameters.gains.joint1.p", 400))


@pytest.mark.parametrize(("case", "tree", "field", "value"), REFUSALS, ids=[r[0] for r in REFUSALS])
def test_a_bad_file_is_refused_naming_the_field(case, tree, field, value, tmp_path):
    with pytest.raises(ConfigError) as info:
        read_ros2_controllers(tree, "c.yaml", base_dir=tmp_path, read=read_yaml)
    assert info.value.source == "c.yaml" and info.value.field == field and info.value.value == value, str(info.value)


def test_a_file_without_a_controller_manager_is_refused():
    with pytest.raises(ConfigError) as info:
        read_ros2_controllers({"effort_controller": {"ros__parameters": {}}}, "c.yaml")
    assert "controller_manager" in str(info.value)


def test_the_manager_loads_a_ros2_file_with_overrides_and_names_their_fields(write_yaml):
    manager = ControllerManager(FakeHardware(("joint1", "joint2")), TWO_JOINTS)
    path = write_yaml(BASE)
    assert manager.load_file(path, {"effort_controller.joints": ["joint1", "joint2"]}) is None
    assert manager.update_rate_hz == 100 and manager.defined == ("joint_state_broadcaster", "effort_controller")
    assert manager.load("effort_controller").joints == ("joint1", "joint2")
    manager = ControllerManager(FakeHardware(("joint1", "joint2")), TWO_JOINTS)
    manager.load_file(path, {"effort_controller.joints": ["joint3"]})
    with pytest.raises(ConfigError) as info:
        manager.load("effort_controller")
    assert info.value.field == "effort_controller.ros__parameters.joints[0]" and info.value.value == "joint3"


def test_an_unknown_type_is_refused_where_the_manager_declares_it(write_yaml):
    manager = ControllerManager(FakeHardware(("joint1", "joint2")), TWO_JOINTS)
    manager.load_file(write_yaml(_set(f"{M}/effort_controller/type", "effort_controllers/JointGroupEfortController")))
    manager.load("joint_state_broadcaster")  # the others load
    with pytest.raises(ConfigError) as info:
        manager.load("effort_controller")
    assert info.value.field == "controller_manager.ros__parameters.effort_controller.type"


def test_an_integer_gain_set_by_jointctl_is_taken(write_yaml):
    # Refused in the file (ros2_control_node refuses it: "setting it to {integer} is not allowed"); a --set value
    # is jointctl's own.
    tree = copy.deepcopy(PID)
    tree["pid"]["ros__parameters"]["gains"]["joint1"]["p"] = 400.0
    tree["pid"]["ros__parameters"].update(command_interface="effort", reference_and_state_interfaces=["position"])
    manager = ControllerManager(FakeHardware(("joint1", "joint2")), TWO_JOINTS)
    manager.load_file(write_yaml(tree), {"pid.gains.joint1.p": 800})
    assert manager.load("pid").gains[0].p == 800.0

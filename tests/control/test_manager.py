"""Tests of ControllerManager: loading the chapter's files, refusals, claims, start order."""

from __future__ import annotations

from pathlib import Path

import pytest

from jointctl.control import (
    ControllerManager,
    JointPositionController,
    JointStateController,
    JointVelocityController,
)
from jointctl.control.manager import read_yaml, set_dotted
from jointctl.errors import ConfigError, ControllerError

from .conftest import NAMESPACE, POSITION_YAML, VELOCITY_YAML

JSC = "joint_state_controller"
POS = "joint1_position_controller"
VEL = "joint1_velocity_controller"
POSITION_TYPE = "effort_controllers/JointPositionController"


@pytest.fixture
def manager(hardware, robot) -> ControllerManager:
    return ControllerManager(hardware, robot)


@pytest.fixture
def both(manager) -> ControllerManager:
    """A manager holding both chapter files' definitions."""
    manager.load_file(POSITION_YAML)
    manager.load_file(VELOCITY_YAML)
    return manager


# -- loading the chapter's files ----------------------------------------------------------
@pytest.mark.parametrize(("path", "names", "cls"), [
    (POSITION_YAML, (JSC, POS), JointPositionController),
    (VELOCITY_YAML, (JSC, VEL), JointVelocityController),
])
def test_loads_the_chapter_files_unchanged(manager, path, names, cls) -> None:
    assert manager.load_file(path) == NAMESPACE
    assert manager.namespace == NAMESPACE
    assert manager.defined == names
    assert isinstance(manager.load(names[0]), JointStateController)
    c = manager.load(names[1])
    assert isinstance(c, cls)
    assert c.field == f"{NAMESPACE}.{names[1]}"
    assert c.source == str(path)
    assert manager.controller(names[1]) is c
    assert manager.load(names[1]) is c  # loading twice returns the same controller
    assert manager.active == ()


def test_a_file_without_the_namespace_level_loads(manager, write_yaml) -> None:
    path = write_yaml({
        JSC: {"type": "joint_state_controller/JointStateController", "publish_rate": 100},
        POS: {"type": POSITION_TYPE, "joint": "joint1", "pid": {"p": 250.0}},
    })
    assert manager.load_file(path) is None
    assert manager.namespace is None
    assert manager.defined == (JSC, POS)
    c = manager.load(POS)
    assert c.field == POS
    assert c.pid.gains.p == 250.0
    assert manager.load(JSC).publish_rate_hz == 100.0


def test_the_robot_namespace_is_chosen_among_several(manager, write_yaml) -> None:
    entry = {"type": POSITION_TYPE, "joint": "joint1", "pid": {"p": 1.0}}
    path = write_yaml({"other_robot": {"a": entry}, NAMESPACE: {"b": entry}})
    assert manager.load_file(path) == NAMESPACE
    assert manager.defined == ("b",)


def test_several_namespaces_none_the_robot_is_refused(manager, write_yaml) -> None:
    entry = {"type": POSITION_TYPE, "joint": "joint1"}
    path = write_yaml({"robot_a": {"a": entry}, "robot_b": {"b": entry}})
    with pytest.raises(ConfigError) as info:
        manager.load_file(path)
    assert info.value.source == str(path)
    assert "namespace" in info.value.message


# -- overrides --------------------------------------------------------------------------------
def test_overrides_apply(manager) -> None:
    manager.load_file(POSITION_YAML, {f"{POS}.pid.p": 800, f"{POS}.pid.d": 5.0,
                                      f"{JSC}.publish_rate": 100})
    c = manager.load(POS)
    assert (c.pid.gains.p, c.pid.gains.d) == (800.0, 5.0)
    assert manager.load(JSC).publish_rate_hz == 100.0


def test_overrides_do_not_leak_into_later_loads(hardware, robot) -> None:
    first = ControllerManager(hardware, robot)
    first.load_file(POSITION_YAML, {f"{POS}.pid.p": 800})
    second = ControllerManager(hardware, robot)
    second.load_file(POSITION_YAML)
    assert second.load(POS).pid.gains.p == 400.0
    assert read_yaml(POSITION_YAML)[NAMESPACE][POS]["pid"]["p"] == 400.0


def test_override_values_are_validated_like_the_file(manager) -> None:
    manager.load_file(POSITION_YAML, {f"{POS}.pid.p": -800})
    with pytest.raises(ConfigError) as info:
        manager.load(POS)
    assert info.value.field == f"{NAMESPACE}.{POS}.pid.p"
    assert info.value.value == -800


def test_override_naming_an_unknown_controller_is_refused(manager) -> None:
    with pytest.raises(ConfigError) as info:
        manager.load_file(POSITION_YAML, {"joint2_position_controller.pid.p": 800})
    err = info.value
    assert err.field == f"{NAMESPACE}.joint2_position_controller.pid.p"
    assert err.value == "joint2_position_controller"
    assert err.source == str(POSITION_YAML)
    assert POS in err.message  # lists the controllers there are
    assert manager.defined == ()  # nothing was defined from the refused file


def test_override_inside_a_non_mapping_is_refused(manager) -> None:
    with pytest.raises(ConfigError) as info:
        manager.load_file(POSITION_YAML, {f"{POS}.joint.name": "joint1"})
    assert info.value.field == f"{NAMESPACE}.{POS}.joint"
    assert info.value.value == "joint1"


def test_numbers_in_files_read_as_yaml_1_2(manager, tmp_path) -> None:
    """A controller file's ``p: 1e3`` is a number (PyYAML's YAML 1.1 alone reads a string)."""
    path = tmp_path / "gains.yaml"
    path.write_text(f"{NAMESPACE}:\n  {POS}:\n    type: {POSITION_TYPE}\n    joint: joint1\n"
                    "    pid: {p: 1e3, i: .5, d: 2.5E+1, i_clamp: 1_000}\n")
    assert read_yaml(path)[NAMESPACE][POS]["pid"] == {"p": 1000.0, "i": 0.5, "d": 25.0, "i_clamp": 1000}
    manager.load_file(path)
    gains = manager.load(POS).pid.gains
    assert (gains.p, gains.i, gains.d, gains.i_clamp_max) == (1000.0, 0.5, 25.0, 1000.0)


def test_quoted_numbers_in_files_stay_strings_and_are_refused(manager, tmp_path) -> None:
    path = tmp_path / "gains.yaml"
    path.write_text(f"{NAMESPACE}:\n  {POS}:\n    type: {POSITION_TYPE}\n    joint: joint1\n"
                    "    pid: {p: '1e3'}\n")
    manager.load_file(path)
    with pytest.raises(ConfigError) as info:
        manager.load(POS)
    assert info.value.field == f"{NAMESPACE}.{POS}.pid.p" and info.value.value == "1e3"
    assert "must be a number" in info.value.message


def test_set_dotted_creates_mappings() -> None:
    tree: dict = {"a": {"b": 1}}
    set_dotted(tree, "a.c.d", 2, source=None)
    set_dotted(tree, "a.b", 3, source=None)
    assert tree == {"a": {"b": 3, "c": {"d": 2}}}


# -- refusals ---------------------------------------------------------------------------------
def test_unknown_controller_type_is_refused(manager, write_yaml) -> None:
    path = write_yaml({NAMESPACE: {"mystery": {"type": "effort_controllers/JointEffortController",
                                               "joint": "joint1"}}})
    manager.load_file(path)
    with pytest.raises(ConfigError) as info:
        manager.load("mystery")
    err = info.value
    assert err.field == f"{NAMESPACE}.mystery.type"
    assert err.value == "effort_controllers/JointEffortController"
    assert err.source == str(path)
    assert POSITION_TYPE in err.message  # lists the known types
    assert "mystery" not in {c.name for c in manager.active}


def test_a_misspelt_joint_key_is_named_before_the_missing_joint(manager, write_yaml) -> None:
    path = write_yaml({NAMESPACE: {POS: {"type": POSITION_TYPE, "jont": "joint1", "pid": {"p": 400.0}}}})
    manager.load_file(path)
    with pytest.raises(ConfigError) as info:
        manager.start([POS])
    assert str(info.value) == (f"{path}: {NAMESPACE}.{POS}.jont: unknown field (did you mean 'joint'?) "
                               "(got 'joint1')")
    assert manager.active == ()


@pytest.mark.parametrize(("name", "entry", "typo", "message"), [
    (POS, {"type": POSITION_TYPE, "joint": "joint1", "feed_forward": {"gravity": True}}, "feed_forward",
     "unknown field (did you mean 'feedforward'? known: derivative, feedforward, joint, pid, type)"),
    (VEL, {"type": "effort_controllers/JointVelocityController", "joint": "joint1", "pid": {"p": 1.0},
           "command_timeout": 0.5}, "command_timeout",
     "unknown field (did you mean 'command_timeout_s'? known: command_timeout_s, joint, pid, type)"),
])
def test_unknown_keys_list_what_that_controller_accepts(manager, write_yaml, name, entry, typo, message) -> None:
    """The known keys are the controller's own: a position controller's include feedforward (and pid,
    given or not); a velocity controller's do not include feedforward."""
    path = write_yaml({NAMESPACE: {name: entry}})
    manager.load_file(path)
    with pytest.raises(ConfigError) as info:
        manager.start([name])
    assert info.value.field == f"{NAMESPACE}.{name}.{typo}"
    assert info.value.message == message
    assert manager.active == ()


@pytest.mark.parametrize("joint", ["joint7", "ft_sensor_jnt", "glue_robot_to_world"])
def test_controller_joint_not_movable_in_the_model_is_refused(manager, write_yaml, joint) -> None:
    path = write_yaml({NAMESPACE: {POS: {"type": POSITION_TYPE, "joint": joint,
                                         "pid": {"p": 400.0}}}})
    manager.load_file(path)
    with pytest.raises(ConfigError) as info:
        manager.start([POS])
    err = info.value
    assert err.field == f"{NAMESPACE}.{POS}.joint"
    assert err.value == joint
    assert err.source == str(path)
    assert manager.active == ()


def test_controller_entry_without_type_is_refused(manager, write_yaml) -> None:
    path = write_yaml({NAMESPACE: {
        JSC: {"type": "joint_state_controller/JointStateController"},
        POS: {"joint": "joint1", "pid": {"p": 400.0}},
    }})
    with pytest.raises(ConfigError) as info:
        manager.load_file(path)
    assert info.value.field == f"{NAMESPACE}.{POS}"
    assert info.value.source == str(path)
    assert "type" in info.value.message
    assert manager.defined == ()


def test_controller_entry_that_is_not_a_mapping_is_refused(manager, write_yaml) -> None:
    path = write_yaml({NAMESPACE: {JSC: {"type": "joint_state_controller/JointStateController"},
                                   POS: POSITION_TYPE}})
    with pytest.raises(ConfigError) as info:
        manager.load_file(path)
    assert info.value.field == f"{NAMESPACE}.{POS}"
    assert info.value.value == POSITION_TYPE


@pytest.mark.parametrize("text", ["- joint_state_controller\n- joint1_position_controller\n",
                                  "just a string\n", "42\n", "", "{}\n"])
def test_a_yaml_that_is_not_a_mapping_of_controllers_is_refused(manager, write_yaml, text) -> None:
    path = write_yaml(text)
    with pytest.raises(ConfigError) as info:
        manager.load_file(path)
    assert info.value.source == str(path)
    assert "mapping" in info.value.message


def test_malformed_yaml_is_refused_with_the_line(manager, write_yaml) -> None:
    path = write_yaml(f"{NAMESPACE}:\n"
                      f"  {POS}:\n"
                      f"    type: {POSITION_TYPE}\n"
                      "    pid: {p: 400.0, i: 0.0\n"
                      "    joint: joint1\n")
    with pytest.raises(ConfigError) as info:
        manager.load_file(path)
    err = info.value
    assert err.source == str(path)
    assert "not valid YAML" in err.message
    assert "line 5" in err.message
    assert str(path) in str(err)


def test_a_missing_file_is_refused(manager, tmp_path: Path) -> None:
    path = tmp_path / "nowhere" / "controllers.yaml"
    with pytest.raises(ConfigError) as info:
        manager.load_file(path)
    assert info.value.source == str(path)
    assert "not found" in info.value.message


def test_loading_an_undefined_controller_is_refused(manager) -> None:
    manager.load_file(POSITION_YAML)
    with pytest.raises(ControllerError) as info:
        manager.load(VEL)
    assert info.value.value == VEL
    assert POS in info.value.message
    with pytest.raises(ControllerError) as info:
        manager.start([JSC, VEL])
    assert manager.active == ()
    with pytest.raises(ControllerError):
        manager.controller(POS)  # defined but not loaded


# -- claims, start and stop --------------------------------------------------------------------
def test_both_files_define_three_controllers(both) -> None:
    assert set(both.defined) == {JSC, POS, VEL}


def test_starting_position_and_velocity_for_joint1_is_refused(both, hardware) -> None:
    both.start([JSC, POS])
    with pytest.raises(ControllerError) as info:
        both.start([VEL])
    err = info.value
    assert "'joint1'" in err.message and f"'{POS}'" in err.message
    assert err.value == VEL
    assert [c.name for c in both.active] == [JSC, POS]
    assert both.commanding("joint1") is both.controller(POS)


def test_refused_start_starts_nothing(both, hardware) -> None:
    published = []
    both.load(JSC).subscribe(published.append)
    with pytest.raises(ControllerError) as info:
        both.start([JSC, POS, VEL])
    assert "'joint1'" in info.value.message
    assert POS in info.value.message and info.value.value == VEL
    assert both.active == ()
    assert both.update_calls == ()
    assert hardware.reads == 0  # the position controller's start() never ran
    both.update(0.0, 0.001)
    assert published == []
    assert both.commanding("joint1") is None


def test_refused_start_keeps_what_was_running(both) -> None:
    both.start([JSC])
    with pytest.raises(ControllerError):
        both.start([POS, VEL])
    assert [c.name for c in both.active] == [JSC]


def test_stop_then_start_the_other_works(both, hardware) -> None:
    both.start([JSC, POS])
    both.stop([POS])
    assert [c.name for c in both.active] == [JSC]
    assert both.commanding("joint1") is None
    both.start([VEL])
    assert [c.name for c in both.active] == [JSC, VEL]
    vel = both.commanding("joint1")
    assert vel is both.controller(VEL)
    hardware.set_state("joint1", -0.5, 0.25)
    vel.set_reference(1.0)
    both.update(0.0, 0.001)
    assert hardware.command_buffer("effort")[0] == pytest.approx(200.0 * 0.75)


def test_stop_calls_stop_and_drops_the_update(both) -> None:
    both.start([JSC, POS])
    pos = both.controller(POS)
    stopped = []
    pos.stop = lambda t: stopped.append(t)  # type: ignore[method-assign]
    both.stop([POS], time_s=1.5)
    assert stopped == [1.5]
    assert len(both.update_calls) == 1
    both.stop([POS, "never_loaded"])  # stopping what is not running is a no-op
    assert stopped == [1.5]


def test_starting_a_running_controller_again_does_not_restart_it(both, hardware) -> None:
    both.start([POS])
    pos = both.controller(POS)
    pos.set_reference(-0.8)
    both.start([POS])
    assert pos.reference_input == (-0.8, 0.0, 0.0)  # not reset to "hold where it is"
    assert [c.name for c in both.active] == [POS]


def test_a_name_listed_twice_starts_once(both) -> None:
    both.start([POS, POS])
    assert [c.name for c in both.active] == [POS]


def _record_updates(manager: ControllerManager, names: list[str], log: list) -> None:
    for name in names:
        c = manager.load(name)
        c.update = lambda t, dt, n=name: log.append((n, t))  # type: ignore[method-assign]


def test_update_order_follows_start_order(both) -> None:
    log: list = []
    _record_updates(both, [JSC, POS, VEL], log)
    both.start([POS])
    both.start([JSC])
    both.update(0.5, 0.001)
    assert log == [(POS, 0.5), (JSC, 0.5)]
    assert both.update_calls == tuple(c.update for c in both.active)
    log.clear()
    both.stop([POS])
    both.start([VEL])
    both.update(0.6, 0.001)
    assert log == [(JSC, 0.6), (VEL, 0.6)]


def test_update_order_within_one_start_call_follows_the_list(both) -> None:
    log: list = []
    _record_updates(both, [JSC, POS], log)
    both.start([POS, JSC])
    both.update(0.0, 0.001)
    assert [n for n, _ in log] == [POS, JSC]


def test_start_passes_the_time(both) -> None:
    both.start([JSC], time_s=0.5)
    jsc = both.controller(JSC)
    both.update(0.5, 0.001)
    assert jsc.published == 1 and jsc.latest.time_s == 0.5


def test_commanding(both) -> None:
    assert both.commanding("joint1") is None
    both.start([JSC])
    assert both.commanding("joint1") is None  # the broadcaster commands nothing
    both.start([POS])
    assert both.commanding("joint1") is both.controller(POS)
    assert both.commanding("ft_sensor_jnt") is None


# -- the real stack --------------------------------------------------------------------------
def test_position_control_of_the_mujoco_piston(robot) -> None:
    """The chapter's position controller holds the piston at -0.5 m against gravity.

    With p = 400 N/m and no i term the piston (link2 1 kg + disk 0.01 kg) settles
    m*g/p below the reference, pushing with m*g.
    """
    from jointctl.hardware import MujocoHardware
    from jointctl.sim import MujocoWorld

    world = MujocoWorld(robot, initial_positions={"joint1": -0.2})
    hw = MujocoHardware(world)
    manager = ControllerManager(hw, robot)
    manager.load_file(POSITION_YAML)
    manager.start([JSC, POS])
    pos = manager.commanding("joint1")
    assert pos.reference_input == (pytest.approx(-0.2), 0.0, 0.0)  # holds where it starts
    samples = []
    manager.controller(JSC).subscribe(samples.append)
    pos.set_reference(-0.5)
    period = 0.001
    for k in range(3000):
        hw.read()
        manager.update(k * period, period)
        hw.write()
        hw.advance(period)
    hw.read()
    weight = 1.01 * 9.81
    assert hw.position[0] == pytest.approx(-0.5 - weight / 400.0, abs=1e-4)
    assert hw.velocity[0] == pytest.approx(0.0, abs=1e-3)
    assert hw.effort[0] == pytest.approx(weight, rel=1e-3)
    assert len(samples) == 150  # 50 Hz for 3 s
    assert samples[0].position == (pytest.approx(-0.2),)
    assert samples[-1].name == ("joint1",)


def test_the_registry_lists_every_type_once_and_refuses_a_plugin_taking_a_built_in_name():
    from jointctl.control.registry import BUILTIN_TYPES, controller_types, register_controller
    from jointctl.trajectory.executor import TrajectoryExecutor

    types = controller_types()
    assert types["trajectory_controllers/JointTrajectoryExecutor"] is TrajectoryExecutor  # imported on first use
    assert set(BUILTIN_TYPES) <= set(types)
    with pytest.raises(ValueError, match="built-in"):
        register_controller("effort_controllers/JointPositionController")(TrajectoryExecutor)


def test_the_feed_forward_computes_inertia_only_while_a_running_controller_reads_it():
    from jointctl.model import load_robot_model
    from tests.control.conftest import ONE_DOF_XACRO, FakeHardware

    manager = ControllerManager(FakeHardware(), load_robot_model(ONE_DOF_XACRO))
    manager.load_file(ONE_DOF_XACRO.parents[1] / "config" / "one_dof_traj_params.yaml")
    manager.start(["joint1_position_controller"])  # feedforward: gravity, damping, inertia
    assert manager.context.feedforward.wants_inertia
    manager.stop(["joint1_position_controller"])
    assert not manager.context.feedforward.wants_inertia  # nothing running reads it any more


def test_a_file_read_again_is_parsed_again_when_edited_and_each_reader_gets_its_own_copy(tmp_path):
    # read_yaml keeps the texts it parsed (a sweep reads the same files for every run): an edit of the same size
    # within the file system's time resolution is still read, and what one caller changes no other sees.
    path = tmp_path / "gains.yaml"
    path.write_text("pid: {p: 400.0, d: 1.0}\n")
    first = read_yaml(path)
    first["pid"]["p"] = -1.0
    assert read_yaml(path) == {"pid": {"p": 400.0, "d": 1.0}}
    path.write_text("pid: {p: 500.0, d: 1.0}\n")
    assert read_yaml(path) == {"pid": {"p": 500.0, "d": 1.0}}

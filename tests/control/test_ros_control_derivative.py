"""The position controller's derivative law against ros_controllers' (see
/work/shared/reference/ros-control-facts.md, from effort_controllers/src/joint_position_controller.cpp
and control_toolbox/src/pid.cpp): with ``derivative: error`` (the default) a plain position command
gives ``p·e + d·(e - e_last)/dt`` with ``error_dot`` 0 on the first call after start (a step of Δ:
one cycle of ``d·Δ/dt``, then the difference of ``-q``); a reference with a velocity gives
``p·e + d·(v_ref - v)``. ``derivative: measurement`` (jointctl's law) gives ``p·e + d·(v_ref - v)``
always. The expected numbers are computed here from those formulas, never from the controller."""

from __future__ import annotations

import pytest

from jointctl.control import controller_types
from jointctl.control.manager import ControllerManager
from jointctl.control.params import Params
from jointctl.errors import ConfigError
from jointctl.hardware.interface import EFFORT

from .conftest import NAMESPACE, robots_dir

DT = 0.001
P, D = 400.0, 20.0
POSITION_TYPE = "effort_controllers/JointPositionController"


def controller(hardware, robot, **extra):
    definition = {"type": POSITION_TYPE, "joint": "joint1", "pid": {"p": P, "d": D}, **extra}
    c = controller_types()[POSITION_TYPE]("ctl", Params(definition, source="t.yaml", field=f"{NAMESPACE}.ctl"))
    c.configure(hardware, robot)
    return c


def effort(hardware) -> float:
    return hardware.command_buffer(EFFORT)[0]


def test_the_ros_control_type_runs_ros_controls_law_by_default(hardware, robot) -> None:
    assert controller(hardware, robot).derivative == "error"


def test_a_plain_step_gives_one_cycle_of_derivative_kick_then_minus_d_velocity(hardware, robot) -> None:
    c = controller(hardware, robot)
    hardware.set_state("joint1", -0.2, 0.3)
    c.start(0.0)  # holds -0.2: the first call's error_dot is 0 whatever the velocity
    c.update(0.0, DT)
    assert effort(hardware) == pytest.approx(0.0, abs=1e-12)
    step = -0.01
    c.set_reference(-0.2 + step)  # a step of Δ = -0.01 m on the command topic
    c.update(DT, DT)
    e1 = step  # the joint has not moved
    assert effort(hardware) == pytest.approx(P * e1 + D * (e1 - 0.0) / DT)  # -4 - 200: the kick
    hardware.set_state("joint1", -0.2 - 0.0004, -0.4)  # it moved 0.4 mm at -0.4 m/s
    c.update(2 * DT, DT)
    e2 = -0.2 + step - (-0.2 - 0.0004)
    assert effort(hardware) == pytest.approx(P * e2 + D * (e2 - e1) / DT)  # -d·Δq/dt = -d·0.4 m/s
    assert D * (e2 - e1) / DT == pytest.approx(-D * -0.4)


def test_a_reference_with_a_velocity_acts_on_the_velocity_error(hardware, robot) -> None:
    c = controller(hardware, robot)
    hardware.set_state("joint1", -0.2, 0.1)
    c.start(0.0)
    c.set_reference(-0.25, 0.3)  # setCommand(pos, vel): no kick, d·(v_ref - v)
    c.update(0.0, DT)
    assert effort(hardware) == pytest.approx(P * -0.05 + D * (0.3 - 0.1))
    c.set_reference(-0.35, 0.0)  # a velocity of 0 is a velocity: d·(0 - v)
    c.update(DT, DT)
    assert effort(hardware) == pytest.approx(P * -0.15 + D * (0.0 - 0.1))


def test_a_chained_executor_reference_carries_its_velocity(hardware, robot) -> None:
    c = controller(hardware, robot)
    hardware.set_state("joint1", -0.2, 0.1)
    c.start(0.0)
    c.upstream = "executor"  # chained: the executor writes the reference interfaces
    c.context.reference_positions[c.index], c.context.reference_velocities[c.index] = -0.3, 0.2
    c.update(0.0, DT)
    assert effort(hardware) == pytest.approx(P * -0.1 + D * (0.2 - 0.1))


def test_derivative_on_measurement_keeps_jointctls_law(hardware, robot) -> None:
    c = controller(hardware, robot, derivative="measurement")
    hardware.set_state("joint1", -0.2, 0.3)
    c.start(0.0)
    c.set_reference(-0.21)
    c.update(0.0, DT)
    assert effort(hardware) == pytest.approx(P * -0.01 - D * 0.3)  # no kick: -d·q̇
    c.set_reference(-0.25, 0.5)
    c.update(DT, DT)
    assert effort(hardware) == pytest.approx(P * -0.05 + D * (0.5 - 0.3))


def test_start_forgets_the_last_error(hardware, robot) -> None:
    c = controller(hardware, robot)
    hardware.set_state("joint1", -0.2)
    c.start(0.0)
    c.set_reference(-0.3)
    c.update(0.0, DT)  # first call: error_dot 0
    assert effort(hardware) == pytest.approx(P * -0.1)
    c.start(DT)  # holds where it is again: the last error is forgotten (Pid::reset)
    c.set_reference(-0.3)
    c.update(DT, DT)
    assert effort(hardware) == pytest.approx(P * -0.1)


def test_an_unknown_derivative_law_is_refused(hardware, robot) -> None:
    with pytest.raises(ConfigError) as info:
        controller(hardware, robot, derivative="setpoint")
    assert info.value.field.endswith(".derivative")


@pytest.mark.parametrize(("robot_name", "file_name", "law"), [
    ("minimal_robot", "minimal_robot_pos_ctl_params.yaml", "measurement"),  # the book's -Kv·q̇
    ("one_dof", "one_dof_pos_ctl_params.yaml", "error"),
])
def test_built_in_files_say_their_law(hardware, robot, robot_name, file_name, law) -> None:
    import yaml

    document = yaml.safe_load((robots_dir() / robot_name / "config" / file_name).read_text())
    (entries,) = document.values()
    laws = {e.get("derivative", "error") for e in entries.values() if e.get("type") == POSITION_TYPE}
    assert laws == {law}

"""The book's minimal_joint_controller as jointctl's position controller on a continuous joint.

The book's law is ``τ = Kp·err - Kv·q̇`` with ``err = command - q`` wrapped to (-π, π]. jointctl's
JointPositionController computes ``p·err + d·(velocity reference - q̇)``: with no velocity
reference (a position command, or an executor without velocity feed-forward) that is the book's
law exactly, derivative on measurement; on a continuous joint it wraps ``err``. Checked here on a
fake hardware (no physics), cycle by cycle, to rounding.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from jointctl.control.joint_controllers import JointPositionController, wrap_angle
from jointctl.control.manager import ControllerManager
from jointctl.hardware.interface import EFFORT
from jointctl.model import load_robot_model
from jointctl.model.robot_model import Joint, JointLimits, Link, RobotModel
from jointctl.paths import robots_dir
from jointctl.trajectory.executor import GoalStatus
from jointctl.trajectory.messages import JointTrajectory

from .conftest import FakeHardware

MINIMAL = robots_dir() / "minimal_robot"
KP, KV = 10.0, 3.0  # the book's minimal_joint_controller
DT = 0.001
POSITION_TYPE = "effort_controllers/JointPositionController"


@pytest.fixture(scope="module")
def minimal_robot() -> RobotModel:
    return load_robot_model(MINIMAL / "urdf" / "minimal_robot.xacro")


def manager_for(robot: RobotModel, controllers: str,
                overrides: dict | None = None) -> tuple[ControllerManager, FakeHardware]:
    """A manager over a fake joint1 with every controller of the robot's ``controllers`` file started."""
    files = yaml.safe_load((MINIMAL / "robot.yaml").read_text())["controllers"]
    path = MINIMAL / files[controllers]
    hardware = FakeHardware(("joint1",))
    manager = ControllerManager(hardware, robot)
    manager.load_file(path, overrides)
    names = list(yaml.safe_load(Path(path).read_text())["one_DOF_robot"])
    for name in names:
        manager.load(name)
    manager.start(names)
    return manager, hardware


def book_law(command: float, q: float, qdot: float) -> float:
    """The book's minimal_joint_controller: Kp·min_periodicity(command - q) - Kv·q̇ [N·m]."""
    err = command - q
    while err > math.pi:
        err -= 2 * math.pi
    while err <= -math.pi:  # the book's loop stops at -π; (-π, π] here, as ros_control's
        err += 2 * math.pi
    return KP * err - KV * qdot


# -- wrapping ---------------------------------------------------------------------------------

@pytest.mark.parametrize(("angle", "wrapped"), [
    (0.0, 0.0), (1.0, 1.0), (math.pi, math.pi), (-math.pi, math.pi), (3 * math.pi, math.pi),
    (6.0, 6.0 - 2 * math.pi), (-6.0, 2 * math.pi - 6.0), (4 * math.pi + 0.5, 0.5),
    (-100.0, -100.0 + 32 * math.pi),
])
def test_wrap_angle(angle, wrapped):
    assert wrap_angle(angle) == pytest.approx(wrapped, abs=1e-12)


@given(st.floats(min_value=-1e4, max_value=1e4, allow_nan=False))
def test_wrap_angle_lands_in_the_half_open_turn_and_keeps_the_direction(angle):
    wrapped = wrap_angle(angle)
    assert -math.pi < wrapped <= math.pi
    turns = (angle - wrapped) / (2 * math.pi)
    assert turns == pytest.approx(round(turns), abs=1e-9)


def wheel(joint_type: str) -> RobotModel:
    limits = JointLimits(-10.0, 10.0, 0.0, 0.0) if joint_type == "revolute" else None
    return RobotModel(name="wheel_bot", links=(Link("base"), Link("wheel")),
                      joints=(Joint("wheel", joint_type, "base", "wheel", axis=(0.0, 1.0, 0.0), limits=limits),))


def controller_on(joint_type: str, hardware: FakeHardware) -> JointPositionController:
    from jointctl.control.params import Params

    params = Params({"type": POSITION_TYPE, "joint": "wheel", "pid": {"p": KP, "d": KV},
                     "derivative": "measurement"}, source="t.yaml",  # the book's law, as its YAML says
                    field="c")
    c = JointPositionController("c", params)
    c.configure(hardware, wheel(joint_type))
    return c


@pytest.mark.parametrize(("command", "position", "error"), [
    (3.0, -3.0, 6.0 - 2 * math.pi),           # the short way round: 0.28 rad backwards
    (math.pi + 0.1, 0.0, 0.1 - math.pi),
    (0.0, 7.0, 2 * math.pi - 7.0),            # a joint that has turned more than once
    (0.5, 0.5 - math.pi, math.pi),            # exactly half a turn: +π
    (0.5, 0.5 + math.pi, math.pi),
    (0.2, -0.1, 0.3),                         # within half a turn: as it is
])
def test_a_continuous_joint_servos_the_wrapped_error(command, position, error):
    hw = FakeHardware(("wheel",))
    c = controller_on("continuous", hw)
    hw.set_state("wheel", position, 0.4)
    c.set_reference(command)
    c.update(0.0, DT)
    assert hw.command_buffer(EFFORT)[0] == pytest.approx(KP * error - KV * 0.4, abs=1e-12)
    assert c.reference == command  # the reference stays the command as given


def test_a_revolute_joint_does_not_wrap():
    hw = FakeHardware(("wheel",))
    c = controller_on("revolute", hw)
    hw.set_state("wheel", -3.0)
    c.set_reference(3.0)
    c.update(0.0, DT)
    assert hw.command_buffer(EFFORT)[0] == pytest.approx(KP * 6.0)


# -- the minimal robot's files ----------------------------------------------------------------

def test_the_position_file_is_the_books_law_on_a_streamed_command(minimal_robot):
    manager, hw = manager_for(minimal_robot, "position")
    controller = manager.controller("joint1_position_controller")
    assert controller.continuous
    assert (controller.pid.gains.p, controller.pid.gains.i, controller.pid.gains.d) == (KP, 0.0, KV)
    assert controller.effort_limit == math.inf  # no <limit>: the book never saturates its torque
    states = [(0.0, 0.0, 0.0), (0.5, 0.047, 0.0), (0.5, 0.3, 1.2), (-2.0, 2.5, -0.7), (3.0, -3.1, 0.1),
              (12.0, 0.1, 0.0), (0.412, 0.8716, 0.0)]
    for k, (command, q, qdot) in enumerate(states):
        hw.set_state("joint1", q, qdot)
        controller.set_reference(command)  # what /pos_cmd does: a position only
        manager.update(k * DT, DT)
        assert hw.command_buffer(EFFORT)[0] == pytest.approx(book_law(command, q, qdot), rel=1e-12, abs=1e-12)


def test_the_trajectory_file_streams_linear_positions_at_100_hz_into_the_books_law(minimal_robot):
    # The book's law is the file's without the gravity feed-forward jointctl adds (as the scenario runs it).
    manager, hw = manager_for(minimal_robot, "trajectory",
                              {"joint1_position_controller.feedforward.gravity": False})
    executor = manager.controller("joint1_trajectory_controller")
    assert (executor.interpolation, executor.stream_rate_hz, executor.velocity_feedforward) == ("linear", 100.0, False)
    goal = JointTrajectory.from_dict(yaml.safe_load((MINIMAL / "goals" / "example_trajectory_client.yaml").read_text()))
    times = [p.time_from_start_s for p in goal.points]
    positions = [p.positions[0] for p in goal.points]
    manager.update(0.0, DT)  # holding where it started: 0 rad
    start = DT
    handle = executor.submit(goal, now_s=start)
    references, k = [], 1
    while not handle.done:
        t = k * DT
        # Any joint state: the law must hold whatever the joint does.
        q, qdot = 0.3 * math.sin(1.3 * t) + 0.4, 0.39 * math.cos(1.3 * t)
        hw.set_state("joint1", q, qdot)
        manager.update(t, DT)
        reference = manager.references[0]
        assert hw.command_buffer(EFFORT)[0] == pytest.approx(book_law(reference, q, qdot), rel=1e-12, abs=1e-12)
        references.append((t, reference))
        k += 1
    assert handle.result.status is GoalStatus.SUCCEEDED
    # In loop time: updated every 10 ms from the cycle the goal starts (held in between), on the
    # straight lines from the last cycle's reference (the hold at 0 rad, at loop time 0) through
    # the client's points (0.1 s and later after the goal's arrival); the last point exactly.
    knots_t, knots_q = [0.0, *(start + tk for tk in times)], [0.0, *positions]
    for cycle, (t, reference) in enumerate(references):
        streamed_at = start + (cycle // 10) * 0.010
        expected = _linear(knots_t, knots_q, streamed_at)
        assert reference == pytest.approx(expected, abs=1e-9), t
    assert references[-1][1] == positions[-1]
    assert len({r for _, r in references[:-1]}) == pytest.approx(len(references) / 10, abs=1)


def _linear(knots_t, knots_q, t):
    if t >= knots_t[-1]:
        return knots_q[-1]
    k = max(i for i in range(len(knots_t)) if knots_t[i] <= t)
    f = (t - knots_t[k]) / (knots_t[k + 1] - knots_t[k])
    return knots_q[k] + f * (knots_q[k + 1] - knots_q[k])

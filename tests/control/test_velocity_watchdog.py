"""The command watchdog of effort_controllers/JointVelocityController (``command_timeout_s``)."""

from __future__ import annotations

import pytest

from jointctl.errors import ConfigError

from .test_joint_controllers import VELOCITY_TYPE, build

DT = 0.001


def controller(hardware, robot, **extra):
    c = build({"type": VELOCITY_TYPE, "joint": "joint1", "pid": {"p": 200.0}, **extra}, hardware, robot)
    c.start(0.0)
    return c


def step(c, hardware, t0: float, seconds: float) -> float:
    """Run closed loop for ``seconds`` from loop time ``t0``; returns the loop time reached."""
    t = t0
    for _ in range(round(seconds / DT)):
        t += DT
        c.update(t, DT)
        hardware.write()
        hardware.advance(DT)
    return t


def test_without_a_timeout_an_old_command_is_kept_as_ros_control_does(hardware, robot):
    c = controller(hardware, robot)
    assert c.command_timeout_s is None
    c.set_reference(0.1)
    step(c, hardware, 0.0, 2.0)
    assert c.reference == pytest.approx(0.1)
    assert hardware.velocity[0] == pytest.approx(0.1, abs=1e-3)
    assert not c.timed_out


def test_a_stale_command_is_replaced_by_zero_velocity(hardware, robot):
    c = controller(hardware, robot, command_timeout_s=0.2)
    c.set_reference(0.1)
    t = step(c, hardware, 0.0, 0.15)
    assert c.reference == pytest.approx(0.1) and not c.timed_out
    t = step(c, hardware, t, 0.1)  # 0.25 s after the command: past the timeout
    assert c.timed_out and c.reference == 0.0
    t = step(c, hardware, t, 0.5)
    assert hardware.velocity[0] == pytest.approx(0.0, abs=1e-3)  # held
    assert c.reference_input == pytest.approx(0.1)  # the last command is still visible, just not applied


def test_a_new_command_restarts_motion_and_the_timer(hardware, robot):
    c = controller(hardware, robot, command_timeout_s=0.2)
    c.set_reference(0.1)
    t = step(c, hardware, 0.0, 0.5)
    assert c.timed_out
    c.set_reference(-0.05)
    t = step(c, hardware, t, 0.001)
    assert not c.timed_out and c.reference == pytest.approx(-0.05)
    t = step(c, hardware, t, 0.15)
    assert c.reference == pytest.approx(-0.05)
    step(c, hardware, t, 0.1)
    assert c.timed_out and c.reference == 0.0


def test_a_stream_of_commands_never_times_out(hardware, robot):
    c = controller(hardware, robot, command_timeout_s=0.2)
    t = 0.0
    for _ in range(40):  # 20 Hz for 2 s: each command younger than the timeout
        c.set_reference(0.1)
        t = step(c, hardware, t, 0.05)
        assert not c.timed_out
    assert hardware.velocity[0] == pytest.approx(0.1, abs=1e-3)


def test_the_same_value_sent_again_counts_as_a_new_command(hardware, robot):
    c = controller(hardware, robot, command_timeout_s=0.2)
    c.set_reference(0.1)
    t = step(c, hardware, 0.0, 0.19)
    c.set_reference(0.1)
    step(c, hardware, t, 0.19)
    assert not c.timed_out


def test_age_counts_in_loop_time_from_start(hardware, robot):
    c = build({"type": VELOCITY_TYPE, "joint": "joint1", "pid": {"p": 200.0}, "command_timeout_s": 0.2},
              hardware, robot)
    c.start(10.0)  # started late in loop time: no command yet, zero anyway
    c.update(10.1, DT)
    assert not c.timed_out
    c.update(10.3, DT)
    assert c.timed_out and c.reference == 0.0


def test_a_refused_command_does_not_refresh_the_watchdog(hardware, robot):
    c = controller(hardware, robot, command_timeout_s=0.2)
    c.set_reference(0.1)
    t = step(c, hardware, 0.0, 0.15)
    with pytest.raises(Exception):
        c.set_reference(float("nan"))
    step(c, hardware, t, 0.1)
    assert c.timed_out


@pytest.mark.parametrize("bad", [0, -0.1, "0.2", True, float("nan"), float("inf")])
def test_bad_timeouts_are_refused(hardware, robot, bad):
    with pytest.raises(ConfigError, match="command_timeout_s"):
        build({"type": VELOCITY_TYPE, "joint": "joint1", "pid": {"p": 1.0}, "command_timeout_s": bad},
              hardware, robot)


def test_the_timeout_is_only_a_velocity_controller_parameter(hardware, robot):
    with pytest.raises(ConfigError, match="command_timeout_s"):
        build({"type": "effort_controllers/JointPositionController", "joint": "joint1", "pid": {"p": 1.0},
               "command_timeout_s": 0.2}, hardware, robot)

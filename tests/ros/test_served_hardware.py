"""The served robot's joint states as jointctl hardware sees them (messages handed in directly; the
whole path over a real graph is tests/ros/test_served_tools.py)."""

from __future__ import annotations

import time

import pytest
import rospy
from sensor_msgs.msg import JointState

from jointctl.errors import JointCtlError
from jointctl.hardware.interface import POSITION
from jointctl.ros.served_hardware import ServedRobotHardware


def state(stamp_s: float, names, position, velocity=None, effort=None) -> JointState:
    msg = JointState(name=list(names), position=list(position), velocity=list(velocity or []),
                     effort=list(effort or []))
    msg.header.stamp = rospy.Time.from_sec(stamp_s)
    return msg


@pytest.fixture
def hardware():
    return ServedRobotHardware("arm", ["a", "b"], {"b": (POSITION, "b_position_controller")})


def test_states_in_another_order_are_read_by_name_and_recorded_whole(hardware) -> None:
    assert hardware.fault == "no joint state yet"
    hardware.start_recording()
    for k in range(3):
        hardware._on_state(state(10 + k / 1000, ["b", "x", "a"], [k, 9.0, -k], [1.0, 0.0, 2.0], [5.0, 0.0, 6.0]))
    hardware.read()
    assert hardware.position == [-2.0, 2.0] and hardware.velocity == [2.0, 1.0] and hardware.effort == [6.0, 5.0]
    assert hardware.fault is None
    stamps, q, qd, u = hardware.recorded("b")
    assert stamps == pytest.approx([10.0, 10.001, 10.002]) and q == [0, 1, 2] and qd == [1.0] * 3 and u == [5.0] * 3
    assert hardware.recorded("b") == ([], [], [], [])  # recording stopped
    assert hardware.command_interfaces("b") == {POSITION} and hardware.command_interfaces("a") == frozenset()


def test_states_without_efforts_cannot_identify_and_stale_ones_are_a_fault(hardware) -> None:
    hardware.start_recording()
    hardware._on_state(state(1.0, ["a", "b"], [0.0, 0.1], [0.0, 0.0]))
    with pytest.raises(JointCtlError, match="carry no effort") as info:
        hardware.recorded("b")
    assert info.value.field == "/arm/joint_states"
    hardware.stale_after_s = 0.05
    time.sleep(0.1)
    hardware.read()
    assert hardware.fault is not None and "no joint state on /arm/joint_states for" in hardware.fault


def test_states_that_do_not_name_every_joint_are_refused_naming_them() -> None:
    hardware = ServedRobotHardware("arm", ["a", "b"], {})
    hardware._on_state(state(1.0, ["a", "c"], [0.0, 0.0]))
    with pytest.raises(JointCtlError, match="name a, c, not every joint of the robot"):
        hardware.wait_for_state(timeout_s=0.1)

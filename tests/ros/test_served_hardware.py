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


class RecordingPublisher:
    """What rospy.Publisher is to ServedRobotHardware.write: the messages published, in order, per
    topic (what the served node's command subscriber would receive, each one)."""

    sent: list[tuple[str, float]] = []

    def __init__(self, name, data_class, **_):
        self.resolved_name = name

    def publish(self, msg) -> None:
        RecordingPublisher.sent.append((self.resolved_name, msg.data))

    def get_num_connections(self) -> int:
        return 1

    def unregister(self) -> None:
        pass


def test_write_publishes_each_loops_reference_when_it_changes_and_only_then(monkeypatch) -> None:
    from jointctl.hardware.interface import VELOCITY

    monkeypatch.setattr(rospy, "Publisher", RecordingPublisher)
    monkeypatch.setattr(RecordingPublisher, "sent", [])
    # Three joints: the first not commanded, the second a velocity loop, the third a position loop
    # (so a wrong index or interface shows).
    hardware = ServedRobotHardware("arm", ["a", "b", "c"], {"c": (POSITION, "c_pos"), "b": (VELOCITY, "b_vel")})
    position, velocity = hardware.command_buffer(POSITION), hardware.command_buffer(VELOCITY)
    sent = RecordingPublisher.sent
    c_topic, b_topic = "/arm/c_pos/command", "/arm/b_vel/command"

    def cycle() -> list[tuple[str, float]]:
        """One write(); what it published."""
        before = len(sent)
        hardware.write()
        return sorted(sent[before:])

    position[2], velocity[1] = -0.3, 0.0
    assert cycle() == sorted([(c_topic, -0.3), (b_topic, 0.0)])  # the first write sends every reference
    assert cycle() == []  # nothing changed: nothing sent
    position[2] = -0.25
    assert cycle() == [(c_topic, -0.25)]  # the buffer written in place after construction is read
    assert cycle() == []
    velocity[1] = 0.1
    position[0] = velocity[2] = 9.0  # other joints' entries and another interface's: not these loops'
    assert cycle() == [(b_topic, 0.1)]
    position[2] = -0.3  # back to a value sent before: a change from the last one sent
    velocity[1] = 0.2
    assert cycle() == sorted([(c_topic, -0.3), (b_topic, 0.2)])
    for _ in range(3):
        assert cycle() == []
    position[2] = -0.2
    position[2] = -0.1  # changed twice between cycles: the latest is what goes out
    assert cycle() == [(c_topic, -0.1)]

"""The joint states a served robot's hardware takes (jointctl.hardware.joint_state_inbox), as sensor_msgs/JointState
publishers send them: joints in any order, velocity or effort left out (empty arrays) or NaN for an interface a
joint lacks (ros2_control's joint_state_broadcaster), stale publishers."""

from __future__ import annotations

import math

import pytest

from jointctl.errors import JointCtlError
from jointctl.hardware.joint_state_inbox import JointStateInbox

JOINTS = ("shoulder", "elbow")


def lists() -> tuple[list[float], list[float], list[float]]:
    return [9.0, 9.0], [9.0, 9.0], [9.0, 9.0]


def test_a_state_naming_the_joints_in_another_order_reads_in_the_hardwares_order():
    inbox = JointStateInbox(JOINTS, "/arm/joint_states")
    position, velocity, effort = lists()
    assert inbox.read_into(position, velocity, effort, 0.5) == "no joint state yet"
    assert position == [9.0, 9.0] and not inbox.complete()
    inbox.take(["gripper", "elbow", "shoulder"], 1.0, [0.5, 0.2, 0.1], [0.0, 2.0, 1.0], [7.0, 20.0, 10.0])
    assert inbox.complete()
    assert inbox.read_into(position, velocity, effort, 0.5) is None
    assert (position, velocity, effort) == ([0.1, 0.2], [1.0, 2.0], [10.0, 20.0])
    assert inbox.effort_of(1) == 20.0


def test_left_out_values_keep_the_last_and_nan_reads_zero():
    inbox = JointStateInbox(JOINTS, "/joint_states")
    position, velocity, effort = lists()
    inbox.take(JOINTS, 1.0, [0.1, 0.2], [], [math.nan, 3.0])
    inbox.read_into(position, velocity, effort, 0.5)
    assert (position, velocity, effort) == ([0.1, 0.2], [9.0, 9.0], [0.0, 3.0])
    assert math.isnan(inbox.effort_of(0)) and inbox.effort_of(1) == 3.0


def test_a_state_lacking_a_joint_is_not_complete_and_the_wait_names_what_came():
    inbox = JointStateInbox(JOINTS, "/joint_states")
    assert "no joint state within 2 s (is it served?)" in str(inbox.missing_error(2.0, "is it served?"))
    inbox.take(["shoulder"], 1.0, [0.1], [0.0], [0.0])
    assert not inbox.complete() and inbox.effort_of(0) is None
    error = inbox.missing_error(2.0, "is it served?")
    assert "the joint states name shoulder, not every joint of the robot (shoulder, elbow)" in str(error)
    assert error.field == "/joint_states" and error.value == ["shoulder"]


def test_a_silent_publisher_is_the_hardwares_fault(monkeypatch):
    now = [100.0]
    monkeypatch.setattr("jointctl.hardware.joint_state_inbox.time.monotonic", lambda: now[0])
    inbox = JointStateInbox(JOINTS, "/joint_states")
    inbox.take(JOINTS, 1.0, [0.1, 0.2], [0.0, 0.0], [0.0, 0.0])
    now[0] += 0.4
    assert inbox.read_into(*lists(), 0.5) is None
    now[0] += 0.3
    assert inbox.read_into(*lists(), 0.5) == "no joint state on /joint_states for 0.7 s"


def test_the_recording_keeps_every_state_with_its_stamp_in_the_joints_order():
    inbox = JointStateInbox(JOINTS, "/joint_states")
    inbox.take(JOINTS, 0.5, [0.0, 0.0], [0.0, 0.0], [0.0, 0.0])  # before the recording: not kept
    inbox.start_recording()
    for k in range(3):
        inbox.take(["elbow", "shoulder"], 1.0 + 0.02 * k, [k, -k], [2.0 * k, -2.0 * k], [5.0, 6.0])
    stamps, positions, velocities, efforts = inbox.recorded_all(0)
    assert stamps == [1.0, 1.02, 1.04]
    assert positions == [(0, 0), (-1, 1), (-2, 2)] and velocities == [(0.0, 0.0), (-2.0, 2.0), (-4.0, 4.0)]
    assert efforts == [(6.0, 5.0)] * 3
    assert inbox.recorded_all(0) == ([], [], [], [])  # the recording stopped


@pytest.mark.parametrize(("velocity", "effort", "quantity"), [
    ([], [1.0, 2.0], "velocity"),
    ([0.0, math.nan], [1.0, 2.0], "velocity"),
    ([0.0, 0.0], [math.nan, 2.0], "effort"),
])
def test_identification_refuses_a_recording_without_velocities_or_the_joints_effort(velocity, effort, quantity):
    inbox = JointStateInbox(JOINTS, "/arm/joint_states")
    inbox.start_recording()
    inbox.take(JOINTS, 1.0, [0.1, 0.2], velocity, effort)
    with pytest.raises(JointCtlError, match=f"carry no {quantity} for every joint") as info:
        inbox.recorded_all(0)
    assert info.value.field == "/arm/joint_states" and info.value.value == quantity


def test_the_other_joints_effort_may_be_missing():
    inbox = JointStateInbox(JOINTS, "/joint_states")
    inbox.start_recording()
    inbox.take(JOINTS, 1.0, [0.1, 0.2], [0.0, 0.0], [1.0, math.nan])
    assert inbox.recorded_all(0)[3] == [(1.0, None)]

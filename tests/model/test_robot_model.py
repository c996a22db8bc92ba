"""Tests of the RobotModel data classes and their queries."""

from __future__ import annotations

import dataclasses

import pytest

from jointctl.model.robot_model import (
    JOINT_TYPES,
    MOVABLE_JOINT_TYPES,
    Joint,
    JointLimits,
    Link,
    Pose,
    RobotModel,
    SensorSpec,
    Transmission,
)


def limits(lower: float | None, upper: float | None) -> JointLimits:
    return JointLimits(lower, upper, effort=5.0, velocity=1.0)


def make_robot() -> RobotModel:
    """world -> base (fixed) -> a (revolute) -> b (prismatic, locked) and a -> c (continuous)."""
    links = tuple(Link(n) for n in ("world", "base", "a", "b", "c"))
    joints = (
        Joint("glue", "fixed", "world", "base"),
        Joint("ja", "revolute", "base", "a", limits=limits(-1.0, 1.0)),
        Joint("jb", "prismatic", "a", "b", limits=limits(0.2, 0.2)),
        Joint("jc", "continuous", "a", "c"),
    )
    transmissions = (
        Transmission("tc", "SimpleTransmission", "jc", ("EffortJointInterface",)),
        Transmission("ta", "SimpleTransmission", "ja", ("EffortJointInterface",)),
    )
    sensors = (SensorSpec("ft", "force_torque", "jb", "b"),)
    return RobotModel("r", links, joints, transmissions, sensors, namespace="ns", source="r.urdf")


def test_lookup_by_name() -> None:
    robot = make_robot()
    assert robot.link("a") is robot.links[2]
    assert robot.joint("jc") is robot.joints[3]
    assert robot.has_link("c") and not robot.has_link("jc")
    assert robot.has_joint("jc") and not robot.has_joint("c")
    with pytest.raises(KeyError):
        robot.joint("nope")
    with pytest.raises(KeyError):
        robot.link("nope")


def test_root_link_is_the_link_no_joint_points_to() -> None:
    assert make_robot().root_link == "world"
    robot = make_robot()
    without_world = RobotModel("r", robot.links[1:], robot.joints[1:])
    assert without_world.root_link == "base"


def test_movable_joints_in_document_order_without_fixed_and_locked() -> None:
    robot = make_robot()
    assert [j.name for j in robot.movable_joints] == ["ja", "jc"]


def test_transmission_for_and_child_joints() -> None:
    robot = make_robot()
    assert robot.transmission_for("ja").name == "ta"
    assert robot.transmission_for("jc").name == "tc"
    assert robot.transmission_for("jb") is None
    assert [j.name for j in robot.child_joints("a")] == ["jb", "jc"]
    assert robot.child_joints("c") == ()
    assert [j.name for j in robot.child_joints("world")] == ["glue"]


@pytest.mark.parametrize(
    ("jtype", "lim", "locked", "movable"),
    [
        ("fixed", None, False, False),
        ("revolute", limits(-1.0, 1.0), False, True),
        ("revolute", limits(0.5, 0.5), True, False),
        ("prismatic", limits(-1.0, 0.0), False, True),
        ("prismatic", limits(0.0, 0.0), True, False),
        ("continuous", None, False, True),
        ("continuous", limits(None, None), False, True),
        ("floating", None, False, False),
        ("planar", None, False, False),
    ],
)
def test_joint_locked_and_movable(jtype: str, lim: JointLimits | None, locked: bool, movable: bool) -> None:
    joint = Joint("j", jtype, "p", "c", limits=lim)
    assert joint.is_locked is locked
    assert joint.is_movable is movable
    assert joint.is_prismatic is (jtype == "prismatic")


def test_joint_type_sets() -> None:
    assert MOVABLE_JOINT_TYPES == {"revolute", "continuous", "prismatic"}
    assert JOINT_TYPES == MOVABLE_JOINT_TYPES | {"fixed", "floating", "planar"}


def test_defaults() -> None:
    joint = Joint("j", "revolute", "p", "c")
    assert joint.origin == Pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert joint.axis == (1.0, 0.0, 0.0)
    assert (joint.damping, joint.friction, joint.limits) == (0.0, 0.0, None)
    tr = Transmission("t", "SimpleTransmission", "j", ("EffortJointInterface",))
    assert tr.mechanical_reduction == 1.0 and tr.actuator is None
    robot = RobotModel("r", (Link("a"),), ())
    assert robot.transmissions == () and robot.sensors == ()
    assert robot.namespace is None and robot.source is None


def test_model_is_immutable() -> None:
    robot = make_robot()
    with pytest.raises(dataclasses.FrozenInstanceError):
        robot.name = "other"  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        robot.joints[1].damping = 3.0  # type: ignore[misc]


def test_equality_ignores_lookup_tables() -> None:
    assert make_robot() == make_robot()
    assert make_robot() != dataclasses.replace(make_robot(), name="other")


def test_replace_rebuilds_lookup_tables() -> None:
    robot = make_robot()
    renamed = dataclasses.replace(robot, links=tuple(dataclasses.replace(lk, name=lk.name + "_x")
                                                     for lk in robot.links))
    assert renamed.has_link("a_x")
    assert not renamed.has_link("a")

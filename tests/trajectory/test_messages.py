"""Tests of the trajectory_msgs-style JointTrajectory / JointTrajectoryPoint classes."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from jointctl.trajectory.messages import JointSpec, JointTrajectory, JointTrajectoryPoint

# ----------------------------------------------------------------------------- strategies

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
names = st.text(min_size=1, max_size=12)


@st.composite
def trajectories(draw) -> JointTrajectory:
    joint_names = tuple(draw(st.lists(names, min_size=0, max_size=6, unique=True)))
    n = len(joint_names)

    def vector():
        return st.one_of(st.just(()), st.tuples(*[finite] * n))

    points = draw(st.lists(
        st.builds(JointTrajectoryPoint, positions=vector(), velocities=vector(),
                  accelerations=vector(), effort=vector(), time_from_start_s=finite),
        max_size=8))
    return JointTrajectory(joint_names, tuple(points), stamp_s=draw(finite),
                           frame_id=draw(st.text(max_size=10)))


# ----------------------------------------------------------------------------- construction


def test_point_defaults_are_empty_vectors_at_time_zero() -> None:
    p = JointTrajectoryPoint()
    assert p.positions == p.velocities == p.accelerations == p.effort == ()
    assert p.time_from_start_s == 0.0


def test_sequences_become_tuples_and_messages_are_frozen() -> None:
    p = JointTrajectoryPoint(positions=[1.0, 2.0], velocities=np.array([0.5, 0.5]), time_from_start_s=1.0)
    assert isinstance(p.positions, tuple) and isinstance(p.velocities, tuple)
    traj = JointTrajectory(["a", "b"], [p])
    assert traj.joint_names == ("a", "b") and traj.points == (p,)
    assert isinstance(traj.joint_names, tuple) and isinstance(traj.points, tuple)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.time_from_start_s = 2.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        traj.stamp_s = 1.0  # type: ignore[misc]
    assert hash(p) == hash(JointTrajectoryPoint((1.0, 2.0), (0.5, 0.5), (), (), 1.0))


def test_joint_spec_defaults_are_unlimited() -> None:
    spec = JointSpec("j", None, None, max_velocity=1.0)
    assert spec.max_acceleration == spec.max_jerk == spec.max_effort == float("inf")
    assert dict(spec.extra) == {}


# ----------------------------------------------------------------------------- from_arrays


def test_from_arrays_builds_one_point_per_time() -> None:
    traj = JointTrajectory.from_arrays(
        ["a", "b"], [0.5, 1.0, 2.0],
        [[0.0, 1.0], [0.1, 1.1], [0.2, 1.2]],
        velocities=np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]),
        accelerations=[[0.0, 0.0], [-1.0, 1.0], [0.0, 0.5]],
        stamp_s=12.5,
    )
    assert traj.joint_names == ("a", "b")
    assert traj.stamp_s == 12.5 and traj.frame_id == ""
    assert traj.points == (
        JointTrajectoryPoint((0.0, 1.0), (1.0, 2.0), (0.0, 0.0), (), 0.5),
        JointTrajectoryPoint((0.1, 1.1), (3.0, 4.0), (-1.0, 1.0), (), 1.0),
        JointTrajectoryPoint((0.2, 1.2), (5.0, 6.0), (0.0, 0.5), (), 2.0),
    )
    for p in traj.points:
        assert all(type(x) is float for x in p.positions + p.velocities + p.accelerations)
        assert type(p.time_from_start_s) is float


def test_from_arrays_without_velocities_leaves_them_empty() -> None:
    traj = JointTrajectory.from_arrays(("j",), np.array([1.0, 2.0]), np.array([[3], [4]]))
    assert traj.points == (
        JointTrajectoryPoint(positions=(3.0,), time_from_start_s=1.0),
        JointTrajectoryPoint(positions=(4.0,), time_from_start_s=2.0),
    )
    assert traj.stamp_s == 0.0


@given(st.integers(1, 6), st.integers(1, 20), st.data())
def test_from_arrays_matches_the_arrays(n_joints: int, n_points: int, data) -> None:
    row = st.lists(finite, min_size=n_joints, max_size=n_joints)
    times = data.draw(st.lists(finite, min_size=n_points, max_size=n_points))
    pos = np.array(data.draw(st.lists(row, min_size=n_points, max_size=n_points)), dtype=float)
    vel = np.array(data.draw(st.lists(row, min_size=n_points, max_size=n_points)), dtype=float)
    joint_names = [f"j{i}" for i in range(n_joints)]
    traj = JointTrajectory.from_arrays(joint_names, times, pos, vel)
    assert len(traj.points) == n_points
    for k, p in enumerate(traj.points):
        assert p.positions == tuple(pos[k]) and p.velocities == tuple(vel[k])
        assert p.accelerations == () and p.effort == ()
        assert p.time_from_start_s == times[k]


# ----------------------------------------------------------------------------- to_dict / from_dict


def test_to_dict_uses_ros_field_names() -> None:
    traj = JointTrajectory(("a",), (JointTrajectoryPoint((1.0,), (2.0,), (), (0.5,), 3.0),),
                           stamp_s=4.0, frame_id="base")
    assert traj.to_dict() == {
        "header": {"stamp": 4.0, "frame_id": "base"},
        "joint_names": ["a"],
        "points": [{"positions": [1.0], "velocities": [2.0], "accelerations": [], "effort": [0.5],
                    "time_from_start": 3.0}],
    }


def test_from_dict_fills_missing_fields_with_ros_defaults() -> None:
    assert JointTrajectory.from_dict({}) == JointTrajectory((), ())
    traj = JointTrajectory.from_dict({"joint_names": ["a"], "points": [{"positions": [1]}]})
    assert traj == JointTrajectory(("a",), (JointTrajectoryPoint(positions=(1,)),))
    assert traj.stamp_s == 0.0 and traj.frame_id == ""
    nulls = JointTrajectory.from_dict({"header": None, "joint_names": None,
                                       "points": [{"positions": None, "velocities": None}]})
    assert nulls == JointTrajectory((), (JointTrajectoryPoint(),))


@given(trajectories())
def test_to_dict_from_dict_round_trip(traj: JointTrajectory) -> None:
    assert JointTrajectory.from_dict(traj.to_dict()) == traj


@given(trajectories())
def test_json_and_yaml_round_trip(traj: JointTrajectory) -> None:
    assert JointTrajectory.from_dict(json.loads(json.dumps(traj.to_dict()))) == traj
    assert JointTrajectory.from_dict(yaml.safe_load(yaml.safe_dump(traj.to_dict()))) == traj


@given(trajectories())
def test_to_dict_is_plain_data(traj: JointTrajectory) -> None:
    data = traj.to_dict()
    assert isinstance(data["joint_names"], list) and isinstance(data["points"], list)
    for p in data["points"]:
        assert all(isinstance(p[k], list) for k in ("positions", "velocities", "accelerations", "effort"))

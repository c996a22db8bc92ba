"""Joint states read from a rosbag for identification: the topic chosen, and each refusal naming why."""

from __future__ import annotations

import math

import pytest
import rosbag
import rospy
from sensor_msgs.msg import JointState

from jointctl.errors import ConfigError
from jointctl.identification.identify import identify_states
from jointctl.ros.bag_trace import read_joint

MASS, DAMPING, LOAD = 1.5, 4.0, 12.0


def states(seconds: float = 4.0, rate_hz: float = 100.0, *, effort: bool = True, names=("joint1", "joint2")):
    """JointStates of joint1 swinging (two sines: one alone cannot tell a delayed effort from other
    parameters) as a mass ``MASS`` with ``DAMPING`` under a load ``LOAD`` would need (exact
    accelerations), stamped at ``rate_hz``."""
    for k in range(int(seconds * rate_hz)):
        t = k / rate_hz
        w, v = 2 * math.pi, 2 * math.pi * 0.37
        q = 0.2 * math.sin(w * t) + 0.1 * math.sin(v * t)
        qd = 0.2 * w * math.cos(w * t) + 0.1 * v * math.cos(v * t)
        qdd = -0.2 * w * w * math.sin(w * t) - 0.1 * v * v * math.sin(v * t)
        msg = JointState(name=list(names), position=[q, 0.0], velocity=[qd, 0.0],
                         effort=[MASS * qdd + DAMPING * qd + LOAD, 0.0] if effort else [])
        msg.header.stamp = rospy.Time.from_sec(100.0 + t)
        yield msg


def write_bag(path, topics: dict) -> None:
    with rosbag.Bag(str(path), "w") as bag:
        for topic, messages in topics.items():
            for msg in messages:
                bag.write(topic, msg, msg.header.stamp)


def test_the_one_topic_naming_the_joint_is_read_and_fits(tmp_path) -> None:
    path = tmp_path / "run.bag"
    write_bag(path, {"/robot/joint_states": states(), "/other/joint_states": states(names=("a", "b"))})
    topic, stamps, q, qd, u = read_joint(path, "joint1")
    assert topic == "/robot/joint_states" and len(stamps) == 400 and stamps[0] == pytest.approx(100.0)
    _, metrics = identify_states(stamps, q, qd, u, "joint1", "prismatic", source=str(path), fit_friction=False)
    # 100 Hz states: central differences, accurate to (ωh)²/6 = 0.07 % at 1 Hz.
    assert metrics["mass_kg"] == pytest.approx(MASS, rel=1e-3)
    assert metrics["damping_n_s_m"] == pytest.approx(DAMPING, rel=1e-3)
    assert metrics["gravity_load_n"] == pytest.approx(LOAD, rel=1e-3)
    assert metrics["sample_period_s"] == pytest.approx(0.01)


def test_each_refusal_names_what_is_wrong(tmp_path) -> None:
    two = tmp_path / "two.bag"
    write_bag(two, {"/a/joint_states": states(1.0), "/b/joint_states": states(1.0)})
    with pytest.raises(ConfigError, match="several JointState topics name the joint") as info:
        read_joint(two, "joint1")
    assert info.value.field == "--topic"
    assert read_joint(two, "joint1", "/b/joint_states")[0] == "/b/joint_states"
    with pytest.raises(ConfigError, match="it has: /a/joint_states, /b/joint_states"):
        read_joint(two, "joint1", "/c/joint_states")
    with pytest.raises(ConfigError, match="names the joint") as info:
        read_joint(two, "joint7")
    assert info.value.field == "--joint" and info.value.value == "joint7"
    bare = tmp_path / "bare.bag"
    write_bag(bare, {"/a/joint_states": states(1.0, effort=False)})
    with pytest.raises(ConfigError, match="carry no effort") as info:
        read_joint(bare, "joint1")
    assert info.value.field == "effort"
    broken = tmp_path / "broken.bag"
    broken.write_bytes(b"not a bag at all")
    with pytest.raises(ConfigError, match="cannot read the bag"):
        read_joint(broken, "joint1")

"""The CDR encoder of ``sensor_msgs/msg/JointState`` against ROS 2 itself: rclpy's ``serialize_message`` gives the
same bytes, and the ros2msg schema text is the one rosbag2 assembles from the installed ``.msg`` files."""

from __future__ import annotations

import re

import pytest

from jointctl.wire import ros2_cdr
from tests.ros2.environment import require_ros2
from tests.ros2.serialization import deserialize_joint_states, serialize_joint_states

SETUP = require_ros2()

#: Names of every length modulo 4 (the strings' padding), no joint, unicode, a frame or none, stamps past 2^31 ns.
CASES = [
    {"sec": 0, "nanosec": 0, "frame_id": "", "name": [], "position": [], "velocity": [], "effort": []},
    {"sec": 3, "nanosec": 500, "frame_id": "", "name": ["joint1"], "position": [-0.2], "velocity": [0.0],
     "effort": [98.1]},
    {"sec": 12, "nanosec": 999_999_999, "frame_id": "world", "name": ["a", "bc", "def", "ghij", "klmno"],
     "position": [0.1, -0.2, 0.3, 1e-300, -1e300], "velocity": [1.5, 2.5, -3.5, 0.0, 5e-324],
     "effort": [10.0, 20.0, 30.0, 40.0, 50.0]},
    {"sec": 1_700_000_000, "nanosec": 123_456_789, "frame_id": "base_link", "name": ["épaule", "coude"],
     "position": [1.0, 2.0], "velocity": [3.0, 4.0], "effort": [5.0, 6.0]},
    {"sec": 7, "nanosec": 1, "frame_id": "abc", "name": ["j1", "j2", "j3"], "position": [0.5, 0.25, 0.125],
     "velocity": [], "effort": [1.0, 2.0, 3.0]},  # an empty array between two full ones
]


def _ns(case) -> int:
    return case["sec"] * 1_000_000_000 + case["nanosec"]


@pytest.fixture(scope="module")
def reference():
    return serialize_joint_states(SETUP, CASES)


def test_joint_states_are_rclpys_bytes(reference):
    for case, expected in zip(CASES, reference):
        ours = ros2_cdr.joint_state(_ns(case), case["name"], case["position"], case["velocity"], case["effort"],
                                    case["frame_id"])
        assert ours == expected, case


def test_the_fixed_layout_encoder_gives_the_same_bytes(reference):
    for case, expected in zip(CASES, reference):
        if not len(case["position"]) == len(case["velocity"]) == len(case["effort"]) == len(case["name"]):
            continue  # the encoder writes every array full
        encoder = ros2_cdr.JointStateEncoder(case["name"], case["frame_id"])
        ours = encoder.encode(_ns(case), case["position"] + case["velocity"] + case["effort"])
        assert ours == expected, case
        assert encoder.size == len(expected)


def test_rclpy_reads_back_what_was_encoded():
    case = CASES[2]
    data = ros2_cdr.joint_state(_ns(case), case["name"], case["position"], case["velocity"], case["effort"],
                                case["frame_id"])
    (decoded,) = deserialize_joint_states(SETUP, [data])
    assert decoded == case


def test_the_schema_is_the_installed_definitions_as_rosbag2_joins_them():
    """rosbag2's LocalMessageDefinitionSource: the root type's .msg text, then for each field type that is not a
    primitive (depth first, in name order, each once) a line of 80 '=', 'MSG: <type as written>' and its text."""
    share = SETUP.parent / "share"
    primitives = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32",
                  "int64", "uint64", "string"}
    seen = set()

    def text_of(name: str) -> str:
        package, kind = name.split("/", 1)
        return (share / package / "msg" / f"{kind.split('/')[-1]}.msg").read_text()

    def dependencies(text: str, package: str) -> list[str]:
        types = {m for m in re.findall(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+", text) if m not in primitives}
        return sorted(t if "/" in t else f"{package}/{t}" for t in types)

    def joined(name: str) -> str:
        text = text_of(name)
        out = text
        for dep in dependencies(text, name.split("/")[0]):
            if dep not in seen:
                seen.add(dep)
                out += f"\n{'=' * 80}\nMSG: {dep}\n" + joined(dep)
        return out

    assert ros2_cdr.JOINT_STATE_DEFINITION == joined("sensor_msgs/msg/JointState")
    assert ros2_cdr.JOINT_STATE_DEFINITION.count("\nMSG: ") == 2  # std_msgs/Header, builtin_interfaces/Time

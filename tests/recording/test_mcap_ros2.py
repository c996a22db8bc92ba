"""``run.mcap``'s ``/joint_states`` read by ROS 2 itself: rclpy's ``deserialize_message`` of every recorded message is
trace.csv's row of the same cycle (names in the hardware's order, stamps the loop's time), and the channel's
offered QoS names policies rclpy knows. ROS 2 runs in a child process (:mod:`tests.ros2.serialization`)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from jointctl.paths import scenarios_dir
from jointctl.recording import foxglove_messages as fm
from jointctl.recording.mcap_record import MCAP_FILE
from jointctl.recording.trace import load_trace
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from tests.ros2.environment import require_ros2
from tests.ros2.serialization import deserialize_joint_states, run_with_ros2

SETUP = require_ros2()
JOINTS = [f"joint{k}" for k in range(7)]


@pytest.fixture(scope="module")
def arm_run(tmp_path_factory):
    """The 7-DOF arm starting its move to the pre-pose: 0.4 s recorded every other cycle (200 rows)."""
    out = tmp_path_factory.mktemp("arm")
    data = yaml.safe_load((scenarios_dir() / "arm7dof_pose.yaml").read_text())
    data.pop("analysis")
    data.update(duration_s=0.4, record={"every": 2})
    data["goals"][0]["at_s"] = 0.05
    path = out / "scenario.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with Session(load_scenario(path), out_dir=out, mcap=True) as session:
        session.run()
    with open(out / MCAP_FILE, "rb") as f:
        records = [(channel, message) for _, channel, message in make_reader(f).iter_messages(
            topics=[fm.ROS_JOINT_STATES])]
    return load_trace(out / "trace.csv"), records


def test_rclpy_reads_every_joint_state_as_trace_csv_has_it(arm_run):
    trace, records = arm_run
    assert len(records) == len(trace.time_s) == 200
    decoded = deserialize_joint_states(SETUP, [message.data for _, message in records])
    assert all(m["name"] == JOINTS and m["frame_id"] == "" for m in decoded)
    stamps = [m["sec"] * 1_000_000_000 + m["nanosec"] for m in decoded]
    assert stamps == [round(t * 1e9) for t in trace.time_s] == [message.log_time for _, message in records]
    for quantity in ("position", "velocity", "effort"):
        recorded = np.array([m[quantity] for m in decoded])
        columns = np.column_stack([trace.joint(j, quantity) for j in JOINTS])
        assert np.array_equal(recorded, columns), quantity  # trace.csv's ten digits, the very numbers
    moved = np.array([m["position"] for m in decoded])
    assert np.ptp(moved[:, 1]) > 1e-3  # joint1 moved: the values are not all the start pose


def test_the_offered_qos_names_policies_rclpy_knows(arm_run):
    _, records = arm_run
    text = records[0][0].metadata["offered_qos_profiles"]
    script = r"""
import json, sys, yaml
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy
(p,) = yaml.safe_load(json.load(sys.stdin))
qos = QoSProfile(history=HistoryPolicy.get_from_short_key(p["history"]), depth=p["depth"],
                 reliability=ReliabilityPolicy.get_from_short_key(p["reliability"]),
                 durability=DurabilityPolicy.get_from_short_key(p["durability"]),
                 liveliness=LivelinessPolicy.get_from_short_key(p["liveliness"]))
json.dump([qos.history.name, qos.depth, qos.reliability.name, qos.durability.name, qos.liveliness.name,
           sorted(p)], sys.stdout)
"""
    history, depth, reliability, durability, liveliness, keys = run_with_ros2(SETUP, script, text)
    assert (history, depth, reliability, durability, liveliness) == ("KEEP_LAST", 10, "RELIABLE", "VOLATILE",
                                                                      "AUTOMATIC")
    assert keys == sorted(["history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
                           "liveliness_lease_duration", "avoid_ros_namespace_conventions"])

"""run.mcap read back with the ``mcap`` package: every channel, one message per trace row on the per-cycle
channels, timestamps in order, the trace's values, the simulation's link poses, objects and events."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from mcap.reader import make_reader

from jointctl.model.loader import description_text
from jointctl.recording import foxglove_messages as fm
from jointctl.recording.foxglove_layout import LAYOUT_FILE, layout_json
from jointctl.recording.mcap_record import MCAP_FILE
from jointctl.recording.trace import TraceRecorder, load_trace
from jointctl.scenario.run import run_scenario
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from tests.conftest import step_scenario

WEIGHT = {"name": "weight", "shape": "cylinder", "radius_m": 0.05, "length_m": 0.2, "mass_kg": 10.0,
          "xyz": [0.0, 0.0, 2.5], "spawn_at_s": 0.2}


def read_mcap(path):
    """(summary, {topic: [(log_time, publish_time, decoded message)]}, every log time in file order,
    metadata, attachments). JSON messages are decoded, others (ROS 2's CDR) left as bytes."""
    by_topic: dict[str, list] = {}
    order = []
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for _, channel, message in reader.iter_messages(log_time_order=False):
            data = json.loads(message.data) if channel.message_encoding == "json" else message.data
            by_topic.setdefault(channel.topic, []).append((message.log_time, message.publish_time, data))
            order.append(message.log_time)
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        attachments = {a.name: a for a in reader.iter_attachments()}
    return summary, by_topic, order, metadata, attachments


@pytest.fixture(scope="module")
def drop_run(tmp_path_factory):
    """A step with a weight dropped on the sensor at 0.2 s and a trajectory goal, recorded every cycle; the
    simulated world's link poses kept at every cycle for comparison."""
    out = tmp_path_factory.mktemp("drop")
    data = step_scenario(
        controller_file="trajectory", duration_s=1.2, commands={}, objects=[WEIGHT],
        start_controllers=["joint_state_controller", "joint1_position_controller", "joint1_trajectory_controller"],
        goals=[{"controller": "joint1_trajectory_controller", "at_s": 0.1,
                "trajectory": {"joint_names": ["joint1"],
                               "points": [{"positions": [-0.3], "time_from_start": 0.4}]}}])
    scenario = load_scenario(_write(out / "scenario.yaml", data))
    poses = {}
    with Session(scenario, out_dir=out, mcap=True) as session:
        world = session.world

        def keep(time_s):
            poses[round(time_s * 1e9)] = {link: world.body_pose(link) for link in ("link1", "link2", "ft_sensor_link")}

        session.loop.add_observer(keep)
        session.run()
        robot = session.robot
    return out, robot, poses


def _write(path, data):
    import yaml

    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_every_channel_is_there_with_one_message_per_trace_row(drop_run):
    out, _, _ = drop_run
    trace = load_trace(out / "trace.csv")
    summary, by_topic, order, _, _ = read_mcap(out / MCAP_FILE)
    topics = {channel.topic for channel in summary.channels.values()}
    assert topics == {fm.ROBOT_DESCRIPTION, *fm.PER_CYCLE, fm.TF, fm.OBJECTS, fm.EVENTS}
    rows = len(trace.time_s)
    for topic in fm.PER_CYCLE:
        assert len(by_topic[topic]) == rows, topic
        stamps = [t for t, _, _ in by_topic[topic]]
        assert stamps == [round(t * 1e9) for t in trace.time_s]
    counts = summary.statistics.channel_message_counts
    assert sum(counts.values()) == len(order)
    assert order == sorted(order)  # the whole file in time order, not only each channel
    for topic, messages in by_topic.items():
        assert all(log == publish for log, publish, _ in messages), topic  # PlotJuggler reads publish times
    schemas = {channel.topic: summary.schemas[channel.schema_id] for channel in summary.channels.values()}
    assert schemas[fm.JOINT_STATES].name == "foxglove.JointStates"
    assert schemas[fm.TF].name == "foxglove.FrameTransforms"
    assert schemas[fm.OBJECTS].name == "foxglove.SceneUpdate"
    assert schemas[fm.EVENTS].name == "foxglove.Log"
    assert schemas[fm.ROBOT_DESCRIPTION].name == "std_msgs/String"
    schemas.pop(fm.ROS_JOINT_STATES)  # the ROS 2 channel: ros2msg and cdr, checked in test_mcap_ros2
    assert all(s.encoding == "jsonschema" for s in schemas.values())
    assert all(c.message_encoding == "json" for c in summary.channels.values() if c.topic in schemas)


def test_the_ros2_joint_states_are_what_a_generic_reader_takes_for_a_ros2_channel(drop_run):
    """The MCAP registry's ros2 profile: message encoding cdr, schema encoding ros2msg named by the ROS 2 type,
    the offered QoS in the channel's metadata; every message the size of a one-joint JointState."""
    out, _, _ = drop_run
    summary, by_topic, _, _, _ = read_mcap(out / MCAP_FILE)
    (channel,) = [c for c in summary.channels.values() if c.topic == "/joint_states"]
    schema = summary.schemas[channel.schema_id]
    assert (channel.message_encoding, schema.encoding, schema.name) == ("cdr", "ros2msg", "sensor_msgs/msg/JointState")
    assert schema.data.decode().startswith("# This is a message that holds data to describe the state")
    assert "\nMSG: std_msgs/Header\n" in schema.data.decode()
    assert channel.metadata["offered_qos_profiles"].startswith("- history: keep_last\n")
    messages = [m for _, _, m in by_topic["/joint_states"]]
    # 4 encapsulation + 8 stamp + 8 empty frame_id + 4 count + 4 + 7 "joint1\0" + 1 pad + 3 x (4 count + 4 pad + 8)
    assert {len(m) for m in messages} == {84}
    assert all(m[:4] == b"\x00\x01\x00\x00" for m in messages)  # CDR, little-endian


def test_a_generic_ros2_decoder_reads_the_joint_states_from_the_schema_alone(drop_run):
    """The MCAP project's ROS 2 decoder (no ROS 2 installed): it parses the channel's ros2msg text and decodes
    each message into the trace's row of its cycle."""
    from mcap_ros2.decoder import DecoderFactory

    out, _, _ = drop_run
    trace = load_trace(out / "trace.csv")
    with open(out / MCAP_FILE, "rb") as f:
        decoded = [(message.log_time, state) for _, _, message, state in make_reader(
            f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(topics=[fm.ROS_JOINT_STATES])]
    assert len(decoded) == len(trace.time_s)
    assert all(state.name == ["joint1"] and state.header.frame_id == "" for _, state in decoded)
    assert [s.header.stamp.sec * 1_000_000_000 + s.header.stamp.nanosec for _, s in decoded] == \
        [t for t, _ in decoded] == [round(t * 1e9) for t in trace.time_s]
    for quantity in ("position", "velocity", "effort"):
        values = [getattr(state, quantity)[0] for _, state in decoded]
        assert np.array_equal(values, trace.joint("joint1", quantity)), quantity


def test_values_are_the_traces(drop_run):
    out, _, _ = drop_run
    trace = load_trace(out / "trace.csv")
    _, by_topic, _, _, _ = read_mcap(out / MCAP_FILE)

    def close(a, b):  # both write ten significant digits: the very same numbers
        return np.array_equal(np.asarray(a, float), b, equal_nan=True)

    states = [m for _, _, m in by_topic[fm.JOINT_STATES]]
    assert {j["name"] for m in states for j in m["joints"]} == {"joint1"}
    assert close([m["joints"][0]["position"] for m in states], trace.joint("joint1", "position"))
    assert close([m["joints"][0]["velocity"] for m in states], trace.joint("joint1", "velocity"))
    assert close([m["joints"][0]["effort"] for m in states], trace.joint("joint1", "effort"))
    stamp = states[-1]["timestamp"]
    assert stamp["sec"] + stamp["nsec"] * 1e-9 == pytest.approx(trace.time_s[-1], abs=1e-9)
    references = [m["joints"][0]["position"] for _, _, m in by_topic[fm.REFERENCES]]
    assert close(references, trace.joint("joint1", "reference"))
    joints = [m["joint1"] for _, _, m in by_topic[fm.JOINTS]]
    assert set(joints[0]) == {"reference_m", "position_m", "velocity_m_s", "effort_N"}  # a prismatic joint
    assert close([j["position_m"] for j in joints], trace.joint("joint1", "position"))
    assert close([j["effort_N"] for j in joints], trace.joint("joint1", "effort"))
    wrenches = [m["ft_sensor"] for _, _, m in by_topic[fm.WRENCHES]]
    assert wrenches[0]["frame_id"] == "ft_sensor_link"
    for axis, column in zip(fm.WRENCH_AXES, ("force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z")):
        assert close([w[axis] for w in wrenches], trace[f"ft_sensor.{column}"])
    assert min(w["force_z_N"] for w in wrenches) < -50  # the weight landed on the sensor


def test_tf_gives_the_simulated_links_poses(drop_run):
    out, _, poses = drop_run
    _, by_topic, _, _, _ = read_mcap(out / MCAP_FILE)
    tf = by_topic[fm.TF]
    assert len(tf) == 120  # 100 Hz over 1.2 s
    assert [t for t, _, _ in tf] == [round(k * 0.01 * 1e9) for k in range(120)]
    for log_time, _, message in tf[::7]:
        transforms = {t["child_frame_id"]: t for t in message["transforms"]}
        assert transforms["link1"]["parent_frame_id"] == "world"
        assert transforms["link2"]["parent_frame_id"] == "link1"
        pose = np.eye(4)
        for child in ("link1", "link2", "ft_sensor_link"):  # world -> link1 -> link2 -> sensor
            pose = pose @ _matrix(transforms[child])
            # The world's body poses are computed at the start of a physics step: the next cycle's are this one's.
            position, quaternion = poses[log_time + 1_000_000][child]
            assert np.allclose(pose[:3, 3], position, atol=1e-9), (log_time, child)
            assert np.allclose(pose[:3, :3], _rotation(quaternion), atol=1e-9), (log_time, child)


def _matrix(transform) -> np.ndarray:
    t, q = transform["translation"], transform["rotation"]
    m = np.eye(4)
    m[:3, :3] = _rotation((q["w"], q["x"], q["y"], q["z"]))
    m[:3, 3] = (t["x"], t["y"], t["z"])
    return m


def _rotation(wxyz) -> np.ndarray:
    w, x, y, z = wxyz
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_the_spawned_object_falls_in_the_scene_from_its_spawn(drop_run):
    out, _, _ = drop_run
    _, by_topic, _, _, _ = read_mcap(out / MCAP_FILE)
    updates = by_topic[fm.OBJECTS]
    assert updates[0][0] == round(WEIGHT["spawn_at_s"] * 1e9)
    assert len(updates) == 100  # 100 Hz from 0.2 s to the end
    entity = updates[0][2]["entities"][0]
    assert entity["id"] == "weight" and entity["frame_id"] == "world"
    cylinder = entity["cylinders"][0]
    assert cylinder["size"] == {"x": 0.1, "y": 0.1, "z": 0.2}
    assert cylinder["bottom_scale"] == cylinder["top_scale"] == 1.0
    assert cylinder["pose"]["position"]["z"] == pytest.approx(2.5, abs=1e-3)
    assert entity["texts"][0]["text"] == "weight"
    heights = [m["entities"][0]["cylinders"][0]["pose"]["position"]["z"] for _, _, m in updates]
    assert heights[30] < heights[0] - 0.3  # falling
    assert all(m["deletions"] == [] for _, _, m in updates)


def test_events_say_the_spawn_and_the_goal(drop_run):
    out, _, _ = drop_run
    _, by_topic, _, _, _ = read_mcap(out / MCAP_FILE)
    events = [(t, m["message"], m["level"]) for t, _, m in by_topic[fm.EVENTS]]
    texts = [text for _, text, _ in events]
    assert (round(0.2e9), "spawned weight", fm.INFO) in events
    assert any(text.startswith("joint1_trajectory_controller: goal 1 starts") for text in texts)
    ended = [(t, text) for t, text, _ in events if text.startswith("joint1_trajectory_controller: goal 1 succeeded")]
    assert len(ended) == 1 and 0.5e9 <= ended[0][0] <= 1.2e9
    assert [t for t, _, _ in events] == sorted(t for t, _, _ in events)


def test_the_robot_description_is_the_urdf(drop_run):
    out, robot, _ = drop_run
    _, by_topic, _, metadata, attachments = read_mcap(out / MCAP_FILE)
    ((log_time, _, message),) = by_topic[fm.ROBOT_DESCRIPTION]
    assert log_time == 0 and message["data"] == description_text(robot)
    assert attachments["robot.urdf"].data.decode() == message["data"]
    assert metadata["jointctl"]["robot"] == robot.name
    assert json.loads(metadata["jointctl"]["joints"]) == ["joint1"]


def test_a_decimated_trace_gives_as_many_messages_as_rows(tmp_path, write_scenario):
    path = write_scenario(step_scenario(duration_s=0.3, record={"every": 7}))
    run_scenario(load_scenario(path), tmp_path / "run")
    trace = load_trace(tmp_path / "run" / "trace.csv")
    summary, by_topic, _, _, _ = read_mcap(tmp_path / "run" / MCAP_FILE)
    assert len(trace.time_s) == 43
    assert all(len(by_topic[t]) == 43 for t in fm.PER_CYCLE)
    assert len(by_topic[fm.TF]) == 22  # every second row (every 14 ms): at most 100 Hz
    assert fm.OBJECTS not in by_topic and fm.EVENTS not in by_topic  # nothing spawned, nothing happened


def test_the_same_run_gives_the_same_file(tmp_path, write_scenario):
    path = write_scenario(step_scenario(duration_s=0.3, objects=[dict(WEIGHT, spawn_at_s=0.1)]))
    for name in ("a", "b"):
        run_scenario(load_scenario(path), tmp_path / name)
    assert (tmp_path / "a" / MCAP_FILE).read_bytes() == (tmp_path / "b" / MCAP_FILE).read_bytes()


def test_revolute_joints_have_radians_and_newton_metres():
    from jointctl.model.loader import load_robot_model
    from jointctl.paths import robots_dir

    robot = load_robot_model(robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro")
    names = [j.name for j in robot.movable_joints]
    record = fm.RecordFormat(robot, names, ["position"] * 6 + ["velocity"], ["ft_sensor"])
    row = [0.5] + [math.nan] + [0.1] * 6 + [0.2] * 7 + [0.3] * 7 + [0.4] * 7 + [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    ros, *json_messages = record.row_messages(row, 500_000_000)
    states, references, joints, wrenches = (json.loads(m) for m in json_messages)
    assert ros[4:12] == bytes.fromhex("00000000 0065cd1d")  # header.stamp: 0 s, 500000000 ns (CDR)
    assert joints[names[1]] == {"reference_rad": 0.1, "position_rad": 0.2, "velocity_rad_s": 0.3, "effort_Nm": 0.4}
    assert joints[names[0]]["reference_rad"] is None  # a NaN reference is JSON's null
    assert joints[names[6]] == {"reference_rad_s": 0.1, "position_rad": 0.2, "velocity_rad_s": 0.3, "effort_Nm": 0.4}
    assert references["joints"][6] == {"name": names[6], "velocity": 0.1}
    assert states["timestamp"] == {"sec": 0, "nsec": 500_000_000}
    assert wrenches["ft_sensor"]["torque_z_Nm"] == 6
    rows = np.array([row, row])
    assert [m for _, m in record.cycle_messages(rows)][1] == record.row_messages(row, 500_000_000)
    lines = [",".join("%.10g" % v for v in r) for r in rows]  # as trace.csv writes them
    assert record.cycle_messages(rows, lines) == record.cycle_messages(rows)


def test_quaternions_of_rotations():
    from scipy.spatial.transform import Rotation

    rotations = Rotation.random(500, random_state=3)
    expected = rotations.as_quat()
    expected *= np.where(expected[:, 3:4] < 0, -1.0, 1.0)
    assert np.allclose(fm.quaternions(rotations.as_matrix()), expected, atol=1e-12)
    assert np.allclose(fm.quaternions(np.diag([1.0, -1.0, -1.0])), [1, 0, 0, 0])


def test_trace_csv_is_written_whole_when_the_mcap_writer_fails(tmp_path):
    class Hardware:
        joint_names, sensor_names, wrenches = ("j",), (), {}
        position, velocity, effort = [0.0], [0.0], [0.0]

    recorder = TraceRecorder(tmp_path / "trace.csv", Hardware(), [0.0], chunk_rows=4)

    def broken(rows, lines):
        raise OSError("disk full")

    recorder.chunk_readers.append(broken)
    for k in range(10):
        recorder(k * 0.001)
    with pytest.raises(OSError, match="disk full"):
        recorder.close()
    assert len(load_trace(tmp_path / "trace.csv").time_s) == 10


def test_the_shipped_layout_is_the_layout_and_reads_recorded_topics():
    assert LAYOUT_FILE.read_text() == layout_json()
    text = LAYOUT_FILE.read_text()
    for topic in (fm.JOINT_STATES, fm.REFERENCES, fm.WRENCHES, fm.ROBOT_DESCRIPTION, fm.OBJECTS, fm.TF, fm.EVENTS):
        assert f'"{topic}' in text, topic


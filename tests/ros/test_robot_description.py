"""The robot in rviz as the book's launch files make it: robot_description, TF, the objects' markers.

Against a real master, a real ``jointctl serve`` and Debian's real robot_state_publisher (C++), one
served robot per module:

- one_dof, served with ``--rviz`` and no display: jointctl starts robot_state_publisher itself (with
  the book's remap) and says in one line that rviz is not started. The piston is commanded from
  -0.5 m to -0.2 m; theory: link2's origin is joint1's, ``base_height`` (1 m) above link1 (at the
  world origin) plus q along z, so the TF world -> link2 stamped t is (0, 0, 1 + q(t)) with q(t) from
  ``joint_states`` stamped t. A box spawned through ``/gazebo/spawn_urdf_model`` falls to the floor;
  its marker has the pose ``/gazebo/model_states`` reports in the same cycle.
- arm7dof, with robot_state_publisher started as the book's launch files start it (a node of its
  own, ``joint_states:=/arm7dof/joint_states``): the flange's TF (world -> ft_sensor_link) at
  stamp t equals the model's forward kinematics (RobotDynamics) at the joint angles stamped t.

Run as a script (``python test_robot_description.py client JOINT_STATES STEPS_JSON``) this file is
the client: one rospy node that records joint states, /tf, /tf_static, the markers and
model_states while it runs the steps, printing one JSON line. It waits for what it records, never a
fixed time: until its subscribers are connected and recording, until the joints have moved so far
and so many /tf messages are in, until a marker shows the object at rest or deleted.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

HERE = Path(__file__).resolve()
ROOT = HERE.parents[2]
TOL_M = 1e-6
ONE_DOF_STATES = "/one_DOF_robot/joint_states"
ARM_STATES = "/arm7dof/joint_states"
MARKERS = "/jointctl/object_markers"
BOX_URDF = """<robot name="crate"><link name="crate_link"><inertial><mass value="2.0"/>
  <inertia ixx="0.013333" ixy="0" ixz="0" iyy="0.013333" iyz="0" izz="0.013333"/></inertial>
  <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link></robot>"""


# ------------------------------------------------------------------------------------------------
# The client (its own process: rospy allows one node per process)
# ------------------------------------------------------------------------------------------------

def _client(joint_states: str, steps: list[dict]) -> dict:
    import threading

    import rosgraph
    import rospy
    from gazebo_msgs.msg import ModelStates
    from gazebo_msgs.srv import DeleteModel, SpawnModel
    from geometry_msgs.msg import Pose
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import MarkerArray

    rospy.init_node("robot_description_test_client", anonymous=True)
    lock = threading.Lock()
    rec: dict[str, list] = {"joint_states": [], "tf": [], "tf_static": [], "markers": [], "model_states": []}

    def pose(p):
        return [p.position.x, p.position.y, p.position.z, p.orientation.w, p.orientation.x, p.orientation.y,
                p.orientation.z]

    def transforms(msg):
        return [[t.header.stamp.to_nsec(), t.header.frame_id, t.child_frame_id,
                 [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z,
                  t.transform.rotation.w, t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z]]
                for t in msg.transforms]

    def on(key, convert):
        def callback(msg):
            item = [time.monotonic(), convert(msg)]
            with lock:
                rec[key].append(item)
        return callback

    subscribers = [
        rospy.Subscriber(joint_states, JointState, on("joint_states", lambda m: [
            m.header.stamp.to_nsec(), list(m.name), list(m.position)]), queue_size=1000),
        rospy.Subscriber("/tf", TFMessage, on("tf", transforms), queue_size=1000),
        rospy.Subscriber("/tf_static", TFMessage, on("tf_static", transforms), queue_size=100),
        rospy.Subscriber(MARKERS, MarkerArray, on("markers", lambda m: [
            [k.header.stamp.to_nsec(), k.header.frame_id, k.ns, k.id, k.action, k.type, k.text, pose(k.pose),
             [k.scale.x, k.scale.y, k.scale.z]] for k in m.markers]), queue_size=1000),
        rospy.Subscriber("/gazebo/model_states", ModelStates, on("model_states", lambda m: [
            list(m.name), [pose(p) for p in m.pose], [[t.linear.x, t.linear.y, t.linear.z] for t in m.twist]]),
            queue_size=1000)]
    publishers = {}
    out = []

    def wait(condition, what: str, timeout_s: float = 60.0):
        """Poll ``condition`` (under the record's lock) until it holds; exit saying ``what`` otherwise."""
        deadline = time.monotonic() + timeout_s
        while True:
            with lock:
                if condition():
                    return
            if time.monotonic() > deadline:
                with lock:
                    counts = {key: len(items) for key, items in rec.items()}
                raise SystemExit(f"waited {timeout_s:g} s for {what}; recorded {counts}")
            time.sleep(0.02)

    def joint_values(name):
        return [positions[names.index(name)] for _, (_, names, positions) in rec["joint_states"] if name in names]

    def marker_id(name):
        """The marker id of object ``name`` (its label's text is the name), or None."""
        return next((m[3] for _, markers in rec["markers"] for m in markers
                     if m[2] == "spawned_object_names" and m[6] == name), None)

    def holds(until: dict) -> bool:
        """Whether every condition of an ``until`` step holds on what is recorded so far."""
        for name, value in until.get("above", {}).items():
            if not joint_values(name) or not joint_values(name)[-1] > value:
                return False
        for name, span in until.get("moved", {}).items():
            values = joint_values(name)
            if not values or max(values) - min(values) < span:
                return False
        if len(rec["tf"]) < until.get("tf", 0):
            return False
        if "at_rest" in until:  # {"name", "z", "tol", "count"}: so many shape markers, the last five at z
            rest = until["at_rest"]
            shown = [m for _, markers in rec["markers"] for m in markers
                     if m[2] == "spawned_objects" and m[3] == marker_id(rest["name"]) and m[4] == 0]
            if len(shown) < rest["count"] or any(abs(m[7][2] - rest["z"]) > rest["tol"] for m in shown[-5:]):
                return False
        if "deleted" in until:  # its shape's and its label's DELETE markers have come, then `after`
            # model_states messages (loop time at 100 Hz: a marker showing it again would be among them)
            deleted = {m[2]: t for t, markers in rec["markers"] for m in markers
                       if m[3] == marker_id(until["deleted"]) and m[4] == 2}
            if set(deleted) != {"spawned_objects", "spawned_object_names"}:
                return False
            if len([t for t, _ in rec["model_states"] if t > max(deleted.values())]) < until.get("after", 0):
                return False
        return True

    for step in steps:
        kind = step["do"]
        if kind == "param":
            out.append(rospy.get_param(step["name"], None))
        elif kind == "connected":
            # Every subscriber connected to its publisher, and the joint states and /tf coming in: what
            # follows is recorded from its start.
            wait(lambda: all(s.get_num_connections() for s in subscribers) and rec["joint_states"] and rec["tf"],
                 "the subscribers to connect and the joint states and /tf to come in")
            out.append(None)
        elif kind == "command":
            topic = step["topic"]
            if topic not in publishers:
                publishers[topic] = rospy.Publisher(topic, Float64, queue_size=1, latch=True)
                wait(lambda: publishers[topic].get_num_connections(), f"the node to subscribe to {topic}")
            publishers[topic].publish(step["value"])
            out.append(None)
        elif kind == "spawn":
            rospy.wait_for_service("/gazebo/spawn_urdf_model", timeout=30)
            p = Pose()
            p.position.x, p.position.y, p.position.z = step["xyz"]
            p.orientation.w = 1.0
            r = rospy.ServiceProxy("/gazebo/spawn_urdf_model", SpawnModel)(
                model_name=step["name"], model_xml=step["xml"], robot_namespace="", initial_pose=p,
                reference_frame="")
            out.append([r.success, r.status_message])
        elif kind == "delete":
            r = rospy.ServiceProxy("/gazebo/delete_model", DeleteModel)(model_name=step["name"])
            out.append([r.success, r.status_message])
        elif kind == "until":
            wait(lambda: holds(step), f"{step}")
            out.append(None)
        elif kind == "graph":
            publishers_, subscribers, _ = rosgraph.Master(rospy.get_name()).getSystemState()
            out.append({"publishers": dict(publishers_), "subscribers": dict(subscribers)})
    with lock:
        return {"steps": out, **rec}


# ------------------------------------------------------------------------------------------------
# The tests
# ------------------------------------------------------------------------------------------------

if __name__ != "__main__":
    import numpy as np
    import pytest
    import yaml

    from tests.ros.conftest import Master, Probe, ros_environment, run, wait_for_topic

    class Graph:
        """A master on a free port and the processes started against it (stopped at exit)."""

        def __init__(self, folder: Path) -> None:
            self.folder = folder
            env = ros_environment(folder, 0)
            for name in ("DISPLAY", "WAYLAND_DISPLAY"):  # no display: --rviz must say so and serve on
                env.pop(name, None)
            self.env = env
            self.processes: list[subprocess.Popen] = []
            # Up once it answers with its own pid; retried on another port after a failed bind.
            self.master_process = Master(env)
            self.port = self.master_process.port
            self.probe = Probe(env)

        def master(self):
            import rosgraph
            return rosgraph.Master("/robot_description_test", master_uri=self.env["ROS_MASTER_URI"])

        def master_online(self) -> bool:
            return self.master().is_online()

        def start(self, *args: str, log: str | None = None) -> subprocess.Popen:
            out = open(self.folder / log, "w") if log else subprocess.DEVNULL
            process = subprocess.Popen(list(args), env=self.env, stdout=out, stderr=subprocess.STDOUT, text=True)
            self.processes.append(process)
            return process

        def serve(self, *args: str) -> subprocess.Popen:
            return self.start(sys.executable, "-m", "jointctl.cli", "serve", *args, log="serve.log")

        def client(self, joint_states: str, steps: list[dict]) -> dict:
            result = run(self.env, sys.executable, str(HERE), "client", joint_states, json.dumps(steps), timeout=120)
            return json.loads(result.stdout.strip().splitlines()[-1])

        @staticmethod
        def stop(process: subprocess.Popen, sig=signal.SIGTERM) -> int:
            if process.poll() is None:
                process.send_signal(sig)
                try:
                    process.wait(15)
                except subprocess.TimeoutExpired:
                    process.kill()
            return process.wait()

        def close(self) -> None:
            self.probe.close()
            for process in reversed(self.processes):
                self.stop(process, signal.SIGINT if "robot_state_publisher" in str(process.args) else signal.SIGTERM)
            self.master_process.stop()  # the master last

    @contextmanager
    def graph(folder: Path):
        g = Graph(folder)
        try:
            yield g
        finally:
            g.close()

    def expanded(robot: str) -> str:
        from jointctl.model.loader import expand_xacro
        from jointctl.model.package_paths import PackageResolver
        from jointctl.scenario.spec import scenario_for_robot

        return expand_xacro(Path(scenario_for_robot(robot, "position").robot.description), PackageResolver(()), {})

    # -- TF composed by hand, at one stamp -----------------------------------------------------
    def _quat_matrix(w, x, y, z) -> np.ndarray:
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])

    def _static(rec) -> dict:
        return {child: (parent, pq) for _, items in rec["tf_static"] for _, parent, child, pq in items}

    def tf_at_stamps(rec, root: str, link: str) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """``{stamp_ns: (position, rotation)}`` of ``link`` in ``root`` for every stamp of /tf, composed
        from that stamp's moving transforms and the static ones (only complete chains)."""
        static = _static(rec)
        by_stamp: dict[int, dict] = {}
        for _, items in rec["tf"]:
            for stamp, parent, child, pq in items:
                by_stamp.setdefault(stamp, {})[child] = (parent, pq)
        poses = {}
        for stamp, moving in by_stamp.items():
            p, r, frame = np.zeros(3), np.eye(3), link
            while frame != root:
                edge = moving.get(frame) or static.get(frame)
                if edge is None:
                    break
                parent, pq = edge
                # pose_in_parent ∘ (current pose in frame)
                rp = _quat_matrix(*pq[3:])
                p, r = rp @ p + np.array(pq[:3]), rp @ r
                frame = parent
            else:
                poses[stamp] = (p, r)
        return poses

    def joint_states_by_stamp(rec) -> dict[int, dict[str, float]]:
        return {stamp: dict(zip(names, positions)) for _, (stamp, names, positions) in rec["joint_states"]}

    # -- one_dof, served with --rviz, no display -----------------------------------------------
    @pytest.fixture(scope="module")
    def one_dof(tmp_path_factory):
        folder = tmp_path_factory.mktemp("one_dof")
        with graph(folder) as g:
            serve = g.serve("one_dof", "--controllers", "position", "--rviz")
            wait_for_topic(g.env, ONE_DOF_STATES)
            wait_for_topic(g.env, "/tf")  # robot_state_publisher, started by jointctl, is up
            rec = g.client(ONE_DOF_STATES, [
                {"do": "param", "name": "/robot_description"},                                    # 0
                {"do": "connected"},
                {"do": "command", "topic": "/one_DOF_robot/joint1_position_controller/command", "value": -0.2},
                # From -0.5 m towards -0.2 m (P alone: it rests m·g/Kp = 25 mm short), 60 TF messages in.
                {"do": "until", "above": {"joint1": -0.24}, "tf": 60},
                {"do": "spawn", "name": "crate", "xml": BOX_URDF, "xyz": [0.6, 0.0, 1.5]},         # 4
                # It falls 1.4 m in 0.53 s (26 markers at 50 Hz), then rests on the floor: 31 markers, the
                # last five (0.1 s) at its half height.
                {"do": "until", "at_rest": {"name": "crate", "z": 0.1, "tol": 0.005, "count": 31}},
                {"do": "delete", "name": "crate"},                                                 # 6
                {"do": "until", "deleted": "crate", "after": 50},
                {"do": "graph"},                                                                   # 8
            ])
            serving = serve.poll() is None
            status = g.stop(serve)
            # jointctl stopped robot_state_publisher on its way out: it is no longer on the graph.
            deadline = time.monotonic() + 10
            while True:
                nodes = {n for _, names in g.master().getSystemState()[1] for n in names}
                if "/robot_state_publisher" not in nodes or time.monotonic() > deadline:
                    break
                time.sleep(0.1)
            log = (folder / "serve.log").read_text()
        yield {"rec": rec, "serving": serving, "status": status, "log": log, "nodes_after": nodes}

    def test_robot_description_is_the_expanded_urdf(one_dof):
        description = one_dof["rec"]["steps"][0]
        assert description == expanded("one_dof")
        assert '<link name="link2">' in description and "xacro:" not in description

    def test_link2_tf_from_robot_state_publisher_follows_joint1_at_the_same_stamp(one_dof):
        rec = one_dof["rec"]
        states = joint_states_by_stamp(rec)
        tf = tf_at_stamps(rec, "world", "link2")
        # Every TF stamp is a joint_states stamp (robot_state_publisher keeps the stamp it is given).
        recorded = [s for s in tf if s >= min(states)]
        matched = [s for s in recorded if s in states]
        assert len(recorded) > 40 and len(matched) == len(recorded), (len(recorded), len(matched))
        q = np.array([states[s]["joint1"] for s in matched])
        position = np.array([tf[s][0] for s in matched])
        assert q.min() < -0.45 and q.max() > -0.25  # the piston moved while recorded
        np.testing.assert_allclose(position[:, 2], 1.0 + q, rtol=0, atol=TOL_M)
        np.testing.assert_allclose(position[:, :2], 0.0, rtol=0, atol=TOL_M)
        for s in matched:
            np.testing.assert_allclose(tf[s][1], np.eye(3), rtol=0, atol=1e-12)

    def test_a_spawned_object_appears_in_the_markers_with_model_states_pose(one_dof):
        rec = one_dof["rec"]
        assert rec["steps"][4][0], rec["steps"][4]
        # Marker fields: stamp, frame, ns, id, action (0 ADD, 2 DELETE), type, text, pose, scale.
        labels = [m for _, markers in rec["markers"] for m in markers if m[2] == "spawned_object_names"]
        marker_id = next(m[3] for m in labels if m[6] == "crate")
        shown = [(t, m) for t, markers in rec["markers"] for m in markers
                 if m[2] == "spawned_objects" and m[3] == marker_id and m[4] == 0]
        assert len(shown) > 30
        _, frame, _, _, _, kind, text, _, scale = shown[0][1]
        assert frame == "world" and kind == 1 and text == ""  # a CUBE (rviz ignores, and warns of, text)
        np.testing.assert_allclose(scale, [0.2, 0.2, 0.2], rtol=0, atol=1e-12)
        # Its name floats above it: 0.1 m (half the box) + 0.1 m (the letters' height) over its centre.
        label = next(m for m in labels if m[3] == marker_id and m[4] == 0 and m[0] == shown[-1][1][0])
        assert label[5] == 9 and label[6] == "crate"  # TEXT_VIEW_FACING
        np.testing.assert_allclose(label[7][:3], np.array(shown[-1][1][7][:3]) + [0, 0, 0.2], rtol=0, atol=1e-12)
        z = np.array([m[7][2] for _, m in shown])
        assert z[0] > 1.3 and z[-1] == pytest.approx(0.1, abs=0.005)  # live: it falls to the floor
        # The same cycle's pose, whenever each message was received. While the crate falls, model_states
        # says which cycle it is from: from rest, each MuJoCo step takes g·h off its vertical speed, so
        # -v/(g·h) counts the steps since it was spawned; a marker's stamp counts loop time in steps of h.
        # The marker and model_states of one cycle have the same pose exactly, and one step moves it by
        # millimetres: the pairs of equal poses give one offset between the two counts, the same for all;
        # then every falling marker whose cycle's model_states came (a publisher may drop one under load)
        # has that pose.
        g, h = 9.81, 0.001
        falling = {}  # steps since the spawn -> the crate's pose in model_states
        for _, (names, poses, twists) in rec["model_states"]:
            k = names.index("crate") if "crate" in names else None
            if k is not None and twists[k][2] < -0.1 and poses[k][2] > 0.2:  # falling, above the floor
                falling[round(-twists[k][2] / (g * h))] = np.array(poses[k])
        first = shown[0][1][0]
        marked = {round((m[0] - first) * 1e-9 / h): np.array(m[7]) for _, m in shown}  # loop steps -> pose
        offsets = {n - c for c, pose in marked.items() for n, state in falling.items()
                   if np.abs(state[:3] - pose[:3]).max() < TOL_M}
        assert len(offsets) == 1, offsets  # one offset: each equal pair is of one cycle
        offset = offsets.pop()
        paired = [(pose, falling[c + offset]) for c, pose in marked.items() if c + offset in falling]
        assert len(paired) >= 3, (len(paired), len(falling), len(marked))
        for pose, state in paired:
            np.testing.assert_allclose(pose, state, rtol=0, atol=TOL_M)
        # Deleted: the next message deletes its marker, and it is not shown again.
        assert rec["steps"][6][0], rec["steps"][6]
        deleted = {m[2]: t for t, markers in rec["markers"] for m in markers if m[3] == marker_id and m[4] == 2}
        assert set(deleted) == {"spawned_objects", "spawned_object_names"}
        assert all(t < deleted["spawned_objects"] for t, _ in shown)

    def test_rviz_without_a_display_says_so_in_one_line_and_the_node_serves_on(one_dof):
        lines = [line for line in one_dof["log"].splitlines() if line.startswith("jointctl: --rviz:")]
        assert len(lines) == 1, one_dof["log"][-2000:]
        line = lines[0]
        assert "robot_state_publisher started (joint_states:=/one_DOF_robot/joint_states)" in line
        assert "rviz is not installed" in line or "no display" in line
        assert line.endswith("serving")
        assert one_dof["serving"] and one_dof["status"] == 0
        graph_state = one_dof["rec"]["steps"][8]
        assert "/robot_state_publisher" in graph_state["subscribers"][ONE_DOF_STATES]
        assert "/robot_state_publisher" in graph_state["publishers"]["/tf"]
        assert "/robot_state_publisher" not in one_dof["nodes_after"]

    # -- arm7dof, robot_state_publisher started as the book's launch files do ------------------
    ARM_TARGETS = {"joint0": 0.5, "joint1": 0.3, "joint3": -0.5, "joint5": 0.6, "joint6": -0.6}

    @pytest.fixture(scope="module")
    def arm(tmp_path_factory):
        from jointctl.ros.robot_description import find_robot_state_publisher, robot_state_publisher_command

        rsp = find_robot_state_publisher()
        if rsp is None:
            pytest.fail("robot_state_publisher is not installed: run make ros (scripts/install_ros.sh)")
        with graph(tmp_path_factory.mktemp("arm7dof")) as g:
            g.serve("arm7dof", "--controllers", "position")
            wait_for_topic(g.env, ARM_STATES)
            g.start(*robot_state_publisher_command(rsp, ARM_STATES), log="rsp.log")
            wait_for_topic(g.env, "/tf")
            steps = [{"do": "command", "topic": f"/arm7dof/{joint}_position_controller/command", "value": value}
                     for joint, value in ARM_TARGETS.items()]
            # Recorded from before the commands until joint0 and joint6 have each moved 0.15 rad of their
            # 0.5 and 0.6 rad, and 60 TF messages are in.
            yield g.client(ARM_STATES, [{"do": "param", "name": "/robot_description"}, {"do": "connected"}, *steps,
                                        {"do": "until", "moved": {"joint0": 0.15, "joint6": 0.15}, "tf": 60}])

    def test_the_arms_flange_tf_is_the_models_forward_kinematics(arm):
        from jointctl.model.dynamics import RobotDynamics
        from jointctl.model.loader import load_robot_model
        from jointctl.scenario.spec import scenario_for_robot

        assert arm["steps"][0] == expanded("arm7dof")
        robot = load_robot_model(scenario_for_robot("arm7dof", "position").robot.description)
        dynamics = RobotDynamics(robot)
        flange = dynamics.frame("ft_sensor_link")
        states = joint_states_by_stamp(arm)
        tf = tf_at_stamps(arm, "world", "ft_sensor_link")
        matched = [s for s in tf if s in states]
        assert len(matched) > 30 and len(matched) == len([s for s in tf if s >= min(states)])
        q = np.array([[states[s][j] for j in dynamics.joint_names] for s in matched])
        assert np.ptp(q[:, 0]) > 0.1 and np.ptp(q[:, 6]) > 0.1  # the arm moved while recorded
        worst_p = worst_r = 0.0
        for s, qs in zip(matched, q):
            dynamics.set_pose(qs, inertia=False)
            worst_p = max(worst_p, np.abs(tf[s][0] - flange.position).max())
            worst_r = max(worst_r, np.abs(tf[s][1] - flange.rotation).max())
        assert worst_p < TOL_M and worst_r < TOL_M, (worst_p, worst_r)

    # -- the shipped rviz configuration ----------------------------------------------------------
    def test_the_shipped_rviz_config_shows_the_model_tf_and_markers_in_the_root_frame():
        from jointctl.ros.robot_description import OBJECT_MARKERS_TOPIC, RVIZ_CONFIG, rviz_config_text

        config = yaml.safe_load(RVIZ_CONFIG.read_text())
        manager = config["Visualization Manager"]
        displays = {d["Class"]: d for d in manager["Displays"]}
        assert displays["rviz/RobotModel"]["Robot Description"] == "robot_description"
        assert "rviz/TF" in displays
        assert displays["rviz/MarkerArray"]["Marker Topic"] == OBJECT_MARKERS_TOPIC
        assert manager["Global Options"]["Fixed Frame"] == "world"
        adapted = yaml.safe_load(rviz_config_text("base_link"))
        assert adapted["Visualization Manager"]["Global Options"]["Fixed Frame"] == "base_link"

    def test_rviz_is_fitted_to_the_robot_where_the_node_starts():
        from jointctl.ros.robot_description import rviz_config_text, robot_bounds
        from jointctl.ros.rviz_layout import rviz_layout
        from jointctl.scenario.session import Session
        from jointctl.scenario.spec import load_scenario

        with Session(load_scenario("one_dof_step")) as session:  # the piston at -0.2 m
            lowest, highest = robot_bounds(session)
        # link1 (the base, from the floor) to the sensor disk's top: 1 m + q + 1 m link2 + the disk.
        assert lowest[2] == pytest.approx(0.0, abs=1e-6) and 1.8 <= highest[2] <= 1.9
        layout = rviz_layout(lowest, highest, (1920, 1080))
        config = yaml.safe_load(rviz_config_text("world", layout))
        assert config["Visualization Manager"]["Views"]["Current"]["Focal Point"]["Z"] == pytest.approx(
            (lowest[2] + highest[2]) / 2, abs=1e-3)
        assert config["Window Geometry"]["Width"] == layout.window_px[2]
        assert config["Visualization Manager"]["Global Options"]["Fixed Frame"] == "world"


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "client":
        print(json.dumps(_client(sys.argv[2], json.loads(sys.argv[3]))))
    else:
        raise SystemExit("usage: test_robot_description.py client JOINT_STATES STEPS_JSON")

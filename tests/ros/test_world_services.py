"""Gazebo's world services against jointctl serve, on a real master, with real rospy service clients.

The chapter's drop-weight steps over ROS: the book's weight file (tests/sim/data, SDF 1.4 with its
attribute-style cylinder) spawned at z = 4 m over the position-controlled piston held at -0.2 m, under
gravity -5 m/s² (Figure 11.5), then gravity changed to -9.8 m/s². Theory at rest, with the piston
(1 kg), the sensor plate (0.01 kg) and the weight (10 kg) on a P loop of Kp 400:
    actuator effort = (1 + 0.01 + 10)·|g|,  sensor force z = -(0.01 + 10)·|g|,
    joint = -0.2 - effort/Kp,  weight centre = 2 + joint + 0.005 (plate) + 0.1 (half the weight).

Run as a script (``python test_world_services.py client STEPS_JSON``) this file is the client: one
rospy node that calls the services and watches ``/gazebo/model_states``, ``/ft_sensor_topic`` and
the joint states, printing one JSON result line.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve()
BOOK_WEIGHT = HERE.parents[1] / "sim" / "data" / "cylinder_model-1_4.sdf"
JOINT_STATES = "/one_DOF_robot/joint_states"
COMMAND = "/one_DOF_robot/joint1_position_controller/command"
KP = 400.0
CONTACT_N = 10.0  # a force reading over this is a weight's: the 10 g plate alone reads 0.1 N
M_PISTON, M_PLATE, M_WEIGHT = 1.0, 0.01, 10.0


def theory(g: float, command: float = -0.2) -> dict:
    effort = (M_PISTON + M_PLATE + M_WEIGHT) * g
    joint = command - effort / KP
    return {"effort": effort, "force_z": -(M_PLATE + M_WEIGHT) * g, "joint": joint,
            "weight_z": 2.0 + joint + 0.005 + 0.1}


# ------------------------------------------------------------------------------------------------
# The client (runs in its own process: rospy allows one node per process)
# ------------------------------------------------------------------------------------------------

def _client(steps: list[dict]) -> dict:
    import threading

    import rospy
    from gazebo_msgs.msg import ModelStates
    from gazebo_msgs.srv import DeleteModel, GetPhysicsProperties, SetPhysicsProperties, SpawnModel
    from geometry_msgs.msg import Pose, WrenchStamped
    from sensor_msgs.msg import JointState

    rospy.init_node("world_services_test_client", anonymous=True)
    lock = threading.Lock()
    force: list[tuple[float, float]] = []  # (wall time, force z)
    joint: list[tuple[float, float, float]] = []  # (wall time, position, effort)
    states: list[tuple[float, list, list, list]] = []  # (wall time, names, poses, twists)

    def on_force(msg):
        with lock:
            force.append((time.monotonic(), msg.wrench.force.z))

    def on_joint(msg):
        with lock:
            joint.append((time.monotonic(), msg.position[0], msg.effort[0]))

    def on_states(msg):
        poses = [[p.position.x, p.position.y, p.position.z, p.orientation.w, p.orientation.x, p.orientation.y,
                  p.orientation.z] for p in msg.pose]
        twists = [[t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z] for t in msg.twist]
        with lock:
            states.append((time.monotonic(), list(msg.name), poses, twists))

    rospy.Subscriber("/ft_sensor_topic", WrenchStamped, on_force, queue_size=100)
    rospy.Subscriber(JOINT_STATES, JointState, on_joint, queue_size=100)
    rospy.Subscriber("/gazebo/model_states", ModelStates, on_states, queue_size=100)
    proxies = {}

    def proxy(name, kind):
        if name not in proxies:
            rospy.wait_for_service(name, timeout=60)
            proxies[name] = rospy.ServiceProxy(name, kind)
        return proxies[name]

    def physics_dict(r):
        o = r.ode_config
        return {"time_step": r.time_step, "pause": r.pause, "max_update_rate": r.max_update_rate,
                "gravity": [r.gravity.x, r.gravity.y, r.gravity.z], "success": r.success,
                "status_message": r.status_message,
                "ode": {k: getattr(o, k) for k in o.__slots__}}

    out = []
    for step in steps:
        kind = step["do"]
        started = time.monotonic()
        if kind == "get":
            out.append(physics_dict(proxy("/gazebo/get_physics_properties", GetPhysicsProperties)()))
        elif kind == "set":
            current = proxy("/gazebo/get_physics_properties", GetPhysicsProperties)()
            req = {"time_step": current.time_step, "max_update_rate": current.max_update_rate,
                   "gravity": current.gravity, "ode_config": current.ode_config}
            for key in ("time_step", "max_update_rate"):
                if key in step:
                    req[key] = step[key]
            if "gravity" in step:
                req["gravity"].x, req["gravity"].y, req["gravity"].z = step["gravity"]
            if step.get("ode_zero"):
                req["ode_config"] = type(current.ode_config)()
            r = proxy("/gazebo/set_physics_properties", SetPhysicsProperties)(**req)
            out.append({"success": r.success, "status_message": r.status_message, "done": time.monotonic()})
        elif kind == "spawn":
            pose = Pose()
            pose.position.x, pose.position.y, pose.position.z = step.get("xyz", (0, 0, 4))
            pose.orientation.w = 1.0
            service = "/gazebo/spawn_urdf_model" if step.get("urdf") else "/gazebo/spawn_sdf_model"
            r = proxy(service, SpawnModel)(model_name=step["name"], model_xml=step["xml"], robot_namespace="",
                                           initial_pose=pose, reference_frame=step.get("frame", ""))
            out.append({"success": r.success, "status_message": r.status_message, "at": started,
                        "done": time.monotonic()})
        elif kind == "delete":
            r = proxy("/gazebo/delete_model", DeleteModel)(model_name=step["name"])
            out.append({"success": r.success, "status_message": r.status_message, "at": started,
                        "done": time.monotonic()})
        elif kind == "command":
            pub = rospy.Publisher(COMMAND, __import__("std_msgs.msg", fromlist=["Float64"]).Float64, queue_size=1,
                                  latch=True)
            deadline = started + 30
            while pub.get_num_connections() == 0 and time.monotonic() < deadline:
                time.sleep(0.01)
            pub.publish(step["value"])
            out.append({"at": started, "done": time.monotonic()})
        elif kind == "settle":
            # Until the last second of samples, all received after step `since` was answered (all of
            # them under its effect), has force varying by less than `spread` N and the joint by less
            # than 1 mm, with (`loaded`) every force reading a weight's (over CONTACT_N: not the
            # empty plate's before a spawned weight lands), or `timeout` s: then the means of that second.
            deadline = started + step.get("timeout", 90.0)
            since = out[step["since"]]["done"]
            result = {"settled": False}
            while time.monotonic() < deadline:
                time.sleep(0.1)
                now = time.monotonic()
                if now - 1.0 < since:
                    continue
                with lock:
                    f = [v for t, v in force if t > now - 1.0]
                    j = [(p, e) for t, p, e in joint if t > now - 1.0]
                if step.get("loaded") and not all(abs(v) > CONTACT_N for v in f):
                    continue
                if len(f) > 100 and len(j) > 10 and max(f) - min(f) < step.get("spread", 1.0) \
                        and max(p for p, _ in j) - min(p for p, _ in j) < 1e-3:
                    result = {"settled": True, "force_z": sum(f) / len(f), "joint": sum(p for p, _ in j) / len(j),
                              "effort": sum(e for _, e in j) / len(j), "after_s": now - started}
                    break
            with lock:
                last = states[-1] if states else None
            result["states"] = None if last is None else {"names": last[1], "poses": last[2], "twists": last[3]}
            out.append(result)
        elif kind == "wait":
            time.sleep(step["s"])
            out.append({})
        elif kind == "gone":
            # Model states from the first that lists `witness` (spawned after `name` was deleted, so
            # each message listing it was published after the delete, whenever it arrives; one still
            # on its way from before cannot list it) until `count` of them list it: the names seen.
            deadline = started + step.get("timeout", 60.0)
            while True:
                with lock:
                    seen = [names for _, names, _, _ in states]
                first = next((k for k, names in enumerate(seen) if step["witness"] in names), None)
                after = [] if first is None else seen[first:]
                if len([n for n in after if step["witness"] in n]) >= step["count"]:
                    break
                if time.monotonic() > deadline:
                    raise SystemExit(f"waited for {step['count']} model_states listing {step['witness']!r}; "
                                     f"{len(after)} so far")
                time.sleep(0.05)
            out.append({"names": sorted({name for n in after for name in n}), "count": len(after),
                        "with": len([n for n in after if step["name"] in n])})
        elif kind == "watch":
            # Model states received since step `since` started: the named model's z and the names
            # seen; for at least `s` s and until the `until` condition on that z holds ("drop": it
            # fell that far from where first seen; "below": the last z is below that; "near": [z,
            # tol]: the last z is that close), or `timeout` s.
            since = out[step["since"]]["at"]
            until, deadline = step.get("until", {}), started + step.get("timeout", 20.0)

            def holds(z):
                if not z:
                    return not until and time.monotonic() > since
                if "drop" in until:
                    return min(z) < z[0] - until["drop"]
                if "below" in until:
                    return z[-1] < until["below"]
                if "near" in until:
                    return abs(z[-1] - until["near"][0]) < until["near"][1]
                return True

            time.sleep(step.get("s", 0.0))
            while True:
                with lock:
                    seen = [(t, n, p) for t, n, p, _ in states if t >= since]
                z = [p[n.index(step["name"])][2] for _, n, p in seen if step["name"] in n]
                if (seen and holds(z)) or time.monotonic() > deadline:
                    break
                time.sleep(0.05)
            names = sorted({name for _, n, _ in seen for name in n})
            out.append({"names": names, "z": z, "count": len(seen)})
    return {"steps": out}


# ------------------------------------------------------------------------------------------------
# The tests
# ------------------------------------------------------------------------------------------------

if __name__ != "__main__":
    import pytest

    from tests.ros.conftest import run

    BAD_JOINT = """<sdf version="1.6"><model name="two"><link name="a"><collision name="c"><geometry><box>
      <size>0.1 0.1 0.1</size></box></geometry></collision></link><link name="b"/>
      <joint name="hinge" type="revolute"><parent>a</parent><child>b</child></joint></model></sdf>"""
    BAD_MESH = """<sdf version="1.6"><model name="m"><link name="l"><collision name="c"><geometry>
      <mesh><uri>model://m/meshes/m.dae</uri></mesh></geometry></collision></link></model></sdf>"""
    URDF_BOX = """<robot name="crate"><link name="crate_link"><inertial><mass value="2.0"/>
      <inertia ixx="0.013333" ixy="0" ixz="0" iyy="0.013333" iyz="0" izz="0.013333"/></inertial>
      <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link></robot>"""

    def client(env, steps: list[dict], timeout: float = 300.0) -> list[dict]:
        result = run(env, sys.executable, str(HERE), "client", json.dumps(steps), timeout=timeout)
        return json.loads(result.stdout.strip().splitlines()[-1])["steps"]

    #: Loop time per wall-clock time for the drop: the statics asserted do not depend on the pace, and
    #: the loaded piston rings down at ζ·ωn = 0.45/s of loop time (some 30 s of it for the two settles).
    SPEED = 3.0

    @pytest.mark.slow
    def test_the_books_weight_dropped_through_spawn_sdf_model_then_gravity_changed(ros_env, serve):
        serve("one_dof", "--controllers", "position", "--speed", str(SPEED), wait_topic=JOINT_STATES)
        # Settles are read from samples received after the change they wait for; a watch lasts until
        # what it looks for is seen. After the delete, a witness spawned once it was answered marks
        # the model_states published after it (see the client's "gone").
        steps = client(ros_env, [
            {"do": "get"},
            {"do": "command", "value": -0.2},
            {"do": "set", "gravity": [0.0, 0.0, -5.0]},                      # 2
            {"do": "settle", "since": 2, "timeout": 60},
            {"do": "spawn", "name": "cyl_weight", "xml": BOOK_WEIGHT.read_text(), "xyz": [0, 0, 4]},  # 4
            {"do": "watch", "since": 4, "name": "cyl_weight", "until": {"drop": 0.5}},  # 5: the fall
            {"do": "settle", "since": 4, "loaded": True, "timeout": 120},   # 6: at rest under -5
            {"do": "set", "gravity": [0.0, 0.0, -9.8]},                     # 7
            {"do": "settle", "since": 7, "loaded": True, "timeout": 120},   # 8: at rest under -9.8
            {"do": "get"},                                                  # 9
            {"do": "delete", "name": "cyl_weight"},                         # 10
            {"do": "spawn", "name": "witness", "xml": URDF_BOX, "xyz": [2.0, 2.0, 0.1], "urdf": True},  # 11
            {"do": "gone", "name": "cyl_weight", "witness": "witness", "count": 25},  # 12
            {"do": "settle", "since": 10, "timeout": 60},                   # 13: unloaded again
        ])
        before, set5, spawn, fall, rest5, set98, rest98, after, delete, witness, gone, unloaded = (
            steps[0], steps[2], steps[4], steps[5], steps[6], steps[7], steps[8], steps[9], steps[10], steps[11],
            steps[12], steps[13])
        # get: the loop's step and rate, the serve's gravity, MuJoCo's solver settings.
        assert before["success"] and before["time_step"] == pytest.approx(0.001)
        assert before["max_update_rate"] == pytest.approx(1000.0 * SPEED) and before["pause"] is False
        assert before["gravity"] == pytest.approx([0.0, 0.0, -9.81])
        assert before["ode"]["sor_pgs_iters"] > 0
        assert set5["success"], set5
        # The book's file loads as it is; the reply says what was adapted for MuJoCo.
        assert spawn["success"], spawn
        message = spawn["status_message"]
        assert "cylinder r 0.5 m, length 0.2 m, 10 kg" in message
        assert "inertia (0.01, 0.01, 0.01)" in message and "attributes" in message and "mu 50" in message
        # model_states: the weight appears near 4 m and falls.
        assert "cyl_weight" in fall["names"] and "one_DOF_robot" in fall["names"]
        assert fall["z"][0] > 3.5 and min(fall["z"]) < fall["z"][0] - 0.5
        for rest, g in ((rest5, 5.0), (rest98, 9.8)):
            expected = theory(g)
            assert rest["settled"], rest
            assert rest["force_z"] == pytest.approx(expected["force_z"], rel=0.01)
            assert rest["effort"] == pytest.approx(expected["effort"], rel=0.01)
            assert rest["joint"] == pytest.approx(expected["joint"], abs=0.003)
            names, poses, twists = rest["states"]["names"], rest["states"]["poses"], rest["states"]["twists"]
            k = names.index("cyl_weight")
            assert poses[k][2] == pytest.approx(expected["weight_z"], abs=0.005)  # resting on the disk
            assert poses[k][:2] == pytest.approx([0.0, 0.0], abs=0.01)
            assert max(abs(v) for v in twists[k]) < 0.05
            base = names.index("one_DOF_robot")
            assert poses[base][:3] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
        assert set98["success"] and "-9.8" in set98["status_message"]
        assert after["gravity"] == pytest.approx([0.0, 0.0, -9.8])
        # delete_model: in no model_states published after it, and the piston carries only itself again.
        assert delete["success"], delete
        assert witness["success"], witness
        assert gone["with"] == 0 and "cyl_weight" not in gone["names"] and "one_DOF_robot" in gone["names"]
        assert unloaded["settled"]
        assert unloaded["force_z"] == pytest.approx(-M_PLATE * 9.8, abs=0.01)
        assert unloaded["joint"] == pytest.approx(-0.2 - (M_PISTON + M_PLATE) * 9.8 / KP, abs=0.002)

    def test_refused_models_spawn_nothing_and_physics_changes_are_checked(ros_env, serve):
        serve("one_dof", "--controllers", "position", wait_topic=JOINT_STATES)
        steps = client(ros_env, [
            {"do": "spawn", "name": "crate", "xml": URDF_BOX, "xyz": [1.0, 0.0, 0.5], "urdf": True},  # 0
            {"do": "watch", "since": 0, "name": "crate", "until": {"below": 0.4}},                    # 1
            {"do": "spawn", "name": "hinged", "xml": BAD_JOINT, "xyz": [0, 0, 3]},                     # 2
            {"do": "spawn", "name": "meshy", "xml": BAD_MESH, "xyz": [0, 0, 3]},                       # 3
            {"do": "spawn", "name": "crate", "xml": URDF_BOX, "xyz": [2.0, 0, 0.5], "urdf": True},     # 4
            {"do": "spawn", "name": "far", "xml": URDF_BOX, "frame": "link2", "urdf": True},           # 5
            {"do": "watch", "since": 2, "name": "crate", "until": {"near": [0.1, 0.01]}},             # 6
            {"do": "set", "time_step": 0.002, "gravity": [0.0, 0.0, -1.0]},                            # 7
            {"do": "set", "max_update_rate": 0.0, "gravity": [0.0, 0.0, -1.0]},                        # 8
            {"do": "get"},                                                                             # 9
            {"do": "set", "gravity": [0.5, 0.0, -9.0], "ode_zero": True},                              # 10
            {"do": "get"},                                                                             # 11
            {"do": "delete", "name": "one_DOF_robot"},                                                 # 12
            {"do": "delete", "name": "nothing_here"},                                                  # 13
            {"do": "delete", "name": "crate"},                                                         # 14
            {"do": "spawn", "name": "witness", "xml": URDF_BOX, "xyz": [2.0, 2.0, 0.1], "urdf": True},  # 15
            {"do": "gone", "name": "crate", "witness": "witness", "count": 25},                       # 16
        ])
        # A valid spawn is visible, so the negative checks below can fail.
        assert steps[0]["success"], steps[0]
        assert "crate" in steps[1]["names"] and steps[1]["z"][0] > 0.4 > steps[1]["z"][-1]  # falling to the floor
        for k, element in ((2, "sdf/model/joint"), (3, "sdf/model/link/collision/geometry/mesh")):
            assert steps[k]["success"] is False and element in steps[k]["status_message"], steps[k]
            assert "nothing spawned" in steps[k]["status_message"]
        assert steps[4]["success"] is False and "already exists" in steps[4]["status_message"]
        assert steps[5]["success"] is False and "reference_frame" in steps[5]["status_message"]
        seen = steps[6]
        assert seen["count"] > 0 and "hinged" not in seen["names"] and "meshy" not in seen["names"]
        assert "far" not in seen["names"] and seen["z"] and seen["z"][-1] == pytest.approx(0.1, abs=0.01)
        # time_step and max_update_rate cannot change: refused, naming the field, gravity untouched.
        for k, field in ((7, "time_step"), (8, "max_update_rate")):
            assert steps[k]["success"] is False and field in steps[k]["status_message"], steps[k]
        assert steps[9]["gravity"] == pytest.approx([0.0, 0.0, -9.81])
        # Gravity round-trips (any direction); a zeroed ode_config is said not to be applied.
        assert steps[10]["success"] and "ode_config not applied" in steps[10]["status_message"]
        assert steps[11]["gravity"] == pytest.approx([0.5, 0.0, -9.0])
        assert steps[12]["success"] is False and "cannot be deleted" in steps[12]["status_message"]
        assert steps[13]["success"] is False and "does not exist" in steps[13]["status_message"]
        assert steps[14]["success"] and steps[15]["success"], steps[14:16]
        # In no model_states published after the delete (each listing the witness, spawned after it).
        assert steps[16]["with"] == 0 and "crate" not in steps[16]["names"] and "witness" in steps[16]["names"]

    NOT_SIMULATED = r'''
import json, sys, types
import rospy
from gazebo_msgs.srv import GetPhysicsProperties, SpawnModel, SetPhysicsProperties, DeleteModel
from jointctl.hardware.interface import HardwareInterface
from jointctl.ros.world_services import attach_world_services
from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot

class RobotController(HardwareInterface):  # stands in for real hardware: no simulation door
    def command_interfaces(self, joint): return frozenset()
    def read(self): pass
    def write(self): pass
    def advance(self, period_s): pass

session = Session(scenario_for_robot("one_dof", "position"))
session.hardware = RobotController(("joint1",))
rospy.init_node("not_simulated", anonymous=True)
attach_world_services(types.SimpleNamespace(session=session, speed=1.0))
rospy.wait_for_service("/gazebo/spawn_sdf_model", timeout=30)
out = {
  "spawn": rospy.ServiceProxy("/gazebo/spawn_sdf_model", SpawnModel)(model_name="w", model_xml=sys.argv[1]),
  "get": rospy.ServiceProxy("/gazebo/get_physics_properties", GetPhysicsProperties)(),
  "set": rospy.ServiceProxy("/gazebo/set_physics_properties", SetPhysicsProperties)(time_step=0.001),
  "delete": rospy.ServiceProxy("/gazebo/delete_model", DeleteModel)(model_name="w"),
}
published = any(t == "/gazebo/model_states" for t, _ in rospy.get_published_topics())
print(json.dumps({k: [v.success, v.status_message] for k, v in out.items()} | {"published": published}))
'''

    def test_the_services_say_so_when_the_hardware_is_not_simulated(ros_env):
        result = run(ros_env, sys.executable, "-c", NOT_SIMULATED, BOOK_WEIGHT.read_text(), timeout=120)
        out = json.loads(result.stdout.strip().splitlines()[-1])
        for name in ("spawn", "get", "set", "delete"):
            success, message = out[name]
            assert success is False and "RobotController" in message and "not simulated" in message, out
        assert out["published"] is False


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "client":
        print(json.dumps(_client(json.loads(sys.argv[2]))))
    else:
        raise SystemExit("usage: test_world_services.py client STEPS_JSON")

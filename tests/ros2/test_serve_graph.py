"""``jointctl serve --ros2 --sim-time``: what else a ros2_control robot's graph offers, checked with the ros2 CLI:
simulated time, the latched description, /tf from the URDF, and the controller manager's switch.

Theory: link2 sits on the prismatic joint1 at the joint's origin plus ``axis·q`` (URDF), so its /tf translation at
rest is the origin's xyz plus the axis times the rest position /joint_states reports. With its controller
deactivated, its last effort stays on the joint (ros2_control keeps a command interface's last value) and a
reference sent to it is refused: the piston stays; reactivated, the P loop takes a new reference to its sagged rest.
"""

from __future__ import annotations

import pytest
import yaml

from jointctl.identification.safety import real_rest
from tests.ros2.environment import ros2
from tests.ros2.served import ServedRobot
from tests.ros2.test_serve import P, REST_TOLERANCE_M, ROBOT, reference
from tests.waiting import wait_until

pytestmark = pytest.mark.slow

CONTROLLER = "joint1_position_controller"


@pytest.fixture(scope="module")
def sim_time_robot(ros2_env, tmp_path_factory):
    served = ServedRobot(ros2_env, tmp_path_factory.mktemp("serve") / "serve.log", "one_dof", "--controllers",
                         "position", "--sim-time")
    try:
        served.wait_up(["joint_state_controller", CONTROLLER])
        yield served
    finally:
        served.stop()


def echo_once(env, topic: str, kind: str, *qos: str) -> dict:
    out = ros2(env, "topic", "echo", "--once", *qos, topic, kind)
    assert out.returncode == 0, out.stderr
    return yaml.safe_load(out.stdout.split("\n---")[0])


def test_simulated_time_is_on_clock_and_the_nodes_use_it(sim_time_robot):
    env = sim_time_robot.env
    assert "True" in ros2(env, "param", "get", f"/{CONTROLLER}", "use_sim_time").stdout
    clock = echo_once(env, "/clock", "rosgraph_msgs/msg/Clock")["clock"]
    state = echo_once(env, "/joint_states", "sensor_msgs/msg/JointState")["header"]["stamp"]
    # Loop time, not the wall clock (decades of seconds): both counted from the loop's start.
    assert 0 < clock["sec"] < 3600 and 0 <= state["sec"] < 3600


def test_the_description_is_latched_for_a_late_subscriber(sim_time_robot):
    description = echo_once(sim_time_robot.env, "/robot_description", "std_msgs/msg/String",
                            "--qos-durability", "transient_local", "--qos-reliability", "reliable",
                            "--full-length")["data"]
    assert '<robot name="one_DOF_robot">' in description
    assert '<joint name="joint1" type="prismatic">' in description


def test_tf_puts_link2_where_the_urdf_and_the_joint_state_say(sim_time_robot):
    env = sim_time_robot.env
    reference(env, -0.3)
    q = sim_time_robot.rest("joint1")["position"]
    joint = ROBOT.joint("joint1")
    expected = [o + a * q for o, a in zip(joint.origin.xyz, joint.axis)]
    for _ in range(20):  # /tf carries every pair at once; find link2's
        transforms = echo_once(env, "/tf", "tf2_msgs/msg/TFMessage")["transforms"]
        found = [t for t in transforms if t["child_frame_id"] == "link2"]
        if found:
            break
    assert found and found[0]["header"]["frame_id"] == "link1"
    moved = found[0]["transform"]["translation"]
    assert [moved["x"], moved["y"], moved["z"]] == pytest.approx(expected, abs=REST_TOLERANCE_M)


def test_switching_the_controller_off_and_on_as_ros2_control_does(sim_time_robot):
    env = sim_time_robot.env
    reference(env, -0.3)
    # At rest first: the effort left on the joint is then the one that holds it (a P loop's effort mid-move would
    # leave a constant force off the gravity load, and the piston would drift at (F - τ_hold)/b).
    sim_time_robot.rest("joint1")
    out = ros2(env, "control", "switch_controllers", "--deactivate", CONTROLLER)
    assert "Successfully switched controllers" in out.stdout, out.stdout + out.stderr
    listed = ros2(env, "control", "list_controllers").stdout
    assert any(CONTROLLER in line and "inactive" in line for line in listed.splitlines()), listed
    held = sim_time_robot.rest("joint1")["position"]
    reference(env, -0.45)
    wait_until(lambda: "refused a reference: the controller is inactive" in sim_time_robot.log.read_text(),
               "the inactive controller's refusal in the log")
    assert sim_time_robot.rest("joint1")["position"] == pytest.approx(held, abs=REST_TOLERANCE_M)
    out = ros2(env, "control", "switch_controllers", "--activate", CONTROLLER)
    assert "Successfully switched controllers" in out.stdout, out.stdout + out.stderr
    reference(env, -0.45)
    assert sim_time_robot.rest("joint1")["position"] == pytest.approx(real_rest(ROBOT, "joint1", {}, -0.45, P),
                                                                     abs=REST_TOLERANCE_M)
    refused = ros2(env, "control", "switch_controllers", "--activate", "no_such_controller", "--strict")
    assert "Successfully" not in refused.stdout, refused.stdout

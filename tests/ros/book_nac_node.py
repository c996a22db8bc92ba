"""The book's nac_controller node, written again in rospy for the tests (one node per process).

    python book_nac_node.py OUT_JSON [--after-contact S] [--timeout S]

What the book's node (learning_ros, noetic_devel, Part_5/example_controllers/src/nac_controller.cpp)
does, and only that: it keeps the latest ``position[0]`` and ``velocity[0]`` of
``one_DOF_robot/joint_states`` (published at the joint state controller's 50 Hz) and the latest
``wrench.force.z`` of ``ft_sensor_topic`` (the sensor plugin's 1 kHz), subscribing with queues of
one; then, in a loop paced by a 1 kHz rate with a fixed dt of 1 ms whatever the loop really takes,
it computes

    f_virt = K (x_att - x) + B (0 - v);   f_net = F_z + f_virt
    v_ideal += f_net / M · dt;             v_ideal = sat(v_ideal, 1 m/s)

and publishes ``v_ideal`` on ``/one_DOF_robot/joint1_velocity_controller/command``. M 1 kg,
K 1000 N/m, B 50 N·s/m, x_att -0.2 m, as the book's constants. Before the first message the
signals are 0, as the book's globals are.

For the test only, the callbacks also keep what they received (header stamps, values); the script
stops ``--after-contact`` seconds (by the stamps) after the sensed force first departs by more than
10 N from its first reading (the weight has landed), or after ``--timeout`` seconds of wall time, and writes the record as
JSON: ``joint_states`` [[stamp, position, velocity]...], ``force`` [[stamp, force_z]...],
``cycles`` (loop iterations) and ``wall_s``.
"""

import argparse
import json
import time

import rospy
from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

M_VIRT = 1.0          # kg
K_VIRT = 1000.0       # N/m
B_VIRT = 50.0         # N/(m/s)
V_IDEAL_SAT = 1.0     # m/s
X_ATTRACTOR = -0.2    # m
DT = 0.001            # s
CONTACT_N = 10.0  # the 98 N weight on the disk; the 10 g plate alone reads this only beyond 100 g

link2_pos = 0.0
link2_vel = 0.0
force_z = 0.0
joint_states: list = []
forces: list = []


def sat(val: float, sat_val: float) -> float:
    return max(-sat_val, min(sat_val, val))


def joint_state_cb(js: JointState) -> None:
    global link2_pos, link2_vel
    link2_pos = js.position[0]
    link2_vel = js.velocity[0]
    joint_states.append((js.header.stamp.to_sec(), link2_pos, link2_vel))


def ft_sensor_cb(ft: WrenchStamped) -> None:
    global force_z
    force_z = ft.wrench.force.z
    forces.append((ft.header.stamp.to_sec(), force_z))


_contact = {"at": None, "scanned": 0}


def contact_over(after_s: float) -> bool:
    """True once the record holds ``after_s`` seconds of stamps after the first contact."""
    if not forces:
        return False
    if _contact["at"] is None:
        unloaded, end = forces[0][1], len(forces)
        for stamp, value in forces[_contact["scanned"]:end]:
            if abs(value - unloaded) > CONTACT_N:
                _contact["at"] = stamp
                break
        _contact["scanned"] = end
    return _contact["at"] is not None and forces[-1][0] - _contact["at"] >= after_s


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("out")
    parser.add_argument("--after-contact", type=float, default=9.0)
    parser.add_argument("--timeout", type=float, default=90.0)
    args = parser.parse_args()

    rospy.init_node("nac_controller")
    cmd_publisher = rospy.Publisher("/one_DOF_robot/joint1_velocity_controller/command", Float64, queue_size=1)
    rospy.Subscriber("one_DOF_robot/joint_states", JointState, joint_state_cb, queue_size=1)
    rospy.Subscriber("ft_sensor_topic", WrenchStamped, ft_sensor_cb, queue_size=1)
    print("ready", flush=True)

    v_ideal = 0.0
    sample_rate = rospy.Rate(1 / DT)
    start = time.monotonic()
    cycles = 0
    while not rospy.is_shutdown():
        f_virt = K_VIRT * (X_ATTRACTOR - link2_pos) + B_VIRT * (0 - link2_vel)
        f_net = force_z + f_virt
        acc_ideal = f_net / M_VIRT
        v_ideal += acc_ideal * DT
        v_ideal = sat(v_ideal, V_IDEAL_SAT)
        cmd_publisher.publish(Float64(v_ideal))
        cycles += 1
        if cycles % 100 == 0 and (contact_over(args.after_contact) or time.monotonic() - start > args.timeout):
            break
        sample_rate.sleep()
    with open(args.out, "w") as f:
        json.dump({"joint_states": joint_states, "force": forces, "cycles": cycles,
                   "wall_s": time.monotonic() - start}, f)


if __name__ == "__main__":
    main()

"""A two-joint planar arm written for the identification tests (not shipped): a shoulder and an elbow
turning about the world's y axis, gravity -z in the arm's plane, so the elbow carries gravity and the
shoulder's motion loads it through the inertia matrix.

Links (SI units): the upper arm 2 kg, 0.5 m, its centre of mass 0.25 m from the shoulder, I_c 0.04
kg·m²; the forearm 1 kg, its centre of mass 0.25 m from the elbow, I_c 0.0175 kg·m², so the elbow's
inertia about its axis is I_c + m·l_c² = 0.0175 + 0.0625 = 0.080 kg·m². Damping: shoulder 1.0,
elbow 0.5 N·m·s/rad.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.planar_arm import transmission

ELBOW_INERTIA = 0.080
ELBOW_DAMPING = 0.5
SHOULDER_DAMPING = 1.0

URDF = """<?xml version="1.0"?>
<robot name="planar_arm">
  <link name="world"/>
  <joint name="glue" type="fixed"><parent link="world"/><child link="base"/></joint>
  <link name="base">
    <inertial><origin xyz="0 0 0"/><mass value="5"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/>
    </inertial>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 1.5" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2.5" upper="2.5" effort="300" velocity="10"/>
    <dynamics damping="{shoulder_damping}"/>
  </joint>
  <link name="upper">
    <inertial><origin xyz="0.25 0 0"/><mass value="2"/>
      <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.04" iyz="0" izz="0.04"/></inertial>
  </link>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="fore"/><origin xyz="0.5 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2.5" upper="2.5" effort="100" velocity="10"/>
    <dynamics damping="{elbow_damping}"/>
  </joint>
  <link name="fore">
    <inertial><origin xyz="0.25 0 0"/><mass value="1"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.0175" iyz="0" izz="0.0175"/></inertial>
  </link>
  {transmissions}
</robot>
"""



def write_planar_arm(folder: Path, *, shoulder_pid=(1000.0, 0.0, 40.0), elbow_pid=(60.0, 0.0, 2.0)) -> Path:
    """Write the arm's URDF, its ros_control position controllers (a top-level namespace, gravity
    feed-forward) and a ``robot.yaml`` into ``folder``; returns ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "planar_arm.urdf").write_text(URDF.format(
        shoulder_damping=SHOULDER_DAMPING, elbow_damping=ELBOW_DAMPING,
        transmissions="\n  ".join(transmission(j) for j in ("shoulder", "elbow"))))
    controllers = {"joint_state_controller": {"type": "joint_state_controller/JointStateController",
                                              "publish_rate": 50}}
    for joint, (p, i, d) in (("shoulder", shoulder_pid), ("elbow", elbow_pid)):
        controllers[f"{joint}_position_controller"] = {
            "type": "effort_controllers/JointPositionController", "joint": joint,
            "pid": {"p": p, "i": i, "d": d}, "feedforward": {"gravity": True}}
    (folder / "planar_arm_pos.yaml").write_text(yaml.safe_dump({"planar_arm": controllers}))
    (folder / "robot.yaml").write_text(yaml.safe_dump({"description": "planar_arm.urdf",
                                                       "controllers": {"position": "planar_arm_pos.yaml"}}))
    return folder


def planar_arm_scenario(folder: Path, *, shoulder: float = 0.0, elbow: float = 0.3, **gains) -> Path:
    """A scenario file holding the arm at ``shoulder``, ``elbow`` [rad] with both position controllers."""
    write_planar_arm(folder / "planar_arm", **gains)
    path = folder / "planar_arm_scenario.yaml"
    path.write_text(yaml.safe_dump({
        "name": "planar_arm", "robot": "planar_arm", "controller_file": "position",
        "start_controllers": ["joint_state_controller", "shoulder_position_controller",
                              "elbow_position_controller"],
        "gravity": -9.81, "timestep_s": 0.001, "initial_positions": {"shoulder": shoulder, "elbow": elbow},
        "duration_s": 1.0}))
    return path

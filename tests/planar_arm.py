"""A user's own robot, as a user writes it: a 2-joint planar arm (shoulder and elbow about y, gravity in
its plane), a plain URDF with transmissions and no jointctl extension. Not shipped: tests write it.

At q = 0 both links point along +x (horizontal): the gravity load is largest there. Link k is a rod of
mass m_k and length l_k with its centre of mass at l_k/2 (inertia m_k·l_k²/12 about it).
"""

from __future__ import annotations

from pathlib import Path

#: (mass [kg], length [m]) of the upper arm and the forearm; damping [N·m·s/rad]; effort limits [N·m].
UPPER = (2.0, 0.5)
FORE = (1.0, 0.4)
DAMPING = {"shoulder": 1.0, "elbow": 0.5}
EFFORT = {"shoulder": 60.0, "elbow": 30.0}
VELOCITY_RAD_S = 3.0
LIMIT_RAD = 2.5


def _link(name: str, mass: float, length: float) -> str:
    i = mass * length**2 / 12
    rod = (f'<origin xyz="{length / 2} 0 0" rpy="0 1.5708 0"/>'
           f'<geometry><cylinder length="{length}" radius="0.03"/></geometry>')
    return f"""
  <link name="{name}">
    <visual>{rod}</visual>
    <collision>{rod}</collision>
    <inertial><origin xyz="{length / 2} 0 0"/><mass value="{mass}"/>
      <inertia ixx="1e-4" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i}"/></inertial>
  </link>"""


def _joint(name: str, parent: str, child: str, x: float, z: float) -> str:
    return f"""
  <joint name="{name}" type="revolute">
    <parent link="{parent}"/><child link="{child}"/>
    <origin xyz="{x} 0 {z}"/><axis xyz="0 1 0"/>
    <limit lower="-{LIMIT_RAD}" upper="{LIMIT_RAD}" effort="{EFFORT[name]}" velocity="{VELOCITY_RAD_S}"/>
    <dynamics damping="{DAMPING[name]}"/>
  </joint>
  {transmission(name)}"""


def transmission(joint: str) -> str:
    """A ros_control SimpleTransmission driving ``joint`` through an EffortJointInterface (what jointctl, as
    ros_control, needs to drive a joint)."""
    return f"""<transmission name="{joint}_transmission">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="{joint}"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint>
    <actuator name="{joint}_motor"><mechanicalReduction>1</mechanicalReduction></actuator>
  </transmission>"""


def urdf_text() -> str:
    """The planar arm's URDF: a base post 1.2 m tall, the shoulder on top, the elbow at the upper arm's end."""
    return f"""<?xml version="1.0"?>
<robot name="planar_arm">
  <link name="world"/>
  <joint name="base_to_world" type="fixed"><parent link="world"/><child link="base"/></joint>
  <link name="base">
    <visual><origin xyz="0 0 0.6"/><geometry><box size="0.1 0.1 1.2"/></geometry></visual>
    <inertial><origin xyz="0 0 0.6"/><mass value="5"/>
      <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
  </link>
{_link("upper_arm", *UPPER)}
{_link("forearm", *FORE)}
{_joint("shoulder", "base", "upper_arm", 0.0, 1.2)}
{_joint("elbow", "upper_arm", "forearm", UPPER[1], 0.0)}
</robot>
"""


def write_urdf(folder: Path) -> Path:
    """``folder/planar_arm.urdf``."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "planar_arm.urdf"
    path.write_text(urdf_text())
    return path


def elbow_inertia_kg_m2() -> float:
    """The elbow's inertia about its axis: the forearm's I_c + m·(l/2)² (constant: it does not depend on q)."""
    mass, length = FORE
    return mass * length**2 / 12 + mass * (length / 2) ** 2


def shoulder_inertia_kg_m2(elbow_rad: float = 0.0) -> float:
    """The shoulder's inertia about its axis with the elbow at ``elbow_rad``: both rods about the shoulder."""
    import math

    m1, l1 = UPPER
    m2, l2 = FORE
    c2 = l2 / 2
    return (m1 * l1**2 / 3 + m2 * l2**2 / 12
            + m2 * (l1**2 + c2**2 + 2 * l1 * c2 * math.cos(elbow_rad)))


def gravity_loads_n_m(g: float = 9.81) -> dict[str, float]:
    """|τg| at q = 0 (both links horizontal)."""
    m1, l1 = UPPER
    m2, l2 = FORE
    return {"shoulder": g * (m1 * l1 / 2 + m2 * (l1 + l2 / 2)), "elbow": g * m2 * l2 / 2}

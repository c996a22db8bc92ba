"""Two small arms of a user's own, as a user writes them (plain URDF, ros_control transmissions): the first
realistic cases of the tuning tools. Not shipped: tests write them.

- :func:`yaw_pitch_urdf`: a turret turning about z (``base_yaw``) carrying a horizontal upper arm
  (``shoulder_pitch`` about y): the shoulder holds a gravity load ``SHOULDER_LOAD_NM`` at home, with an effort
  limit of 15 N·m.
- :func:`vertical_arm_urdf`: ``base_yaw`` (damping 2 N·m·s/rad) carrying a vertical arm at home
  (``shoulder_pitch``, ``elbow_pitch`` about y): the yaw axis sees only the rods' own slender inertia, so its
  damping alone is faster than a 2 Hz loop with ζ 0.7 asks; the pitch joints rest on an unstable equilibrium.

Link k is a rod of mass m and length l along its axis, its centre of mass at l/2 (inertia m·l²/12 about it
across, a tenth of a thin disk's along it).
"""

from __future__ import annotations

from pathlib import Path

from tests.planar_arm import transmission

GRAVITY = 9.81
#: The yaw/pitch arm's upper arm: (mass [kg], length [m]), horizontal along +x at home.
UPPER_ARM = (0.6, 0.6)
#: Its shoulder's gravity load at home [N·m]: m·g·l/2.
SHOULDER_LOAD_NM = UPPER_ARM[0] * GRAVITY * UPPER_ARM[1] / 2
#: The vertical arm's rods: upper arm and forearm (mass [kg], length [m]), along +z at home.
VERTICAL_UPPER = (1.5, 0.4)
FOREARM = (2.0, 0.51)
#: The forearm's inertia about the elbow [kg·m²]: m·l²/3.
ELBOW_INERTIA = FOREARM[0] * FOREARM[1] ** 2 / 3
ELBOW_DAMPING = 0.8
YAW_DAMPING = 2.0


def _rod(name: str, mass: float, length: float, axis: str) -> str:
    across, along = mass * length**2 / 12, mass * 0.03**2 / 2
    if axis == "x":
        origin, rpy, inertia = f"{length / 2} 0 0", "0 1.5708 0", (along, across, across)
    else:
        origin, rpy, inertia = f"0 0 {length / 2}", "0 0 0", (across, across, along)
    shape = f'<origin xyz="{origin}" rpy="{rpy}"/><geometry><cylinder length="{length}" radius="0.03"/></geometry>'
    return f"""
  <link name="{name}">
    <visual>{shape}</visual>
    <inertial><origin xyz="{origin}"/><mass value="{mass}"/>
      <inertia ixx="{inertia[0]}" ixy="0" ixz="0" iyy="{inertia[1]}" iyz="0" izz="{inertia[2]}"/></inertial>
  </link>"""


def _joint(name: str, parent: str, child: str, xyz: str, axis: str, limit_rad: float, effort: float,
           damping: float) -> str:
    return f"""
  <joint name="{name}" type="revolute">
    <parent link="{parent}"/><child link="{child}"/>
    <origin xyz="{xyz}"/><axis xyz="{axis}"/>
    <limit lower="-{limit_rad}" upper="{limit_rad}" effort="{effort}" velocity="3.0"/>
    <dynamics damping="{damping}"/>
  </joint>
  {transmission(name)}"""


_BASE = """
  <link name="world"/>
  <joint name="base_to_world" type="fixed"><parent link="world"/><child link="base"/></joint>
  <link name="base">
    <visual><origin xyz="0 0 0.25"/><geometry><box size="0.1 0.1 0.5"/></geometry></visual>
    <inertial><origin xyz="0 0 0.25"/><mass value="5"/>
      <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
  </link>
  <link name="turret">
    <inertial><origin xyz="0 0 0.025"/><mass value="0.5"/>
      <inertia ixx="4e-4" ixy="0" ixz="0" iyy="4e-4" iyz="0" izz="6e-4"/></inertial>
  </link>"""


def yaw_pitch_urdf() -> str:
    """The yaw/pitch arm (see the module docstring)."""
    return f"""<?xml version="1.0"?>
<robot name="yaw_pitch_arm">{_BASE}
{_rod("upper_arm", *UPPER_ARM, "x")}
{_joint("base_yaw", "base", "turret", "0 0 0.5", "0 0 1", 3.0, 10.0, 0.5)}
{_joint("shoulder_pitch", "turret", "upper_arm", "0 0 0.05", "0 1 0", 2.5, 15.0, 0.5)}
</robot>
"""


def vertical_arm_urdf() -> str:
    """The 3-joint arm, vertical at home (see the module docstring)."""
    return f"""<?xml version="1.0"?>
<robot name="vertical_arm">{_BASE}
{_rod("upper_arm", *VERTICAL_UPPER, "z")}
{_rod("forearm", *FOREARM, "z")}
{_joint("base_yaw", "base", "turret", "0 0 0.5", "0 0 1", 3.0, 20.0, YAW_DAMPING)}
{_joint("shoulder_pitch", "turret", "upper_arm", "0 0 0.05", "0 1 0", 2.0, 60.0, 1.0)}
{_joint("elbow_pitch", "upper_arm", "forearm", f"0 0 {VERTICAL_UPPER[1]}", "0 1 0", 2.0, 30.0, ELBOW_DAMPING)}
</robot>
"""


def write(folder: Path, which: str) -> Path:
    """``folder/<which>.urdf`` (``yaw_pitch_arm`` or ``vertical_arm``)."""
    folder.mkdir(parents=True, exist_ok=True)
    text = {"yaw_pitch_arm": yaw_pitch_urdf, "vertical_arm": vertical_arm_urdf}[which]()
    path = folder / f"{which}.urdf"
    path.write_text(text)
    return path

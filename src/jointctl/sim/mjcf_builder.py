"""The simulated world's MuJoCo model (an ``MjSpec``): the robot on a floor.

The robot's own model is :mod:`jointctl.model.mjcf` (bodies, joints, limits as stops,
actuators, sensors); the world adds what the URDF does not say: gravity, the physics
step and a ground plane (:class:`WorldSettings`). Objects are spawned later
(:mod:`jointctl.sim.objects`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

from jointctl.model.mjcf import add_robot, empty_spec
# Re-exported for the world's modules (sim/world.py, sim/model_xml.py) that name them here.
from jointctl.model.mjcf import rpy_to_matrix, rpy_to_quat, sensor_site_name  # noqa: F401
from jointctl.model.robot_model import RobotModel


@dataclass(frozen=True)
class WorldSettings:
    """World-level physics settings.

    ``gravity_m_s2`` is the world-frame gravity vector (z up, so Earth is
    (0, 0, -9.81)); ``timestep_s`` the physics step; ``floor`` adds a ground
    plane at z = 0.
    """

    timestep_s: float = 0.001
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    floor: bool = True


def build_spec(robot: RobotModel, settings: WorldSettings) -> mujoco.MjSpec:
    """Return an uncompiled ``MjSpec`` of ``robot`` in a world with ``settings``."""
    spec = empty_spec(robot.name, timestep_s=settings.timestep_s, gravity_m_s2=settings.gravity_m_s2)
    if settings.floor:  # added first, as it always was: geom 0 (contact order follows geom order)
        spec.worldbody.add_geom(
            name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5.0, 5.0, 0.1],
            rgba=[0.8, 0.8, 0.8, 1.0],
        )
    add_robot(spec, robot)
    return spec

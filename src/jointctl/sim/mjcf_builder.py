"""The simulated world's MuJoCo model (an ``MjSpec``): the robot on a floor.

The robot's own model is :mod:`jointctl.model.mjcf` (bodies, joints, limits as stops,
actuators, sensors); the world adds what the URDF does not say: gravity, the physics
step and a ground plane (:class:`WorldSettings`). Objects are spawned later
(:mod:`jointctl.sim.objects`).

The world also carries its scenery, for pictures only (no mass, no contact, no effect on the
physics): a sky that fades from blue at the zenith to white at the horizon, a light grey floor
with a grid line every ``GRID_SPACING_M``, drawn to the horizon, and a sun (a directional light
from above and behind the default camera) whose shadows show where a body stands above the floor.
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


#: The floor's grid spacing [m]; the floor is drawn without end (size 0), as it collides everywhere.
GRID_SPACING_M = 0.5
SKY_ZENITH_RGB = (0.45, 0.62, 0.85)
SKY_HORIZON_RGB = (0.93, 0.95, 0.98)
SHADOW_CLIP_IN_EXTENTS = 2.0
#: The shadow map's size [px] and the floor's drawn quads [m]: MuJoCo's 4096 px and 0.1 m drew a third
#: as many pictures a second in software OpenGL; the sun's light is the same on every quad of a plane.
SHADOW_MAP_PX = 1024
FLOOR_QUAD_M = 2.0
#: The sun's direction (world frame, pointing where the light goes): down, from behind-left of a
#: camera that looks along +y.
SUN_DIRECTION = (0.3, 0.5, -1.0)


def add_scenery(spec: mujoco.MjSpec) -> None:
    """The sky, the floor's grid material and the sun (see the module docstring); drawing only."""
    spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     rgb1=list(SKY_ZENITH_RGB), rgb2=list(SKY_HORIZON_RGB), width=64, height=384)
    spec.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                     mark=mujoco.mjtMark.mjMARK_EDGE, rgb1=[0.82, 0.83, 0.85], rgb2=[0.82, 0.83, 0.85],
                     markrgb=[0.55, 0.57, 0.6], width=64, height=64)
    # The texture's edge is marked; on a plane MuJoCo repeats it texrepeat times every 2 m (measured:
    # tests/visuals/test_framing.py).
    grid = spec.add_material(name="grid", texuniform=True, texrepeat=[2.0 / GRID_SPACING_M] * 2)
    grid.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "grid"
    spec.visual.rgba.haze = [*SKY_HORIZON_RGB, 1.0]  # where the endless floor meets the sky
    # The sun's shadow map reaches this many model extents from it (MuJoCo's 1 leaves specks of false
    # shadow on the floor near the camera).
    spec.visual.map.shadowclip = SHADOW_CLIP_IN_EXTENTS
    spec.visual.quality.shadowsize = SHADOW_MAP_PX
    spec.worldbody.add_light(name="sun", type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, castshadow=True,
                             pos=[0.0, 0.0, 3.0], dir=list(SUN_DIRECTION), diffuse=[0.55, 0.55, 0.55],
                             ambient=[0.1, 0.1, 0.1], specular=[0.1, 0.1, 0.1])


def build_spec(robot: RobotModel, settings: WorldSettings) -> mujoco.MjSpec:
    """Return an uncompiled ``MjSpec`` of ``robot`` in a world with ``settings``."""
    spec = empty_spec(robot.name, timestep_s=settings.timestep_s, gravity_m_s2=settings.gravity_m_s2)
    if settings.floor:  # added first, as it always was: geom 0 (contact order follows geom order)
        spec.worldbody.add_geom(
            name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, FLOOR_QUAD_M],
            material="grid",
        )
    add_scenery(spec)
    add_robot(spec, robot)
    return spec

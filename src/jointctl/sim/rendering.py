"""Offscreen pictures of a MuJoCo world: a free camera, software EGL, no display needed.

:class:`OffscreenRenderer` draws a model's state (``qpos``) as MuJoCo's own viewer would, into an
RGB array (row 0 at the top), through an EGL context (Mesa's, from Debian's ``libegl1`` and
``libegl-mesa0``; ``make render`` installs them). It keeps one MuJoCo render context per model, so
a world whose model changed (an object spawned) renders with the model of each moment.

:class:`CameraView` is MuJoCo's free camera: a point looked at [m, world frame], the distance to it
[m], the azimuth (0 looks along +x, 90 along +y) and the elevation (negative looks down) [deg];
the vertical field of view is the model's ``visual/global/fovy`` (45° by default). A view without
``lookat`` or ``distance_m`` is *fitted*: :mod:`jointctl.visuals.framing` chooses them for each
picture from where the robot and the objects are.
:meth:`OffscreenRenderer.project` maps a world point to the pixel it is drawn at, with the same
camera: what a test uses to find a body in a picture.

The world's sun (:mod:`jointctl.sim.mjcf_builder`) is moved before each picture to stand above the
point looked at, so that its shadow map covers what is seen (a shadow map spread over a large
scene draws stripes of false shadow on the floor). ``stamp`` writes a line of text (the loop
time) in the picture's top left corner.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from jointctl.errors import JointCtlError
from jointctl.sim.scene_bounds import DRAWN_GROUPS

#: The largest picture drawn [px].
MAX_SIZE = (4096, 4096)
#: The headlight (RGB, 0..1): it lights the faces the camera sees, the world's sun the rest.
HEADLIGHT_AMBIENT = (0.3, 0.3, 0.3)
HEADLIGHT_DIFFUSE = (0.4, 0.4, 0.4)
#: Pictures narrower than this [px] are stamped in MuJoCo's smaller font.
SMALL_PICTURE_WIDTH = 480
#: How far the sun stands back from the point looked at, in view distances.
SUN_DISTANCE_IN_VIEWS = 1.5


class RenderingUnavailable(JointCtlError):
    """No offscreen OpenGL (EGL) is available to draw with."""

    code = "rendering"


@dataclass(frozen=True)
class CameraView:
    """MuJoCo's free camera: ``lookat`` [m], ``distance_m``, ``azimuth_deg``, ``elevation_deg``;
    ``lookat`` or ``distance_m`` None: fitted to the scene (see the module docstring)."""

    lookat: tuple[float, float, float] | None
    distance_m: float | None
    azimuth_deg: float = 90.0
    elevation_deg: float = -15.0

    @property
    def fitted(self) -> bool:
        """True when the point looked at or the distance is chosen for each picture."""
        return self.lookat is None or self.distance_m is None

    @classmethod
    def from_config(cls, config: dict, *, field: str = "camera", source: str | None = None) -> CameraView:
        """From ``{lookat: [x, y, z], distance_m, azimuth_deg, elevation_deg}``, each optional (a missing
        ``lookat`` or ``distance_m`` is fitted to the scene); errors name the key."""
        if not isinstance(config, dict):
            raise JointCtlError("must be a mapping {lookat, distance_m, azimuth_deg, elevation_deg}",
                                source=source, field=field, value=config)
        unknown = set(config) - {"lookat", "distance_m", "azimuth_deg", "elevation_deg"}
        if unknown:
            raise JointCtlError("unknown key", source=source, field=f"{field}.{sorted(unknown)[0]}",
                                value=config[sorted(unknown)[0]])
        lookat = config.get("lookat")
        if lookat is not None and not (isinstance(lookat, (list, tuple)) and len(lookat) == 3 and all(
                isinstance(v, (int, float)) and math.isfinite(v) for v in lookat)):
            raise JointCtlError("must be three numbers [m]", source=source, field=f"{field}.lookat", value=lookat)
        values = {}
        for key, default, positive in (("distance_m", None, True), ("azimuth_deg", 90.0, False),
                                       ("elevation_deg", -15.0, False)):
            value = config.get(key, default)
            if value is None and default is None:
                values[key] = None
                continue
            if not (isinstance(value, (int, float)) and math.isfinite(value) and (value > 0 or not positive)):
                raise JointCtlError("must be a positive number" if positive else "must be a number", source=source,
                                    field=f"{field}.{key}", value=value)
            values[key] = float(value)
        if not -90.0 < values["elevation_deg"] < 90.0:
            raise JointCtlError("must be between -90 and 90 [deg]", source=source, field=f"{field}.elevation_deg",
                                value=values["elevation_deg"])
        return cls(None if lookat is None else tuple(float(v) for v in lookat), **values)


class OffscreenRenderer:
    """Draws ``width`` x ``height`` pictures of MuJoCo states (see the module docstring)."""

    def __init__(self, width: int, height: int, *, shadows: bool = True) -> None:
        for name, value, limit in (("width", width, MAX_SIZE[0]), ("height", height, MAX_SIZE[1])):
            if not (isinstance(value, int) and 16 <= value <= limit):
                raise JointCtlError(f"must be a whole number of pixels from 16 to {limit}", field=name, value=value)
        self.width, self.height = width, height
        try:
            from mujoco import egl

            self._gl = egl.GLContext(width, height)
            self._gl.make_current()
        except Exception as exc:  # noqa: BLE001  (no EGL library, no device: one clear error)
            raise RenderingUnavailable(f"no offscreen OpenGL (EGL) to draw with ({type(exc).__name__}: {exc}); "
                                       "'make render' installs Debian's libegl1 and libegl-mesa0",
                                       field="rendering", value="egl") from None
        self._contexts: dict[int, tuple[mujoco.MjModel, mujoco.MjData, mujoco.MjrContext, mujoco.MjvScene]] = {}
        self._option = mujoco.MjvOption()
        self.shadows = shadows
        self._camera = mujoco.MjvCamera()
        self._viewport = mujoco.MjrRect(0, 0, width, height)
        self._pixels = np.empty((height, width, 3), dtype=np.uint8)
        self._scene: mujoco.MjvScene | None = None

    def _context(self, model: mujoco.MjModel):
        key = id(model)
        found = self._contexts.get(key)
        if found is None:
            model.vis.global_.offwidth = max(model.vis.global_.offwidth, self.width)
            model.vis.global_.offheight = max(model.vis.global_.offheight, self.height)
            # URDF robots bring no lights: the camera's headlight lights the scene (drawing only).
            model.vis.headlight.ambient[:] = HEADLIGHT_AMBIENT
            model.vis.headlight.diffuse[:] = HEADLIGHT_DIFFUSE
            font = mujoco.mjtFontScale.mjFONTSCALE_100 if self.width < SMALL_PICTURE_WIDTH else \
                mujoco.mjtFontScale.mjFONTSCALE_150  # the stamp's letters: a smaller share of a small picture
            context = mujoco.MjrContext(model, font)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, context)
            found = (model, mujoco.MjData(model), context, mujoco.MjvScene(model, maxgeom=10_000))
            self._contexts[key] = found
        return found

    def render(self, model: mujoco.MjModel, qpos: np.ndarray, view: CameraView, *,
               stamp: str | None = None, groups=DRAWN_GROUPS) -> np.ndarray:
        """The picture of ``model`` at ``qpos`` from ``view`` (not a fitted one: see
        :mod:`jointctl.visuals.framing`), with ``stamp`` written in its top left corner, showing the
        geoms of ``groups`` (the robot's visuals are group 2; the floor and spawned objects 0): a
        (height, width, 3) uint8 array, a new one."""
        if view.fitted:
            raise JointCtlError("a fitted view must be fitted to the scene first (jointctl.visuals.framing)",
                                field="camera", value=view)
        self._gl.make_current()  # another renderer may have drawn since
        _, data, context, scene = self._context(model)
        data.qpos[:] = qpos
        _follow_with_sun(model, view)
        mujoco.mj_forward(model, data)
        self._option.geomgroup[:] = [int(g in groups) for g in range(len(self._option.geomgroup))]
        camera = self._camera
        camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        camera.lookat[:] = view.lookat
        camera.distance = view.distance_m
        camera.azimuth = view.azimuth_deg
        camera.elevation = view.elevation_deg
        mujoco.mjv_updateScene(model, data, self._option, None, camera, mujoco.mjtCatBit.mjCAT_ALL, scene)
        scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = self.shadows
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, context)
        mujoco.mjr_render(self._viewport, scene, context)
        if stamp:
            mujoco.mjr_overlay(mujoco.mjtFont.mjFONT_NORMAL, mujoco.mjtGridPos.mjGRID_TOPLEFT, self._viewport,
                               stamp, "", context)
        mujoco.mjr_readPixels(self._pixels, None, self._viewport, context)
        self._scene = scene
        return np.flipud(self._pixels).copy()

    def project(self, point) -> tuple[float, float]:
        """(column, row) [px, row 0 at the top] where world ``point`` [m] was drawn in the last picture."""
        if self._scene is None:
            raise JointCtlError("render a picture first", field="project")
        eyes = self._scene.camera
        position = (np.asarray(eyes[0].pos) + np.asarray(eyes[1].pos)) / 2
        forward, up = np.asarray(eyes[0].forward), np.asarray(eyes[0].up)
        right = np.cross(forward, up)
        near, top = eyes[0].frustum_near, eyes[0].frustum_top
        half_width = top * self.width / self.height  # square pixels
        relative = np.asarray(point, dtype=float) - position
        depth = float(relative @ forward)
        x = float(relative @ right) * near / depth
        y = float(relative @ up) * near / depth
        return ((x / half_width + 1) / 2 * self.width, (1 - (y / top + 1) / 2) * self.height)

    def close(self) -> None:
        for _, _, context, _ in self._contexts.values():
            context.free()
        self._contexts.clear()
        self._gl.free()


def _follow_with_sun(model: mujoco.MjModel, view: CameraView) -> None:
    """Stand the directional lights that cast shadows back from ``view``'s point along their direction."""
    directional = int(mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    for light in range(model.nlight):
        if model.light_castshadow[light] and int(model.light_type[light]) == directional:
            direction = model.light_dir[light] / np.linalg.norm(model.light_dir[light])
            model.light_pos[light] = np.asarray(view.lookat) - direction * SUN_DISTANCE_IN_VIEWS * view.distance_m


__all__ = ["CameraView", "OffscreenRenderer", "RenderingUnavailable"]

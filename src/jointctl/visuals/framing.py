"""A camera fitted to the robot and the objects around it, picture by picture.

:func:`fit_view` places MuJoCo's free camera, for a given azimuth and elevation, so that a box
[m, world frame] fills ``FILL`` of the picture's height or width, whichever binds first: it looks
at the box's centre from the nearest distance at which all eight corners project inside that share
of the frame (a pinhole camera with the model's vertical field of view; square pixels).

:func:`framed_views` fits a video's views: each kept state's box around everything drawn (the
robot and every spawned object, :func:`jointctl.sim.scene_bounds.drawn_bounds`), so the camera
follows a falling object and comes back to the robot once it lies still. The boxes are first
widened to the largest box within ``HOLD_S`` either side of each moment, then averaged over
``GLIDE_S`` either side: the camera glides instead of jumping, and since the averaging window is
inside the widening one, every box it averages holds the moment's own box, so nothing drawn ever
leaves the frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from jointctl.sim.rendering import CameraView
from jointctl.sim.scene_bounds import drawn_bounds

#: The share of the picture's height (or width) the framed box fills.
FILL = 0.8
#: Widening window and averaging window, either side of each moment [s] (GLIDE_S <= HOLD_S).
HOLD_S = 0.6
GLIDE_S = 0.4
#: The box's smallest size [m]: a scene smaller than this every way is framed as this cube.
MIN_SIZE_M = 0.2


def camera_axes(azimuth_deg: float, elevation_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forward, right, up) unit vectors of MuJoCo's free camera [world frame]."""
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    forward = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return forward, right, np.cross(right, forward)


def fit_view(lowest, highest, *, azimuth_deg: float, elevation_deg: float, fovy_deg: float,
             aspect: float, fill: float = FILL) -> CameraView:
    """The view of the box ``lowest``..``highest`` [m] from that direction that fills ``fill`` of the
    frame (see the module docstring); ``aspect`` is width / height."""
    lowest, highest = np.asarray(lowest, float), np.asarray(highest, float)
    centre = (lowest + highest) / 2
    half = (highest - lowest) / 2
    if half.max() < MIN_SIZE_M / 2:
        half = np.full(3, MIN_SIZE_M / 2)
    corners = centre + half * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    forward, right, up = camera_axes(azimuth_deg, elevation_deg)
    relative = corners - centre
    depth, across, upward = relative @ forward, relative @ right, relative @ up
    tan_v = math.tan(math.radians(fovy_deg) / 2) * fill
    tan_h = tan_v * aspect
    # A corner at depth d beyond the centre projects inside when |y| <= tan_v * (D + d): D >= |y|/tan_v - d.
    distance = float(np.max(np.maximum(np.abs(upward) / tan_v, np.abs(across) / tan_h) - depth))
    distance = max(distance, float(np.max(-depth)) + MIN_SIZE_M)  # the camera stays outside the box
    return CameraView(tuple(float(v) for v in centre), distance, azimuth_deg, elevation_deg)


def frame_bounds(frames) -> np.ndarray:
    """Each kept state's box around everything drawn: an (n, 2, 3) array [m] (see the module docstring).
    ``frames`` are ``(model, qpos, time_s)`` as :class:`jointctl.visuals.video.FrameCapture` keeps them."""
    datas: dict[int, mujoco.MjData] = {}
    boxes = []
    for model, qpos, _ in frames:
        data = datas.setdefault(id(model), mujoco.MjData(model))
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        found = drawn_bounds(model, data)
        boxes.append(np.zeros((2, 3)) if found is None else np.stack(found))
    return np.asarray(boxes)


def smoothed_bounds(boxes: np.ndarray, times_s: Sequence[float]) -> np.ndarray:
    """``boxes`` (n, 2, 3) widened over ``HOLD_S`` and averaged over ``GLIDE_S`` either side of each
    moment (see the module docstring)."""
    times = np.asarray(times_s, float)
    widened = np.empty_like(boxes)
    for k, t in enumerate(times):
        near = np.abs(times - t) <= HOLD_S + 1e-9
        widened[k, 0] = boxes[near, 0].min(axis=0)
        widened[k, 1] = boxes[near, 1].max(axis=0)
    glided = np.empty_like(boxes)
    for k, t in enumerate(times):
        near = np.abs(times - t) <= GLIDE_S + 1e-9
        glided[k] = widened[near].mean(axis=0)
    return glided


def framed_views(frames, camera: CameraView, width: int, height: int) -> list[CameraView]:
    """One view per kept state: ``camera`` itself when it is not fitted, else fitted to that moment's
    smoothed box with ``camera``'s azimuth and elevation (and its ``lookat`` or ``distance_m`` if it
    gives one)."""
    if not camera.fitted:
        return [camera] * len(frames)
    if not frames:
        return []
    boxes = smoothed_bounds(frame_bounds(frames), [t for _, _, t in frames])
    fovy = float(frames[0][0].vis.global_.fovy)
    views = []
    for lowest, highest in boxes:
        view = fit_view(lowest, highest, azimuth_deg=camera.azimuth_deg, elevation_deg=camera.elevation_deg,
                        fovy_deg=fovy, aspect=width / height)
        views.append(CameraView(camera.lookat or view.lookat, camera.distance_m or view.distance_m,
                                camera.azimuth_deg, camera.elevation_deg))
    return views


__all__ = ["FILL", "GLIDE_S", "HOLD_S", "camera_axes", "fit_view", "frame_bounds", "framed_views",
           "smoothed_bounds"]

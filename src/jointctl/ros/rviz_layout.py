"""rviz's window and view for one robot: the window sized to the screen, the view fitted to the robot.

rviz opens at the size its configuration says and looks where it says; the shipped configuration
(``rviz/jointctl.rviz``) cannot know the screen or the robot. :func:`rviz_layout` chooses:

- the window: ``WINDOW_SHARE`` of the screen's width and height, centred (the screen's size from
  ``xdpyinfo``, else :data:`DEFAULT_SCREEN_PX`, said in the returned ``screen_source``);
- the view (rviz's Orbit camera: focal point [m], distance [m], yaw and pitch [rad], vertical field
  of view 0.785 rad): looking at the centre of the robot's drawn box [m, the root link's frame] from
  the yaw and pitch of :data:`VIEW_YAW_RAD` and :data:`VIEW_PITCH_RAD`, as near as leaves the box
  inside the 3D panel (:func:`jointctl.visuals.framing.fit_view`; the panel is the window less the
  Displays dock and the tool and time bars);
- the TF axes' ``Marker Scale``: rviz draws a frame's axes 0.2 m long times that scale; they are
  made ``AXES_SHARE`` of the robot's largest size.
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from dataclasses import dataclass

import numpy as np

from jointctl.visuals.framing import fit_view

DEFAULT_SCREEN_PX = (1280, 800)
WINDOW_SHARE = 0.85
#: What rviz's window keeps for itself around the 3D panel [px]: the Displays dock on the left,
#: the tool bar, the Time panel and the title bar.
DOCK_WIDTH_PX = 330
BARS_HEIGHT_PX = 120
#: rviz's Orbit view: field of view [rad, vertical] and the direction it looks from (the camera at
#: yaw 0.8 rad about z from +x, 0.35 rad above the horizon).
FIELD_OF_VIEW_RAD = 0.785
VIEW_YAW_RAD = 0.8
VIEW_PITCH_RAD = 0.35
#: Length of rviz's TF axes at Marker Scale 1 [m], and the share of the robot's size they are given.
RVIZ_AXES_LENGTH_M = 0.2
AXES_SHARE = 0.12


@dataclass(frozen=True)
class RvizLayout:
    """The window ``(x, y, width, height)`` [px] and the Orbit view (see the module docstring)."""

    window_px: tuple[int, int, int, int]
    focal_point_m: tuple[float, float, float]
    distance_m: float
    yaw_rad: float
    pitch_rad: float
    axes_scale: float
    screen_source: str


def screen_size_px() -> tuple[tuple[int, int], str]:
    """((width, height) [px], where it came from): ``xdpyinfo``'s dimensions, else the default."""
    if shutil.which("xdpyinfo"):
        try:
            out = subprocess.run(["xdpyinfo"], capture_output=True, text=True, timeout=5).stdout
        except (OSError, subprocess.TimeoutExpired):
            out = ""
        found = re.search(r"dimensions:\s+(\d+)x(\d+) pixels", out)
        if found:
            return (int(found.group(1)), int(found.group(2))), "xdpyinfo"
    return DEFAULT_SCREEN_PX, f"default {DEFAULT_SCREEN_PX[0]}x{DEFAULT_SCREEN_PX[1]} (no xdpyinfo)"


def rviz_layout(lowest, highest, screen_px: tuple[int, int], screen_source: str = "given") -> RvizLayout:
    """The layout for a robot drawn inside the box ``lowest``..``highest`` [m] on a screen of
    ``screen_px`` (see the module docstring)."""
    width, height = round(WINDOW_SHARE * screen_px[0]), round(WINDOW_SHARE * screen_px[1])
    window = ((screen_px[0] - width) // 2, (screen_px[1] - height) // 2, width, height)
    panel = (max(width - DOCK_WIDTH_PX, 100), max(height - BARS_HEIGHT_PX, 100))
    # rviz's camera stands at yaw, pitch from the focal point: it looks the opposite way (MuJoCo's
    # free camera names the direction looked along).
    view = fit_view(lowest, highest, azimuth_deg=math.degrees(VIEW_YAW_RAD) + 180.0,
                    elevation_deg=-math.degrees(VIEW_PITCH_RAD), fovy_deg=math.degrees(FIELD_OF_VIEW_RAD),
                    aspect=panel[0] / panel[1])
    size_m = float(np.max(np.asarray(highest, float) - np.asarray(lowest, float)))
    axes_scale = round(max(AXES_SHARE * size_m / RVIZ_AXES_LENGTH_M, 0.1), 3)
    return RvizLayout(window, view.lookat, view.distance_m, VIEW_YAW_RAD, VIEW_PITCH_RAD, axes_scale, screen_source)


def apply_layout(config: dict, layout: RvizLayout) -> dict:
    """``config`` (an rviz configuration, as YAML loads it) with ``layout``'s window, view and axes."""
    manager = config["Visualization Manager"]
    view = manager["Views"]["Current"]
    view["Focal Point"] = dict(zip("XYZ", (round(v, 4) for v in layout.focal_point_m)))
    view["Distance"] = round(layout.distance_m, 4)
    view["Yaw"], view["Pitch"] = layout.yaw_rad, layout.pitch_rad
    view["Field of View"] = FIELD_OF_VIEW_RAD
    for display in manager["Displays"]:
        if display.get("Class") == "rviz/TF":
            display["Marker Scale"] = layout.axes_scale
    x, y, width, height = layout.window_px
    config["Window Geometry"].update({"X": x, "Y": y, "Width": width, "Height": height})
    return config


__all__ = ["RvizLayout", "apply_layout", "rviz_layout", "screen_size_px"]

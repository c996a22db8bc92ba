"""rviz's window sized to the screen and its Orbit view fitted to the robot, checked with rviz's own camera model
(an Orbit camera at distance d from the focal point, at yaw about z and pitch above the horizon, looking at it, z
up, vertical field of view 0.785 rad) written here from rviz's definition, not from jointctl's framing."""

from __future__ import annotations

import math
import os
import stat

import mujoco
import numpy as np
import pytest
import yaml

from jointctl.model.mjcf import compile_robot
from jointctl.model.urdf_parser import parse_urdf
from jointctl.ros.rviz_layout import (AXES_SHARE, BARS_HEIGHT_PX, DEFAULT_SCREEN_PX, DOCK_WIDTH_PX, RVIZ_AXES_LENGTH_M,
                                      apply_layout, rviz_layout, screen_size_px)
from jointctl.sim.scene_bounds import drawn_bounds
from jointctl.visuals.framing import FILL
from tests.planar_arm import urdf_text


def planar_arm_box(pose) -> tuple[np.ndarray, np.ndarray]:
    model = compile_robot(parse_urdf(urdf_text(), source="planar_arm.urdf"))
    data = mujoco.MjData(model)
    data.qpos[:] = pose
    mujoco.mj_kinematics(model, data)
    return drawn_bounds(model, data)


def rviz_orbit_projection(layout, point, panel_px) -> tuple[float, float]:
    """(column, row) [px] of ``point`` in rviz's 3D panel, from rviz's Orbit camera."""
    focal = np.array(layout.focal_point_m)
    yaw, pitch, d = layout.yaw_rad, layout.pitch_rad, layout.distance_m
    eye = focal + d * np.array([math.cos(yaw) * math.cos(pitch), math.sin(yaw) * math.cos(pitch), math.sin(pitch)])
    forward = (focal - eye) / d
    right = np.cross(forward, [0, 0, 1])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    relative = np.asarray(point) - eye
    depth = relative @ forward
    tan_half = math.tan(0.785 / 2)
    x = (relative @ right) / depth / (tan_half * panel_px[0] / panel_px[1])
    y = (relative @ up) / depth / tan_half
    return (x + 1) / 2 * panel_px[0], (1 - y) / 2 * panel_px[1]


@pytest.mark.parametrize("screen, pose", [((1920, 1080), [0.0, 0.0]), ((1280, 800), [1.2, -2.0]),
                                          ((3840, 2160), [-0.6, 1.5])])
def test_the_window_fits_the_screen_and_the_robot_fills_rvizs_view(screen, pose) -> None:
    lowest, highest = planar_arm_box(pose)
    layout = rviz_layout(lowest, highest, screen)
    x, y, width, height = layout.window_px
    assert 0 <= x and 0 <= y and x + width <= screen[0] and y + height <= screen[1]
    assert width >= 0.8 * screen[0] and height >= 0.8 * screen[1]  # sized to the screen, not a fixed 1200x800
    panel = (width - DOCK_WIDTH_PX, height - BARS_HEIGHT_PX)
    corners = np.array([rviz_orbit_projection(layout, [cx, cy, cz], panel) for cx in (lowest[0], highest[0])
                        for cy in (lowest[1], highest[1]) for cz in (lowest[2], highest[2])])
    assert corners[:, 0].min() >= 0 and corners[:, 0].max() <= panel[0]
    assert corners[:, 1].min() >= 0 and corners[:, 1].max() <= panel[1]
    # As near as the share FILL allows: the corners inside FILL of the panel, one of them on its edge.
    inner = np.array([[(1 - FILL) / 2 * panel[0], (1 + FILL) / 2 * panel[0]],
                      [(1 - FILL) / 2 * panel[1], (1 + FILL) / 2 * panel[1]]])
    to_edges = np.concatenate([corners[:, 0] - inner[0, 0], inner[0, 1] - corners[:, 0],
                               corners[:, 1] - inner[1, 0], inner[1, 1] - corners[:, 1]])
    assert to_edges.min() > -1.0 and to_edges.min() < 1.0
    assert np.ptp(corners[:, 1]) / panel[1] >= 1 / 3
    size = float(np.max(highest - lowest))
    assert layout.axes_scale == pytest.approx(AXES_SHARE * size / RVIZ_AXES_LENGTH_M, abs=1e-3)


def test_the_layout_lands_in_rvizs_configuration() -> None:
    from jointctl.ros.robot_description import RVIZ_CONFIG

    layout = rviz_layout(*planar_arm_box([0.0, 0.0]), (1920, 1080))
    config = apply_layout(yaml.safe_load(RVIZ_CONFIG.read_text()), layout)
    window = config["Window Geometry"]
    assert (window["X"], window["Y"], window["Width"], window["Height"]) == layout.window_px
    view = config["Visualization Manager"]["Views"]["Current"]
    assert (view["Focal Point"]["X"], view["Focal Point"]["Y"], view["Focal Point"]["Z"]) == pytest.approx(
        layout.focal_point_m, abs=1e-4)
    assert view["Distance"] == pytest.approx(layout.distance_m, abs=1e-4) and view["Class"] == "rviz/Orbit"
    tf = next(d for d in config["Visualization Manager"]["Displays"] if d["Class"] == "rviz/TF")
    assert tf["Marker Scale"] == layout.axes_scale > 0.5  # was 0.5: 0.1 m axes on a 1.2 m robot


def test_the_screen_size_comes_from_xdpyinfo_or_a_default_that_says_so(tmp_path, monkeypatch) -> None:
    fake = tmp_path / "xdpyinfo"
    fake.write_text("#!/bin/sh\necho 'screen #0:'\necho '  dimensions:    2560x1440 pixels (677x381 millimeters)'\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    assert screen_size_px() == ((2560, 1440), "xdpyinfo")
    monkeypatch.setenv("PATH", str(tmp_path / "nothing-here"))
    size, source = screen_size_px()
    assert size == DEFAULT_SCREEN_PX and "no xdpyinfo" in source

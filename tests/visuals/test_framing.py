"""The fitted camera, checked on the pictures it gives: the robot fills at least a third of the frame's height
and is drawn where the pinhole model projects it, a dropped weight stays in the frame while it falls; and the
scenery (sky, shadows) and the time stamp each change the picture where they should and nowhere else."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from jointctl.model.urdf_parser import parse_urdf
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from jointctl.sim.rendering import CameraView, OffscreenRenderer
from jointctl.sim.scene_bounds import drawn_bounds, robot_bodies
from jointctl.sim.world import MujocoWorld
from jointctl.visuals.framing import FILL, camera_axes, fit_view, framed_views
from jointctl.visuals.video import FrameCapture, robot_camera, time_stamp
from tests.planar_arm import urdf_text

SIZE = (320, 240)
FITTED = CameraView(None, None, azimuth_deg=90.0, elevation_deg=-15.0)


@pytest.fixture(scope="module")
def renderer():
    renderer = OffscreenRenderer(*SIZE, shadows=False)  # a robot's shadow is not the robot
    yield renderer
    renderer.close()


def drawn_robot_box(renderer, model, qpos, view) -> tuple[int, int, int, int]:
    """(top, bottom, left, right) [px] of what the robot's visuals (group 2) add to the picture."""
    without_robot = renderer.render(model, qpos, view, groups=(0,))
    picture = renderer.render(model, qpos, view)
    rows, columns = np.nonzero(np.abs(picture.astype(int) - without_robot.astype(int)).sum(axis=2) > 30)
    return rows.min(), rows.max(), columns.min(), columns.max()


def projected_box(renderer, model, qpos, bodies) -> tuple[float, float, float, float]:
    """(top, bottom, left, right) [px] of the bodies' box, projected with the last picture's camera."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    lowest, highest = drawn_bounds(model, data, bodies)
    corners = [renderer.project([x, y, z]) for x in (lowest[0], highest[0]) for y in (lowest[1], highest[1])
               for z in (lowest[2], highest[2])]
    columns, rows = zip(*corners)
    return min(rows), max(rows), min(columns), max(columns)


def check_robot_framed(renderer, frames, views, objects=(), min_share: float = 1 / 3) -> list[float]:
    """Every picture: the robot drawn inside its projected box (2 px of rasterisation), inside the frame, and
    at least ``min_share`` of the frame's height. Returns the drawn heights [share of the frame]."""
    shares = []
    for (model, qpos, _), view in zip(frames, views):
        top, bottom, left, right = drawn_robot_box(renderer, model, qpos, view)
        p_top, p_bottom, p_left, p_right = projected_box(renderer, model, qpos, robot_bodies(model, objects))
        assert p_top - 2 <= top and bottom <= p_bottom + 2 and p_left - 2 <= left and right <= p_right + 2
        assert 0 <= top and bottom < SIZE[1] and 0 <= left and right < SIZE[0]
        shares.append((bottom - top + 1) / SIZE[1])
    assert min(shares) >= min_share, shares
    return shares


def world_frames(world, poses) -> list:
    return [(world.model, world.data.qpos.copy() if pose is None else np.asarray(pose, float), 0.0)
            for pose in poses]


def test_a_fitted_view_puts_the_box_at_the_share_of_the_frame_it_fills(renderer) -> None:
    world = MujocoWorld(parse_urdf(urdf_text(), source="planar_arm.urdf"))
    view = fit_view([-0.5, -0.2, 0.0], [0.5, 0.2, 1.5], azimuth_deg=120.0, elevation_deg=-25.0,
                    fovy_deg=float(world.model.vis.global_.fovy), aspect=SIZE[0] / SIZE[1])
    renderer.render(world.model, world.data.qpos, view)
    corners = np.array([renderer.project([x, y, z]) for x in (-0.5, 0.5) for y in (-0.2, 0.2) for z in (0.0, 1.5)])
    margin = (1 - FILL) / 2
    # Every corner inside the share FILL of the frame, and the nearest one on its edge (the distance is the least).
    assert corners[:, 0].min() >= margin * SIZE[0] - 0.5 and corners[:, 0].max() <= (1 - margin) * SIZE[0] + 0.5
    assert corners[:, 1].min() >= margin * SIZE[1] - 0.5 and corners[:, 1].max() <= (1 - margin) * SIZE[1] + 0.5
    to_edges = np.concatenate([corners[:, 0] - margin * SIZE[0], (1 - margin) * SIZE[0] - corners[:, 0],
                               corners[:, 1] - margin * SIZE[1], (1 - margin) * SIZE[1] - corners[:, 1]])
    assert to_edges.min() < 0.5
    forward, right, up = camera_axes(120.0, -25.0)
    assert np.allclose([forward @ right, forward @ up, right @ up], 0) and math.isclose(forward[2], -math.sin(
        math.radians(25.0)))


def test_the_pistons_video_fills_a_third_of_the_frame_as_it_steps(renderer) -> None:
    scenario = load_scenario("one_dof_step", ["duration_s=2.0"])
    with Session(scenario) as session:
        capture = FrameCapture(session.world, fps=5.0)
        session.loop.add_observer(capture)
        session.run()
    camera = robot_camera(scenario.robot.extras)
    assert camera.fitted
    shares = check_robot_framed(renderer, capture.frames, framed_views(capture.frames, camera, *SIZE))
    assert max(shares) >= 0.6  # a tall thin robot: its height binds, at about FILL of the frame


@pytest.mark.parametrize("robot", ["arm7dof", "planar_arm"])
def test_a_robot_fills_a_third_of_the_frame_in_any_pose(renderer, robot) -> None:
    if robot == "arm7dof":
        session = Session(load_scenario("arm7dof_pose"))
        world, camera = session.world, robot_camera(session.scenario.robot.extras)
        poses = [None, [0.8, 0.6, 0.0, -1.2, 0.0, 0.5, 0.0]]
    else:  # a URDF without colours or a camera of its own: the default camera
        world, camera = MujocoWorld(parse_urdf(urdf_text(), source="planar_arm.urdf")), FITTED
        poses = [[0.0, 0.0], [1.2, -2.0], [-0.6, 1.5]]
    frames = world_frames(world, poses)
    check_robot_framed(renderer, frames, [framed_views([f], camera, *SIZE)[0] for f in frames])


def test_the_camera_follows_a_dropped_weight_and_comes_back_to_the_robot(renderer) -> None:
    scenario = load_scenario("one_dof_drop_weight", ["duration_s=6.0"])  # 10 kg from 4 m at 0.5 s
    with Session(scenario) as session:
        capture = FrameCapture(session.world, fps=10.0)
        session.loop.add_observer(capture)
        session.run()
    frames = capture.frames
    views = framed_views(frames, robot_camera(scenario.robot.extras), *SIZE)
    # While a weight falls from 4 m onto a 1.8 m robot the frame holds both: the robot is drawn whole but smaller.
    check_robot_framed(renderer, frames[::3], views[::3], objects=["weight"], min_share=0.2)
    settled = [k for k, (_, _, t) in enumerate(frames) if t >= 5.0]
    check_robot_framed(renderer, [frames[k] for k in settled], [views[k] for k in settled], objects=["weight"])
    heights = []
    for (model, qpos, time_s), view in zip(frames, views):
        renderer.render(model, qpos, view)
        if time_s >= 0.5:  # spawned: the weight is drawn in the frame at every moment
            top, bottom, left, right = projected_box(renderer, model, qpos, ["weight"])
            assert 0 <= top and bottom <= SIZE[1] and 0 <= left and right <= SIZE[0], time_s
            data = mujoco.MjData(model)
            data.qpos[:] = qpos
            mujoco.mj_kinematics(model, data)
            heights.append((time_s, float(data.xpos[model.body("weight").id][2]), view.distance_m))
    # While it falls from 4 m the view stands back; once it lies on the sensor (1.9 m) it comes closer.
    high = max(d for t, z, d in heights if z > 3.5)
    rest = heights[-1]
    assert rest[1] < 2.1 and rest[2] < 0.8 * high


def test_the_sky_is_a_gradient_and_the_shadow_falls_on_the_floor_beside_the_robot() -> None:
    world = MujocoWorld(parse_urdf(urdf_text(), source="planar_arm.urdf"))
    view = framed_views(world_frames(world, [None]), FITTED, *SIZE)[0]
    lit, shadowed = OffscreenRenderer(*SIZE, shadows=False), OffscreenRenderer(*SIZE)
    try:
        plain = lit.render(world.model, world.data.qpos, view).astype(int)
        with_shadow = shadowed.render(world.model, world.data.qpos, view).astype(int)
        without_robot = lit.render(world.model, world.data.qpos, view, groups=(0,)).astype(int)
    finally:
        lit.close()
        shadowed.close()
    top, middle = without_robot[0, SIZE[0] // 2], without_robot[SIZE[1] // 4, SIZE[0] // 2]
    assert top[2] - top[0] > 40 and top.sum() < middle.sum()  # blue above, paler toward the horizon
    robot = np.abs(plain - without_robot).sum(axis=2) > 30
    darker = (plain - with_shadow).sum(axis=2) > 30
    assert darker.sum() > 100 and not (darker & robot).all()  # a shadow, and not only on the robot itself
    floor_rows = np.nonzero(darker & ~robot)[0]
    assert floor_rows.min() > SIZE[1] // 3  # on the floor, below the horizon


def test_the_floors_grid_lines_are_half_a_metre_apart(renderer) -> None:
    from jointctl.sim.mjcf_builder import GRID_SPACING_M

    world = MujocoWorld(parse_urdf(urdf_text(), source="planar_arm.urdf"))
    top_down = CameraView((1.5, 1.5, 0.0), 4.0, azimuth_deg=90.0, elevation_deg=-89.0)
    floor = renderer.render(world.model, world.data.qpos, top_down, groups=(0,))
    brightness = floor[SIZE[1] // 2].astype(int).sum(axis=1)  # a row along x through y = 1.5 m
    dark = np.nonzero(brightness < brightness.max() - 60)[0]
    lines = [run.mean() for run in np.split(dark, np.nonzero(np.diff(dark) > 1)[0] + 1)]
    metres_per_px = 0.5 / (renderer.project([2.0, 1.5, 0.0])[0] - renderer.project([1.5, 1.5, 0.0])[0])
    spacing_m = np.diff(lines) * metres_per_px
    assert len(lines) >= 4 and np.allclose(spacing_m, GRID_SPACING_M, rtol=0.03), spacing_m


def test_each_picture_carries_its_loop_time_in_the_top_left_corner(renderer) -> None:
    world = MujocoWorld(parse_urdf(urdf_text(), source="planar_arm.urdf"))
    view = framed_views(world_frames(world, [None]), FITTED, *SIZE)[0]
    plain = renderer.render(world.model, world.data.qpos, view).astype(int)
    stamped = renderer.render(world.model, world.data.qpos, view, stamp=time_stamp(12.345)).astype(int)
    rows, columns = np.nonzero(np.abs(stamped - plain).sum(axis=2) > 30)
    assert len(rows) > 50 and rows.max() < SIZE[1] // 4 and columns.max() < SIZE[0] // 2
    assert time_stamp(12.345) == "t = 12.35 s"

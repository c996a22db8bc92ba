"""Videos of runs: frames kept during the run and drawn after it, checked against the camera model."""

from __future__ import annotations

import json
import math
import os
import shutil

import mujoco
import numpy as np
import pytest

from jointctl.errors import JointCtlError
from jointctl.scenario.run import run_scenario
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from jointctl.sim.rendering import CameraView, OffscreenRenderer
from jointctl.visuals.video import FrameCapture, VideoSettings, gif_timing, render_frames, robot_camera

# At 1 m height, 4 m away on -y, looking level: the piston's top (1.5 to 1.8 m) is above eye level, against the
# sky, and its silhouette's top is the near rim of its top face.
LEVEL = CameraView((0.0, 0.0, 1.0), 4.0, azimuth_deg=90.0, elevation_deg=0.0)
SIZE = (320, 240)


def top_rim_points(model, qpos) -> list[np.ndarray]:
    """The near top rims (toward the camera, -y) of link2 (r 0.1 m) and the sensor disk (r 0.05 m)."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    points = []
    for body in ("link2", "ft_sensor_link"):
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        for g in np.nonzero(model.geom_bodyid == b)[0]:
            if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CYLINDER and model.geom_rgba[g][3] > 0:
                centre, axis = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3)[:, 2]
                radius, half = model.geom_size[g][:2]
                points.append(centre + half * axis + np.array([0.0, -radius, 0.0]))
    return points


def first_drawn_row(picture: np.ndarray, without_robot: np.ndarray, column: int) -> int:
    """The highest row of ``column`` where the robot changed the picture (the scenery left alone)."""
    changed = np.abs(picture[:, column].astype(int) - without_robot[:, column].astype(int)).sum(axis=1) > 30
    return int(np.argmax(changed))


@pytest.fixture(scope="module")
def step_frames():
    scenario = load_scenario("one_dof_step")  # -0.2 m to -0.5 m at 0.5 s
    with Session(scenario) as session:
        capture = FrameCapture(session.world, fps=10.0)
        session.loop.add_observer(capture)
        session.run()
    return capture.frames


def test_frames_are_kept_at_the_frame_rate_and_differ_as_the_joint_moves(step_frames) -> None:
    assert [round(t, 3) for _, _, t in step_frames[:4]] == [0.0, 0.1, 0.2, 0.3]
    assert len(step_frames) == 30  # 3 s at 10 fps
    pictures = render_frames(step_frames[::10], VideoSettings(fps=10, width=SIZE[0], height=SIZE[1], mp4=False),
                             LEVEL)
    assert pictures[0].shape == (SIZE[1], SIZE[0], 3)
    assert np.abs(pictures[0].astype(int) - pictures[-1].astype(int)).sum() > 0  # the piston moved


def test_the_pistons_top_edge_is_drawn_where_the_camera_projects_it(step_frames) -> None:
    renderer = OffscreenRenderer(*SIZE, shadows=False)
    try:
        rows = []
        for model, qpos, _ in (step_frames[0], step_frames[-1]):
            without_robot = renderer.render(model, qpos, LEVEL, groups=(0,))  # the sky and the floor
            picture = renderer.render(model, qpos, LEVEL)
            projected = [renderer.project(p) for p in top_rim_points(model, qpos)]
            column = int(round(projected[0][0]))
            expected_row = min(row for _, row in projected)
            assert abs(first_drawn_row(picture, without_robot, column) - expected_row) <= 3.0
            rows.append(expected_row)
    finally:
        renderer.close()
    assert rows[1] - rows[0] > 20  # the 0.3 m step moved the edge down by tens of pixels


def test_run_video_writes_an_mp4_and_a_small_gif(tmp_path) -> None:
    if shutil.which("ffmpeg") is None:
        # The only end-to-end MP4/GIF test: where a run must not skip (CI sets JOINTCTL_REQUIRE_ROS and
        # JOINTCTL_REQUIRE_BROWSER; any JOINTCTL_REQUIRE_* says so), a missing ffmpeg is a failure.
        required = sorted(name for name, value in os.environ.items() if name.startswith("JOINTCTL_REQUIRE_") and value)
        if required:
            pytest.fail(f"{', '.join(required)} set but ffmpeg is missing (make render installs it)")
        pytest.skip("ffmpeg is missing (make render installs it)")
    scenario = load_scenario("one_dof_step", ["duration_s=1.0"])
    metrics = run_scenario(scenario, tmp_path, video=VideoSettings(fps=20, width=320, height=240))
    assert metrics["video"]["frames"] == 20
    from PIL import Image

    gif = Image.open(tmp_path / "video.gif")
    assert gif.n_frames == 20 and gif.size == (320, 240)
    assert (tmp_path / "video.mp4").read_bytes()[4:8] == b"ftyp"  # an MP4 container
    assert json.loads((tmp_path / "metrics.json").read_text())["video"]["gif"].endswith("video.gif")


@pytest.mark.parametrize("fps", [10, 15, 24, 30, 60, 120])
def test_a_gif_plays_at_the_runs_speed(fps) -> None:
    frames = 3 * fps  # three seconds of run
    every, durations_ms = gif_timing(frames, fps)
    assert len(durations_ms) == math.ceil(frames / every) and min(durations_ms) >= 20  # browsers slow < 2 cs
    assert all(d % 10 == 0 for d in durations_ms)  # whole hundredths: what a GIF stores
    starts = np.cumsum([0, *durations_ms])
    assert np.abs(starts - np.arange(len(starts)) * every * 1000 / fps).max() <= 5.0
    assert starts[-1] == pytest.approx(3000, abs=5)


def test_a_written_gif_holds_those_delays(tmp_path) -> None:
    from PIL import Image

    from jointctl.visuals.video import _write_gif

    pictures = [np.full((24, 32, 3), 10 * k, dtype=np.uint8) for k in range(15)]  # one second at 15 fps
    gif = Image.open(_write_gif(pictures, tmp_path / "v.gif", 15.0))
    delays = []
    for k in range(gif.n_frames):
        gif.seek(k)
        delays.append(gif.info["duration"])
    assert gif.n_frames == 15 and sum(delays) == 1000 and set(delays) == {60, 70}


def test_the_robots_camera_comes_from_its_manifest_and_is_fitted_unless_it_says_where() -> None:
    camera = robot_camera(load_scenario("one_dof_step").robot.extras)
    assert camera == CameraView(None, None, azimuth_deg=90.0, elevation_deg=-12.0) and camera.fitted
    fixed = robot_camera({"video": {"camera": {"lookat": [0, 0, 2], "distance_m": 5.5}}})
    assert fixed == CameraView((0.0, 0.0, 2.0), 5.5, 90.0, -15.0) and not fixed.fitted


@pytest.mark.parametrize("config, field", [
    ({"lookat": [0, 0]}, "camera.lookat"),
    ({"distance_m": 0}, "camera.distance_m"),
    ({"elevation_deg": 95}, "camera.elevation_deg"),
    ({"zoom": 2}, "camera.zoom"),
])
def test_a_bad_camera_is_refused_naming_the_key(config, field) -> None:
    with pytest.raises(JointCtlError) as info:
        CameraView.from_config(config)
    assert info.value.field == field


@pytest.mark.parametrize("kwargs, field", [
    (dict(fps=0), "--video-fps"), (dict(width=641), "--video-size"), (dict(height=8), "--video-size"),
])
def test_bad_video_settings_are_refused(kwargs, field) -> None:
    with pytest.raises(JointCtlError) as info:
        VideoSettings(mp4=False, **kwargs)
    assert info.value.field == field

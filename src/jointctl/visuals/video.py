"""Videos of runs: the world's states kept during the run, drawn offscreen after it, to MP4 and GIF.

:class:`FrameCapture` is a loop observer: every ``1 / fps`` of loop time it keeps the world's
``qpos`` and the model it belongs to (a spawned weight changes the model). Nothing is drawn while
the loop runs, so a video never slows the loop or changes the trace. :func:`write_video` then draws
each kept state with :class:`~jointctl.sim.rendering.OffscreenRenderer` from the robot's camera
(``video.camera`` in its ``robot.yaml``, or the one given) and writes ``video.mp4`` (H.264 through
Debian's ``ffmpeg``) and a small animated ``video.gif`` (Pillow, at most ``GIF_WIDTH`` pixels wide).
By default the camera only says the direction it looks from; where it stands is fitted to the robot
and the objects in each picture (:mod:`jointctl.visuals.framing`), and each picture carries the
loop time in its top left corner.
"""

from __future__ import annotations

import math
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointctl.errors import JointCtlError
from jointctl.sim.rendering import CameraView, OffscreenRenderer
from jointctl.visuals.framing import framed_views

#: The GIF's largest width [px] (the MP4 has the full size).
GIF_WIDTH = 320
#: The default camera: from the front (-y), a little above; fitted to the scene.
DEFAULT_CAMERA = {"azimuth_deg": 90.0, "elevation_deg": -15.0}


@dataclass(frozen=True)
class VideoSettings:
    """``fps`` [frames per second of loop time], ``width`` x ``height`` [px, even], ``camera``, and
    whether to write the MP4 (``mp4``: needs ffmpeg) besides the GIF."""

    fps: float = 25.0
    width: int = 640
    height: int = 480
    camera: CameraView | None = None
    mp4: bool = True

    def __post_init__(self) -> None:
        if not (isinstance(self.fps, (int, float)) and math.isfinite(self.fps) and 1 <= self.fps <= 120):
            raise JointCtlError("must be 1 to 120 frames per second", field="--video-fps", value=self.fps)
        for name, value in (("width", self.width), ("height", self.height)):
            if not (isinstance(value, int) and 16 <= value <= 4096 and value % 2 == 0):
                raise JointCtlError(f"the {name} must be an even number of pixels from 16 to 4096 (H.264)",
                                    field="--video-size", value=f"{self.width}x{self.height}")
        if self.mp4 and shutil.which("ffmpeg") is None:
            raise JointCtlError("ffmpeg is missing for the MP4 ('make render' installs Debian's ffmpeg)",
                                field="--video", value="ffmpeg")

    @staticmethod
    def parse_size(text: str) -> tuple[int, int]:
        """``"640x480"`` -> (640, 480); an error naming ``--video-size`` otherwise."""
        width, sep, height = str(text).lower().partition("x")
        if not (sep and width.isdigit() and height.isdigit()):
            raise JointCtlError("must be WIDTHxHEIGHT in pixels, e.g. 640x480", field="--video-size", value=text)
        return int(width), int(height)


def robot_camera(robot_extras: dict, *, source: str | None = None) -> CameraView:
    """The camera of a robot's ``robot.yaml`` (``video: {camera: ...}``), else a default one."""
    video = robot_extras.get("video") or {}
    if not isinstance(video, dict):
        raise JointCtlError("must be a mapping {camera: ...}", source=source, field="video", value=video)
    return CameraView.from_config(video.get("camera", DEFAULT_CAMERA), field="video.camera", source=source)


class FrameCapture:
    """A loop observer keeping ``world``'s state every ``1 / fps`` of loop time (see the module docstring)."""

    def __init__(self, world, fps: float) -> None:
        self.world = world
        self.period_s = 1.0 / fps
        self.frames: list[tuple[object, np.ndarray, float]] = []  # (model, qpos, loop time [s])
        self._next_s = 0.0

    def __call__(self, time_s: float) -> None:
        if time_s + 1e-9 >= self._next_s:
            self._next_s += self.period_s
            self.frames.append((self.world.model, self.world.data.qpos.copy(), time_s))


def time_stamp(time_s: float) -> str:
    """The text a picture carries: the loop time [s]."""
    return f"t = {time_s:.2f} s"


def render_frames(frames, settings: VideoSettings, camera: CameraView) -> list[np.ndarray]:
    """Each kept state drawn from ``camera`` (fitted to each one when it is a fitted view), stamped
    with its loop time: a list of (height, width, 3) uint8 pictures."""
    views = framed_views(frames, camera, settings.width, settings.height)
    renderer = OffscreenRenderer(settings.width, settings.height)
    try:
        return [renderer.render(model, qpos, view, stamp=time_stamp(time_s))
                for (model, qpos, time_s), view in zip(frames, views)]
    finally:
        renderer.close()


def write_video(frames, out_dir: str | Path, settings: VideoSettings, camera: CameraView) -> dict[str, str]:
    """Draw ``frames`` (from :class:`FrameCapture`) and write ``video.gif`` (and ``video.mp4``); their paths."""
    if not frames:
        raise JointCtlError("the run kept no frames", field="--video")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    pictures = render_frames(frames, settings, camera)
    written = {"gif": str(_write_gif(pictures, out / "video.gif", settings.fps))}
    if settings.mp4:
        written["mp4"] = str(_write_mp4(pictures, out / "video.mp4", settings))
    return written


def _write_mp4(pictures: list[np.ndarray], path: Path, settings: VideoSettings) -> Path:
    command = ["ffmpeg", "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
               "-s", f"{settings.width}x{settings.height}", "-r", f"{settings.fps:g}", "-i", "-",
               "-c:v", "libx264", "-pix_fmt", "yuv420p", "-movflags", "+faststart", str(path)]
    result = subprocess.run(command, input=b"".join(p.tobytes() for p in pictures), capture_output=True)
    if result.returncode != 0:
        raise JointCtlError(f"ffmpeg failed: {result.stderr.decode(errors='replace').strip()[-300:]}",
                            field="--video", value=str(path))
    return path


def gif_timing(frames: int, fps: float) -> tuple[int, list[int]]:
    """(keep every n-th frame, each kept frame's duration [ms]) so that a GIF plays at the run's
    speed. A GIF counts frame delays in whole hundredths of a second and browsers slow delays under
    2 cs down to 10 cs: above 50 fps frames are dropped, and the delays alternate (for 15 fps: 7, 7,
    6 cs) so that frame k starts at k/fps to within 5 ms, where one rounded delay would drift (15 fps
    as 6 cs plays 11 % fast)."""
    every = max(1, math.ceil(fps / 50.0))
    shown = fps / every
    starts = [round(100 * k / shown) for k in range(math.ceil(frames / every) + 1)]
    return every, [10 * (b - a) for a, b in zip(starts, starts[1:])]


def _write_gif(pictures: list[np.ndarray], path: Path, fps: float) -> Path:
    from PIL import Image

    every, durations_ms = gif_timing(len(pictures), fps)
    images = [Image.fromarray(p) for p in pictures[::every]]
    if images[0].width > GIF_WIDTH:
        size = (GIF_WIDTH, round(images[0].height * GIF_WIDTH / images[0].width))
        images = [image.resize(size, Image.Resampling.BILINEAR) for image in images]
    images = [image.quantize(colors=64) for image in images]
    images[0].save(path, save_all=True, append_images=images[1:], duration=durations_ms, loop=0, optimize=True)
    return path


__all__ = ["DEFAULT_CAMERA", "FrameCapture", "GIF_WIDTH", "VideoSettings", "gif_timing", "render_frames",
           "robot_camera", "time_stamp", "write_video"]

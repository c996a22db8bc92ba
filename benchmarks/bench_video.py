"""Videos of runs: drawing cost.

*Frames per second* drawn offscreen (Mesa's software EGL) at 640x480, the 1-DOF drop-weight run's
states (the robot and the falling weight), the camera fitted to each, with the sun's shadows and the
time stamp; and the same without shadows. *Whole run*: ``one_dof_drop_weight`` with ``--video``
(25 fps, 640x480, MP4 and GIF) over the same run without, in the same process: the video's cost
as a multiple of the run's.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from benchmarks.common import Result


def run() -> list[Result]:
    from jointctl.scenario.run import run_scenario
    from jointctl.scenario.session import Session
    from jointctl.scenario.spec import load_scenario
    from jointctl.sim.rendering import OffscreenRenderer
    from jointctl.visuals.framing import framed_views
    from jointctl.visuals.video import FrameCapture, VideoSettings, robot_camera, time_stamp

    scenario = load_scenario("one_dof_drop_weight")
    with Session(scenario) as session:
        capture = FrameCapture(session.world, 25.0)
        session.loop.add_observer(capture)
        session.run()
    camera = robot_camera(scenario.robot.extras)
    rates = {}
    for shadows in (True, False):
        renderer = OffscreenRenderer(640, 480, shadows=shadows)
        try:
            t0 = time.perf_counter()
            views = framed_views(capture.frames, camera, 640, 480)
            renderer.render(*capture.frames[0][:2], views[0])  # the first draw builds the context
            for (model, qpos, time_s), view in zip(capture.frames, views):
                renderer.render(model, qpos, view, stamp=time_stamp(time_s))
            rates[shadows] = len(capture.frames) / (time.perf_counter() - t0)
        finally:
            renderer.close()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        run_scenario(scenario, Path(tmp) / "plain")
        plain = time.perf_counter() - t0
        t0 = time.perf_counter()
        run_scenario(scenario, Path(tmp) / "video", video=VideoSettings(fps=25.0, width=640, height=480))
        with_video = time.perf_counter() - t0
    return [
        Result("video", "frames drawn per second, 640x480, fitted camera, shadows", rates[True], "/s"),
        Result("video", "frames drawn per second, 640x480, fitted camera, no shadows", rates[False], "/s"),
        Result("video", "drop-weight run with --video / without", with_video / plain, "x"),
    ]


if __name__ == "__main__":
    for row in run():
        print(row)

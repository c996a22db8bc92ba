"""Videos of runs: drawing cost.

*Frames per second* drawn offscreen (Mesa's software EGL) at 640x480, the 1-DOF drop-weight run's
states (the robot and the falling weight). *Whole run*: ``one_dof_drop_weight`` with ``--video``
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
    from jointctl.visuals.video import FrameCapture, VideoSettings, robot_camera

    scenario = load_scenario("one_dof_drop_weight")
    with Session(scenario) as session:
        capture = FrameCapture(session.world, 25.0)
        session.loop.add_observer(capture)
        session.run()
    camera = robot_camera(scenario.robot.extras)
    renderer = OffscreenRenderer(640, 480)
    try:
        renderer.render(*capture.frames[0][:2], camera)  # the first draw builds the context
        t0 = time.perf_counter()
        for model, qpos, _ in capture.frames:
            renderer.render(model, qpos, camera)
        fps = len(capture.frames) / (time.perf_counter() - t0)
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
        Result("video", "frames drawn per second, 640x480", fps, "/s"),
        Result("video", "drop-weight run with --video / without", with_video / plain, "x"),
    ]


if __name__ == "__main__":
    for row in run():
        print(row)

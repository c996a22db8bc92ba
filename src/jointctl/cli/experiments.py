"""``jointctl list``, ``run`` and ``demo``: the built-in robots and scenarios, one run, every experiment."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jointctl.cli.common import (CONTROLLERS_HELP, SET_VALUES, TARGET_HELP, positive_speed, say_warnings,
                                 target_scenario)
from jointctl.errors import JointCtlError
from jointctl.recording.metrics_file import metrics_json


#: How long ``run`` holds a robot given as its target [s].
ROBOT_RUN_S = 5.0


def add_parsers(sub) -> None:
    listing = sub.add_parser("list", help="list built-in robots and scenarios")
    listing.set_defaults(handler=_list)

    run = sub.add_parser("run", help="run a scenario (or hold a robot for a while) and write trace.csv, "
                                     "metrics.json and figures")
    run.add_argument("target", metavar="scenario", help=f"{TARGET_HELP}; a robot is held where its controllers "
                                                        f"start for {ROBOT_RUN_S:g} s (--set duration_s=...)")
    run.add_argument("--controllers", default=None, help=CONTROLLERS_HELP)
    run.add_argument("--out", type=Path, help="output folder (default: out/<scenario name>)")
    run.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scenario field, e.g. gravity=-5 or "
                          f"controllers.joint1_position_controller.pid.p=1e3; {SET_VALUES}")
    run.add_argument("--realtime", action="store_true", help="pace the loop to the wall clock")
    run.add_argument("--speed", type=float, default=1.0,
                     help="with --realtime: loop time per wall-clock time (default 1.0)")
    run.add_argument("--package-path", action="append", default=[], metavar="DIR",
                     help="folder searched for $(find pkg) and package:// (repeatable)")
    run.add_argument("--view", action="store_true",
                     help="show the run in MuJoCo's viewer as it goes (a desktop window; paced to the wall clock)")
    run.add_argument("--video", action="store_true",
                     help="draw the run offscreen after it: video.mp4 and a small video.gif in the output folder")
    run.add_argument("--video-fps", type=float, default=25.0, help="frames per second of loop time (default 25)")
    run.add_argument("--video-size", default="640x480", help="WIDTHxHEIGHT in pixels, even (default 640x480)")
    run.add_argument("--video-camera", metavar="[X,Y,Z,DISTANCE,]AZIMUTH,ELEVATION",
                     help="the camera: azimuth and elevation [deg], fitted to the robot and objects in each "
                          "picture; or also the point looked at [m] and the distance [m], fixed "
                          "(default: the robot's, from robot.yaml)")
    run.add_argument("--no-mcap", dest="mcap", action="store_false",
                     help="do not write run.mcap (the record for Foxglove and PlotJuggler) beside trace.csv")
    run.set_defaults(handler=_run)

    demo = sub.add_parser("demo", help="run every built-in experiment and write report.md")
    demo.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder")
    demo.set_defaults(handler=_demo)


def _list(args: argparse.Namespace) -> int:
    from jointctl.scenario.spec import builtin_robots, builtin_scenarios, load_scenario

    print("robots:")
    for name, folder in builtin_robots().items():
        print(f"  {name:<24} {folder}")
    print("scenarios:")
    for name in builtin_scenarios():
        summary = load_scenario(name).description.split(". ")[0]
        print(f"  {name:<24} {summary}")
    return 0


def _run(args: argparse.Namespace) -> int:
    from jointctl.scenario.run import run_scenario

    positive_speed(args)
    scenario = target_scenario(args, robot_defaults=[f"duration_s={ROBOT_RUN_S}"])
    out = args.out or Path("out") / scenario.name
    if args.view:
        from jointctl.visuals.viewer import check_display

        check_display()  # before anything runs
    metrics = run_scenario(scenario, out, realtime=args.realtime or args.view, speed=args.speed,
                           package_path=tuple(args.package_path), video=_video_settings(args), view=args.view,
                           mcap=args.mcap)
    shown = {k: v for k, v in metrics.items() if k not in ("plant",)}
    print(metrics_json(shown))
    say_warnings(metrics)
    print(f"wrote {out}/", file=sys.stderr)
    return 0


def _video_settings(args: argparse.Namespace):
    """``run --video``'s settings, checked before anything runs; None without --video."""
    if not args.video:
        return None
    from jointctl.sim.rendering import CameraView
    from jointctl.visuals.video import VideoSettings

    width, height = VideoSettings.parse_size(args.video_size)
    camera = None
    if args.video_camera is not None:
        parts = args.video_camera.split(",")
        try:
            numbers = [float(p) for p in parts]
        except ValueError:
            numbers = []
        if len(numbers) not in (2, 6):
            raise JointCtlError("must be AZIMUTH,ELEVATION (fitted to the scene) or X,Y,Z,DISTANCE,AZIMUTH,ELEVATION",
                                field="--video-camera", value=args.video_camera)
        keys = ("azimuth_deg", "elevation_deg") if len(numbers) == 2 else ("x", "y", "z", "distance_m",
                                                                            "azimuth_deg", "elevation_deg")
        config = dict(zip(keys, numbers))
        if len(numbers) == 6:
            config["lookat"] = [config.pop("x"), config.pop("y"), config.pop("z")]
        camera = CameraView.from_config(config, field="--video-camera")
    return VideoSettings(fps=args.video_fps, width=width, height=height, camera=camera)


def _demo(args: argparse.Namespace) -> int:
    from jointctl.scenario.run import run_demo
    from jointctl.sweep.demo import demo_section

    report = run_demo(args.out, sections=[demo_section])
    print(f"wrote {report}")
    return 0

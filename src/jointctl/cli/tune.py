"""``jointctl tune``: the tuning page (live plots, gains, command sources) on a robot run on the wall clock."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from jointctl.cli.common import foxglove_argument, live_scenario, live_target_arguments, ros2_edge, start_foxglove
from jointctl.errors import JointCtlError

LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")


def add_parsers(sub) -> None:
    tune = sub.add_parser("tune", help="the tuning page: live plots, gains and command sources in the browser")
    live_target_arguments(tune)
    tune.add_argument("--port", type=int, default=8765, help="TCP port of the page (default 8765; 0: any free port)")
    tune.add_argument("--host", default="127.0.0.1",
                      help="address to listen on (default 127.0.0.1; another needs --allow-remote)")
    tune.add_argument("--allow-remote", action="store_true",
                      help="allow --host other than loopback: anyone reaching it can move the robot")
    tune.add_argument("--out", type=Path, default=Path("out/tune"), help="where 'Write gains YAML' writes")
    tune.add_argument("--view", action="store_true", help="also show the robot in MuJoCo's viewer (a desktop window)")
    tune.add_argument("--ros2", action="store_true",
                      help="also serve the robot on ROS 2 as serve --ros2 does (its setup.bash sourced in this shell)")
    foxglove_argument(tune)
    tune.set_defaults(handler=_tune)


def _tune(args: argparse.Namespace) -> int:
    from jointctl.tuning.server import check_static_files, serve_tuning
    from jointctl.tuning.tuner import Tuner

    if not 0 <= args.port <= 65535:
        raise JointCtlError("must be a TCP port, 0 to 65535", field="--port", value=args.port)
    if args.host not in LOOPBACK_HOSTS:
        if not args.allow_remote:
            raise JointCtlError("the page moves the robot: listening beyond this machine needs --allow-remote",
                                field="--host", value=args.host)
        print(f"jointctl: warning: listening on {args.host}: anyone who can reach it can change gains and move "
              "the robot (the page has no login)", file=sys.stderr)
    if args.foxglove is not None:
        from jointctl.recording.foxglove_live import check_port

        check_port(args.foxglove)  # refused before anything starts
    check_static_files()
    if args.view:
        from jointctl.visuals.viewer import LiveViewer, check_display

        check_display()
    tuner = Tuner(live_scenario(args), out_dir=args.out)
    viewer = None
    if args.view:
        if tuner.session.world is None:
            raise JointCtlError("the viewer shows the simulation; this robot has none", field="--view")
        viewer = LiveViewer(tuner.session.world, tuner.loop, stop_when_closed=False)
        tuner.loop.add_observer(viewer)
    live = None
    ros2 = contextlib.nullcontext()
    if args.ros2:
        ros2 = ros2_edge("node").on_ros2(tuner.session, speed=args.speed)
    try:
        live = start_foxglove(args, tuner.session, host=args.host)
        with ros2 as robot:
            if robot is not None:
                robot.start_callbacks()
            serve_tuning(tuner, host=args.host, port=args.port, speed=args.speed)
    finally:
        if live is not None:
            live.stop()
        if viewer is not None:
            viewer.close()  # its window's thread would keep the process alive
    return 0

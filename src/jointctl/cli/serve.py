"""``jointctl serve``: a robot or a scenario as a ROS 1 node, with the chapter's topic and action names, or with
``--ros2`` as a ros2_control robot on ROS 2 (jointctl.ros2.node); optionally recorded (``--record DIR``: trace.csv,
run.mcap) and streamed to Foxglove (``--foxglove [PORT]``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jointctl.cli.common import (foxglove_argument, industrial_arguments, industrial_hardware, live_scenario,
                                 live_target_arguments, ros2_edge, ros_edge, start_foxglove)


def add_parsers(sub) -> None:
    serve = sub.add_parser("serve", help="run a robot or a scenario as a ROS 1 node (chapter topic names), or with "
                                         "--ros2 as a ros2_control robot")
    live_target_arguments(serve)
    serve.add_argument("--ros2", action="store_true",
                       help="serve on ROS 2 (its setup.bash sourced in this shell) as a ros2_control robot: "
                            "/controller_manager, /joint_states, the controllers under ros2_controllers' names")
    serve.add_argument("--sim-time", action="store_true", help="publish /clock with loop time, use_sim_time")
    serve.add_argument("--rviz", action="store_true",
                       help="also run robot_state_publisher and rviz (jointctl's config) when installed; what cannot "
                            "start is said in one line and the node serves on")
    serve.add_argument("--hardware", choices=("sim", "industrial"), default="sim",
                       help="sim: the robot in MuJoCo (default); industrial: a robot controller that interpolates "
                            "by itself, over simple_message (with --robot-ip; controllers default to 'industrial')")
    industrial_arguments(serve)
    foxglove_argument(serve)
    serve.add_argument("--record", type=Path, default=None, metavar="DIR",
                       help="record the served run into DIR: trace.csv and run.mcap, written when the node stops")
    serve.set_defaults(handler=_serve)


def _serve(args: argparse.Namespace) -> int:
    from jointctl.scenario.session import Session

    scenario = live_scenario(args)
    if args.foxglove is not None:
        from jointctl.recording.foxglove_live import check_port

        check_port(args.foxglove)  # refused before anything starts
    if args.ros2:
        return _serve_ros2(args, scenario)
    node = ros_edge("node")
    ros_section = scenario.robot.extras.get("ros") or {}
    source = str(scenario.robot.folder)
    hardware = industrial_hardware(args, scenario) if args.hardware == "industrial" else None
    session = Session(scenario, hardware=hardware, out_dir=args.record, mcap=args.record is not None)
    live = None
    started = {c.name for c in session.manager.active}
    actions = {name: spec for name, spec in node.check_actions(ros_section.get("actions"), source).items()
               if spec["controller"] in started}
    topics = {topic: name
              for topic, name in node.check_command_topics(ros_section.get("command_topics"), source).items()
              if name in started}
    try:
        live = start_foxglove(args, session)
        node.serve(session, sim_time=args.sim_time, speed=args.speed, actions=actions, command_topics=topics,
                   rviz=args.rviz)
    finally:
        if live is not None:
            live.stop()
        if hardware is not None:
            hardware.close()
        session.close()  # the records of --record
    if args.record is not None:
        print(f"jointctl: wrote {args.record}/trace.csv and run.mcap", file=sys.stderr)
    return 0


def _serve_ros2(args: argparse.Namespace, scenario) -> int:
    """``serve --ros2``: the session as a ros2_control robot (jointctl.ros2.node)."""
    from jointctl.scenario.session import Session

    if args.rviz:
        from jointctl.errors import JointCtlError

        raise JointCtlError("--rviz starts ROS 1's rviz; on ROS 2 run rviz2 against /robot_description and /tf",
                            field="--rviz", value=True)
    node = ros2_edge("node")
    hardware = industrial_hardware(args, scenario) if args.hardware == "industrial" else None
    session = Session(scenario, hardware=hardware, out_dir=args.record, mcap=args.record is not None)
    live = None
    try:
        live = start_foxglove(args, session)
        node.serve(session, sim_time=args.sim_time, speed=args.speed)
    finally:
        if live is not None:
            live.stop()
        if hardware is not None:
            hardware.close()
        session.close()
    if args.record is not None:
        print(f"jointctl: wrote {args.record}/trace.csv and run.mcap", file=sys.stderr)
    return 0

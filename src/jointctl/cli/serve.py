"""``jointctl serve``: a robot or a scenario as a ROS 1 node, with the chapter's topic and action names."""

from __future__ import annotations

import argparse

from jointctl.cli.common import (industrial_arguments, industrial_hardware, live_scenario,
                                 live_target_arguments, ros_edge)


def add_parsers(sub) -> None:
    serve = sub.add_parser("serve", help="run a robot or a scenario as a ROS 1 node (chapter topic names)")
    live_target_arguments(serve)
    serve.add_argument("--sim-time", action="store_true", help="publish /clock with loop time, use_sim_time")
    serve.add_argument("--rviz", action="store_true",
                       help="also run robot_state_publisher and rviz (jointctl's config) when installed; what cannot "
                            "start is said in one line and the node serves on")
    serve.add_argument("--hardware", choices=("sim", "industrial"), default="sim",
                       help="sim: the robot in MuJoCo (default); industrial: a robot controller that interpolates "
                            "by itself, over simple_message (with --robot-ip; controllers default to 'industrial')")
    industrial_arguments(serve)
    serve.set_defaults(handler=_serve)


def _serve(args: argparse.Namespace) -> int:
    from jointctl.scenario.session import Session

    scenario = live_scenario(args)
    node = ros_edge("node")
    ros_section = scenario.robot.extras.get("ros") or {}
    source = str(scenario.robot.folder)
    hardware = industrial_hardware(args, scenario) if args.hardware == "industrial" else None
    session = Session(scenario, hardware=hardware)
    started = {c.name for c in session.manager.active}
    actions = {name: spec for name, spec in node.check_actions(ros_section.get("actions"), source).items()
               if spec["controller"] in started}
    topics = {topic: name
              for topic, name in node.check_command_topics(ros_section.get("command_topics"), source).items()
              if name in started}
    try:
        node.serve(session, sim_time=args.sim_time, speed=args.speed, actions=actions, command_topics=topics,
                   rviz=args.rviz)
    finally:
        if hardware is not None:
            hardware.close()
    return 0

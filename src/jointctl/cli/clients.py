"""The chapter's clients: ``jointctl prompt`` and ``play`` (the arm, in-process or over ROS with --ros),
``sine`` and ``traj-client`` (ROS)."""

from __future__ import annotations

import argparse
from pathlib import Path

from jointctl.cli.common import positive_speed, ros_edge


def add_parsers(sub) -> None:
    prompt = sub.add_parser("prompt", help="the chapter's prompter client: move one joint at a time")
    prompt.add_argument("robot", choices=["arm7dof"], help="the robot (the arm7dof_streamer scenario)")
    play = sub.add_parser("play", help="the chapter's playfile client: execute a CSV path file on arm7dof")
    play.add_argument("pathfile", type=Path, help="CSV file: 7 joint angles (rad) a line, no times")
    play.add_argument("--timing", choices=["chapter", "ruckig"], default="chapter",
                      help="path timing: the chapter's rule (default) or jerk-limited ruckig")
    for client in (prompt, play):
        client.add_argument("--realtime", action="store_true", help="pace the loop to the wall clock")
        client.add_argument("--speed", type=float, default=1.0,
                            help="with --realtime: loop time per wall-clock time (default 1.0)")
        client.add_argument("--out", type=Path, help="record trace.csv into this folder")
        client.add_argument("--ros", action="store_true",
                            help="drive a served arm over ROS (jointctl serve arm7dof --controllers trajectory) "
                                 "instead of an in-process simulation")

    sine = sub.add_parser("sine", help="the chapter's sine commander: publish a sine to a served robot (ROS)")
    sine.add_argument("--namespace", default="one_DOF_robot", help="the robot's namespace (default one_DOF_robot)")
    sine.add_argument("--joint", default="joint1", help="the joint whose controllers are commanded (default joint1)")

    traj = sub.add_parser("traj-client", help="the chapter's example trajectory client: a coarse sine goal (ROS)")
    traj.add_argument("--seed", type=int, default=7, help="seed of the irregular sample times (default 7)")
    traj.add_argument("--server", default="example_traj_action_server",
                      help="the TrajAction server (default example_traj_action_server)")
    prompt.set_defaults(handler=_prompt)
    play.set_defaults(handler=_play)
    sine.set_defaults(handler=_sine)
    traj.set_defaults(handler=_traj_client)


def _sender(args: argparse.Namespace):
    """Where the arm clients send goals: a simulation in this process, or a served arm over ROS (--ros)."""
    positive_speed(args)
    if args.ros:
        return ros_edge("arm_client").RosGoalSender()
    from jointctl.clients.arm import InProcessGoalSender

    return InProcessGoalSender.open(realtime=args.realtime, speed=args.speed, out_dir=args.out)


def _prompt(args: argparse.Namespace) -> int:
    from jointctl.clients.arm import prompt_command

    return prompt_command(_sender(args))


def _play(args: argparse.Namespace) -> int:
    from jointctl.clients.arm import play_command

    return play_command(_sender(args), args.pathfile, timing=args.timing)


def _sine(args: argparse.Namespace) -> int:
    return ros_edge("clients").sine_command(namespace=args.namespace, joint=args.joint)


def _traj_client(args: argparse.Namespace) -> int:
    return ros_edge("clients").traj_client_command(seed=args.seed, server=args.server)

"""The ``jointctl`` command: one module a command family, each adding its sub-commands to the parser.

    jointctl list                                   built-in robots and scenarios
    jointctl run SCENARIO [--out DIR] [--set K=V]   run one scenario (or hold a robot): trace.csv, metrics.json, PNGs
    jointctl init ROBOT.urdf|xacro [--out DIR]      a robot folder for your own robot, starting gains from its model
    jointctl demo [--out DIR]                       every built-in experiment and report.md
    jointctl serve ROBOT --controllers NAME         the robot as a ROS 1 node (chapter topic and action names)
    jointctl prompt arm7dof [--out DIR]             move the arm one joint at a time (prompter)
    jointctl play PATHFILE [--timing T] [--out DIR] execute a CSV path file on the arm (playfile)
    jointctl prompt arm7dof --ros / play PATHFILE --ros   the same clients on a served arm (actionlib)
    jointctl sine [--namespace NS] [--joint J]      the chapter's sine commander as a ROS node
    jointctl traj-client [--seed N] [--server S]    the chapter's example trajectory action client
    jointctl tune ROBOT --controllers NAME [--port P]  the tuning page: live plots, gains, sources
    jointctl controller ROBOT [--motion-port P]     a simulated industrial controller (simple_message)
    jointctl identify ROBOT|TRACE|BAG --joint J [--hardware ros]  fit a joint's inertia, damping, friction, gravity
    jointctl bode ROBOT --controller NAME [--out DIR]     a loop's measured frequency response and its model
    jointctl autotune ROBOT --controller NAME --zeta Z --bandwidth-hz F   gains for a spec, as the chapter's YAML
                     (or --overshoot-pct P --settling-s T)
    identify, bode, autotune --hardware ros2   the same on a ros2_control robot (ROS 2 sourced): its pid_controller
    identify, bode, autotune: --max-effort N --max-velocity V --workspace LOWER:UPPER --dry-run
                     (limits planned within and watched: docs/real-robots.md)
    jointctl sweep SCENARIO --vary FIELD=VALUES [--samples N --seed S] [--spec M<=X] [--scheduler ADDR]
                     a scenario over grids and distributions (gains, plant, payload, latency, noise) on Dask

Every error a user can cause is printed as one line naming the file, field
and value, with exit status 2.
"""

from __future__ import annotations

import argparse
import sys

from jointctl import __version__
from jointctl.cli import analyses, clients, controller, experiments, init, serve, sweep, tune
from jointctl.errors import JointCtlError

EXIT_USAGE = 2
#: The command families, in the order ``jointctl --help`` lists their commands.
FAMILIES = (experiments, init, serve, clients, tune, controller, analyses, sweep)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="jointctl", description="Joint-level robot control on MuJoCo.")
    parser.add_argument("--version", action="version", version=f"jointctl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for family in FAMILIES:
        family.add_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.handler(args)
    except JointCtlError as exc:
        print(f"jointctl: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("jointctl: interrupted", file=sys.stderr)
        return 130

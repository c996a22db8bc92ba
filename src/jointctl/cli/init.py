"""``jointctl init``: a robot folder for a user's own URDF or xacro, with starting gains from its model."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from jointctl.errors import JointCtlError


def add_parsers(sub) -> None:
    init = sub.add_parser("init", help="write a robot folder for your own URDF/xacro: robot.yaml, a ros_control YAML "
                                       "and a ROS 2 controller_manager YAML with starting gains from the model, the "
                                       "description with its <ros2_control>, a step scenario")
    init.add_argument("description", help="the robot's .urdf or .xacro")
    init.add_argument("--out", type=Path, help="the folder to write (default: ./<robot name>)")
    init.add_argument("--bandwidth-hz", type=float, default=2.0,
                      help="closed-loop bandwidth of the starting position loops [Hz] (default 2: gentle)")
    init.add_argument("--zeta", type=float, default=0.7, help="their damping ratio (default 0.7)")
    init.add_argument("--gravity", type=float, default=-9.81, help="gravity along z [m/s²] (default -9.81)")
    init.add_argument("--package-path", action="append", default=[], metavar="DIR",
                      help="folder searched for $(find pkg) and package:// (repeatable)")
    init.add_argument("--force", action="store_true", help="overwrite the files of an existing folder")
    init.set_defaults(handler=_init)


def _init(args: argparse.Namespace) -> int:
    from jointctl.identification.starting_gains import starting_gains
    from jointctl.model.loader import load_robot_model
    from jointctl.scenario.robot_folder import write_robot_folder

    description = Path(args.description)
    if description.suffix not in (".urdf", ".xacro"):
        raise JointCtlError("must be a .urdf or .xacro file", field="description", value=args.description)
    robot = load_robot_model(description, search_path=tuple(args.package_path))
    loops = starting_gains(robot, bandwidth_hz=args.bandwidth_hz, zeta=args.zeta, gravity_m_s2=(0.0, 0.0, args.gravity))
    out = args.out or Path(robot.name)
    files = write_robot_folder(description, out, robot.name, loops, bandwidth_hz=args.bandwidth_hz, zeta=args.zeta,
                               gravity_z_m_s2=args.gravity, force=args.force, ros2_description=not robot.ros2_control)
    print(f"{'joint':<16} {'home':>8} {'inertia':>10} {'gravity':>9} {'limit':>8} {'p':>10} {'d':>9} {'Hz':>6}")
    for loop in loops:
        print(f"{loop.joint:<16} {loop.home:>8.4g} {loop.inertia:>10.4g} {loop.gravity_load:>9.4g} "
              f"{loop.effort_limit:>8.4g} {loop.gains['p']:>10.4g} {loop.gains['d']:>9.4g} {loop.bandwidth_hz:>6.3g}")
        if loop.note:
            print(f"  {loop.joint}: {loop.note}")
    for path in files.values():
        print(f"wrote {path}", file=sys.stderr)
    for component in robot.ros2_control:
        print(f"{description}: {component.stand_in()}", file=sys.stderr)
    print(f"next: jointctl run {files['scenario']}", file=sys.stderr)
    return 0

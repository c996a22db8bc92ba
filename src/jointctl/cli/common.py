"""What several command families share: a robot or scenario run on the wall clock, and how to reach a
robot controller over simple_message."""

from __future__ import annotations

import argparse
import sys

from jointctl.errors import JointCtlError
from jointctl.hardware.industrial import POINT_MESSAGES, STREAM_POINTS
from jointctl.hardware.ros_industrial_points import DEFAULT_SPEED_FRACTION


def positive_speed(args: argparse.Namespace) -> None:
    """``--speed`` is loop time per wall-clock time: refuse zero, negatives and NaN."""
    if not args.speed > 0:
        raise JointCtlError("must be positive", field="--speed", value=args.speed)


def say_warnings(metrics: dict) -> None:
    """Print an analysis's ``warnings`` (figures off their theory or spec, saturated efforts) on stderr."""
    for warning in metrics.get("warnings", []):
        print(f"jointctl: warning: {warning}", file=sys.stderr)


def ros_edge(module: str):
    """``jointctl.ros.<module>``, or one line saying ROS 1 is missing. In a shell where a ROS 2 is sourced too,
    its Python packages (which carry ROS 1's names: std_msgs, rosgraph_msgs...) are set aside first
    (:func:`jointctl.python_path.set_aside_ros2`), so ROS 1's import."""
    import importlib

    from jointctl.python_path import set_aside_ros2

    set_aside_ros2()
    try:
        return importlib.import_module(f"jointctl.ros.{module}")
    except ImportError as exc:
        raise JointCtlError(f"ROS 1 is not available ({exc}); install it with 'make ros'") from None


#: How a user makes ROS 2 reachable: rclpy and ROS 2's messages come from the ROS 2 the shell sourced.
ROS2_SETUP_HINT = "source your ROS 2 first, e.g. source /opt/ros/jazzy/setup.bash (make ros2 installs one)"


def ros2_edge(module: str):
    """``jointctl.ros2.<module>``, or one line saying how to reach ROS 2 (its setup.bash sourced in this shell)."""
    import importlib

    try:
        return importlib.import_module(f"jointctl.ros2.{module}")
    except ImportError as exc:  # rclpy missing, or its libraries (a setup.bash not sourced): the first line says
        import glob

        reason = (str(exc).splitlines() or [type(exc).__name__])[0]
        found = sorted(glob.glob("/opt/ros/*/lib/python3*/site-packages/rclpy"))
        how = f"source {found[0].split('/lib/')[0]}/setup.bash first" if found else ROS2_SETUP_HINT
        raise JointCtlError(f"ROS 2 is not available ({reason}): {how}") from None


def loop_hardware_arguments(parser: argparse.ArgumentParser) -> None:
    """Where identify, bode and autotune find the joint's loop."""
    parser.add_argument("--hardware", choices=("sim", "ros", "ros2", "industrial"), default="sim",
                        help="sim: the robot in MuJoCo, in simulated time (default); ros: the robot a node serves "
                             "on the ROS graph (jointctl serve), through its topics and dynamic_reconfigure, in "
                             "real time; ros2: a ros2_control robot on the ROS 2 graph, through its pid_controller "
                             "or forward command controller, /joint_states and the controller's parameters, in "
                             "real time (source ROS 2 first); industrial: an industrial controller over "
                             "simple_message (bode only: its own servo loop, streamed positions)")
    parser.add_argument("--namespace", help="with --hardware ros: the served robot's namespace (default: the "
                                            "robot's controller file's, e.g. one_DOF_robot); with --hardware ros2: "
                                            "its controller_manager's namespace (default: none, /controller_manager)")
    industrial_arguments(parser)


def safety_arguments(parser: argparse.ArgumentParser) -> None:
    """The excited joint's limits the user sets, and the dry run, of identify, bode and autotune
    (see docs/real-robots.md)."""
    parser.add_argument("--max-effort", type=float, metavar="N",
                        help="the excited joint's largest effort [N or N·m]: the excitation is planned well inside "
                             "it, and the run stops (the joint brought back) if the measured effort crosses it")
    parser.add_argument("--max-velocity", type=float, metavar="V",
                        help="the excited joint's largest speed [m/s or rad/s], planned within and watched alike")
    parser.add_argument("--workspace", metavar="LOWER:UPPER",
                        help="the excited joint's positions [m or rad] the run must stay in, planned within and "
                             "watched alike (write --workspace=-0.6:-0.4 when LOWER is negative)")
    parser.add_argument("--dry-run", action="store_true",
                        help="print the planned excitation (amplitudes, predicted peaks against each limit, the "
                             "binding limit) and exit without moving anything")


def safety_from_args(args: argparse.Namespace):
    """The :class:`~jointctl.identification.safety.Safety` of :func:`safety_arguments`' flags;
    JointCtlError naming the flag when one is malformed."""
    from jointctl.identification.safety import Safety, UserLimits, parse_workspace

    workspace = parse_workspace(args.workspace) if args.workspace is not None else None
    return Safety(limits=UserLimits(max_effort=args.max_effort, max_velocity=args.max_velocity, workspace=workspace))


def industrial_arguments(parser: argparse.ArgumentParser) -> None:
    """How to reach an industrial controller (serve and bode with --hardware industrial)."""
    parser.add_argument("--robot-ip",
                        help="with --hardware industrial: the robot controller's host name or IPv4 address")
    parser.add_argument("--motion-port", type=int, default=11000, help="the controller's motion port (default 11000)")
    parser.add_argument("--state-port", type=int, default=11002, help="the controller's state port (default 11002)")
    parser.add_argument("--big-endian", action="store_true",
                        help="the controller speaks big-endian (the _bswap drivers)")
    parser.add_argument("--stream-rate-hz", type=float, default=50.0,
                        help="with --points resampled, and outside goals: points streamed to the controller per "
                             "second (default 50)")
    parser.add_argument("--motion", choices=("streaming", "download"), default="streaming",
                        help="the controller's motion handshake: each point a request answered when the "
                             "controller has room (default), or each goal downloaded whole and executed after "
                             "its last point")
    parser.add_argument("--stream-points", choices=STREAM_POINTS, default=None,
                        help="what a goal becomes on the wire: its own points with ROS-I's speed fractions and "
                             "durations ('goal', the default), or the goal resampled every stream period "
                             "('resampled', as the chapter's streamer; for controllers that want a dense stream). "
                             "Default: the robot's robot.yaml industrial.points, else goal")
    parser.add_argument("--message", choices=POINT_MESSAGES, default=None,
                        help="the point message: JOINT_TRAJ_PT ('pt', speed fraction and duration, as ROS-I's "
                             "client) or JOINT_TRAJ_PT_FULL ('full', time, positions, velocities, accelerations). "
                             "Default: robot.yaml industrial.message, else pt")
    parser.add_argument("--default-speed", type=float, default=None,
                        help="the speed fraction of a point without velocities (ROS-I's default_vel_ratio; "
                             "default: robot.yaml industrial.default_speed, else 0.1)")


#: What a command's robot argument may be (see :mod:`jointctl.scenario.targets`).
TARGET_HELP = ("a robot (a built-in name, a folder with a robot.yaml, a robot.yaml, a .urdf or .xacro with "
               "--controllers) or a scenario (a YAML or a built-in name)")
CONTROLLERS_HELP = ("with a robot: its controller file to load and start, every controller of it (a robot.yaml "
                    "key, or a ros_control YAML; default position)")

#: What ``--set KEY=VALUE`` accepts, said in every command's help.
SET_VALUES = ("VALUE is YAML, numbers as written (800, 1_000, .5, 1e3, 1E-3, -2.5e+2), true/false, "
              "[lists]; repeatable")


def foxglove_argument(parser: argparse.ArgumentParser) -> None:
    """``--foxglove [PORT]``: stream the robot live to Foxglove (serve and tune)."""
    from jointctl.recording.foxglove_live import DEFAULT_PORT

    parser.add_argument("--foxglove", nargs="?", const=str(DEFAULT_PORT), default=None, metavar="PORT",
                        help="also stream the robot over Foxglove's WebSocket protocol (joint states, references, "
                             f"wrenches, TF, URDF, objects, events) on PORT (default {DEFAULT_PORT}; 0: any free "
                             "port); open ws://127.0.0.1:PORT in Foxglove with jointctl's layout")


def start_foxglove(args: argparse.Namespace, session, host: str = "127.0.0.1"):
    """The live Foxglove server of ``--foxglove`` on ``session`` (None without it), said in one line."""
    if args.foxglove is None:
        return None
    from jointctl.recording.foxglove_layout import LAYOUT_FILE
    from jointctl.recording.foxglove_live import check_port, live_for_session

    live = live_for_session(session, port=check_port(args.foxglove), host=host)
    print(f"jointctl: Foxglove: ws://{host}:{live.port} (Open connection -> Foxglove WebSocket; layout "
          f"{LAYOUT_FILE})", file=sys.stderr, flush=True)
    return live


def live_target_arguments(parser: argparse.ArgumentParser) -> None:
    """What serve and tune share: a robot and its controller file, or a scenario, run on the wall clock."""
    parser.add_argument("target", help=TARGET_HELP)
    parser.add_argument("--controllers", default=None, help=CONTROLLERS_HELP)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help=f"override a scenario field; {SET_VALUES}")
    parser.add_argument("--speed", type=float, default=1.0, help="loop time per wall-clock time (default 1.0)")


def target_scenario(args: argparse.Namespace, *, default_controllers: str = "position", robot_defaults=(),
                    robot_overrides=(), extra_overrides=(), say: bool = True):
    """The scenario of a command's ``target`` (a robot or a scenario, see
    :mod:`jointctl.scenario.targets`), after saying on stderr what the target was taken for (unless
    ``say`` is false). ``extra_overrides`` follow the user's ``--set`` (a command's own, e.g. gains
    under test)."""
    from jointctl.scenario.targets import resolve_target

    if args.target is None:
        raise JointCtlError("is required: a robot or a scenario (only --hardware ros reads the served model)",
                            field="target")
    target = resolve_target(args.target, controllers=getattr(args, "controllers", None),
                            default_controllers=default_controllers, overrides=[*args.overrides, *extra_overrides],
                            robot_defaults=robot_defaults, robot_overrides=robot_overrides)
    if say:
        print(f"jointctl: {target.taken_as}", file=sys.stderr)
    return target.scenario


def live_scenario(args: argparse.Namespace):
    """The scenario of ``serve``/``tune``/``controller``: a robot with a controller file, or a scenario."""
    positive_speed(args)
    default = ("servo" if args.command == "controller"
               else "industrial" if getattr(args, "hardware", "sim") == "industrial" else "position")
    return target_scenario(args, default_controllers=default)


def industrial_hardware(args: argparse.Namespace, scenario):
    """The robot controller behind ``serve --hardware industrial``, connected (or a clear error). What
    the command line leaves open comes from the robot's ``robot.yaml`` (``industrial: {points, message,
    default_speed}``), else from ROS-I's client's defaults."""
    from jointctl.hardware.industrial import IndustrialHardware
    from jointctl.model.loader import load_robot_model

    if not args.robot_ip:
        raise JointCtlError("is required with --hardware industrial", field="--robot-ip")
    robot = load_robot_model(scenario.robot.description)
    joints = robot.movable_joints
    defaults = scenario.robot.extras.get("industrial") or {}
    if not isinstance(defaults, dict) or set(defaults) - {"points", "message", "default_speed"}:
        raise JointCtlError("must be a mapping of points, message and default_speed",
                            source=str(scenario.robot.folder / "robot.yaml"), field="industrial", value=defaults)

    def pick(flag: str, key: str, fallback):
        given = getattr(args, flag)
        return given if given is not None else defaults.get(key, fallback)

    hardware = IndustrialHardware([j.name for j in joints], robot_ip=args.robot_ip,
                                  motion_port=args.motion_port, state_port=args.state_port,
                                  big_endian=args.big_endian, stream_rate_hz=args.stream_rate_hz,
                                  motion=args.motion, points=pick("stream_points", "points", "goal"),
                                  message=pick("message", "message", "pt"),
                                  default_speed=pick("default_speed", "default_speed", DEFAULT_SPEED_FRACTION),
                                  max_velocities=[j.range_and_speed()[2] for j in joints])
    hardware.connect()
    return hardware

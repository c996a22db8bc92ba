"""The ``jointctl`` command.

    jointctl list                                   built-in robots and scenarios
    jointctl run SCENARIO [--out DIR] [--set K=V]   run one scenario: trace.csv, metrics.json, PNGs
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

Every error a user can cause is printed as one line naming the file, field
and value, with exit status 2.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

from jointctl import __version__
from jointctl.errors import JointCtlError

EXIT_USAGE = 2


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="jointctl", description="Joint-level robot control on MuJoCo.")
    parser.add_argument("--version", action="version", version=f"jointctl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    sub.add_parser("list", help="list built-in robots and scenarios")

    run = sub.add_parser("run", help="run a scenario and write trace.csv, metrics.json and figures")
    run.add_argument("scenario", help="a built-in scenario name or a scenario YAML file")
    run.add_argument("--out", type=Path, help="output folder (default: out/<scenario name>)")
    run.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help="override a scenario field, e.g. gravity=-5 or "
                          "controllers.joint1_position_controller.pid.p=800 (repeatable)")
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
    run.add_argument("--video-camera", metavar="X,Y,Z,DISTANCE,AZIMUTH,ELEVATION",
                     help="the camera: the point looked at [m], distance [m], azimuth and elevation [deg] "
                          "(default: the robot's, from robot.yaml)")

    serve = sub.add_parser("serve", help="run a robot or a scenario as a ROS 1 node (chapter topic names)")
    _live_target_arguments(serve)
    serve.add_argument("--sim-time", action="store_true", help="publish /clock with loop time, use_sim_time")
    serve.add_argument("--rviz", action="store_true",
                       help="also run robot_state_publisher and rviz (jointctl's config) when installed; what cannot "
                            "start is said in one line and the node serves on")
    serve.add_argument("--hardware", choices=("sim", "industrial"), default="sim",
                       help="sim: the robot in MuJoCo (default); industrial: a robot controller that interpolates "
                            "by itself, over simple_message (with --robot-ip; controllers default to 'industrial')")
    _industrial_arguments(serve)

    demo = sub.add_parser("demo", help="run every built-in experiment and write report.md")
    demo.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder")

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
    tune = sub.add_parser("tune", help="the tuning page: live plots, gains and command sources in the browser")
    _live_target_arguments(tune)
    tune.add_argument("--port", type=int, default=8765, help="TCP port of the page (default 8765; 0: any free port)")
    tune.add_argument("--host", default="127.0.0.1",
                      help="address to listen on (default 127.0.0.1; another needs --allow-remote)")
    tune.add_argument("--allow-remote", action="store_true",
                      help="allow --host other than loopback: anyone reaching it can move the robot")
    tune.add_argument("--out", type=Path, default=Path("out/tune"), help="where 'Write gains YAML' writes")
    tune.add_argument("--view", action="store_true", help="also show the robot in MuJoCo's viewer (a desktop window)")
    controller = sub.add_parser("controller", help="a simulated industrial robot controller: the robot in MuJoCo with "
                                                   "its own interpolator, speaking simple_message")
    _live_target_arguments(controller)  # controllers: the robot's servo file by default
    controller.add_argument("--host", default="0.0.0.0", help="address to listen on (default 0.0.0.0, as a "
                                                              "controller cabinet does)")
    controller.add_argument("--motion-port", type=int, default=11000, help="motion port (default 11000; 0: any free)")
    controller.add_argument("--state-port", type=int, default=11002, help="state port (default 11002; 0: any free)")
    controller.add_argument("--big-endian", action="store_true", help="speak big-endian (for the _bswap drivers)")
    controller.add_argument("--state-rate-hz", type=float, default=50.0,
                            help="joint state and status reports per second (default 50)")
    identify = sub.add_parser("identify", help="excite a joint (or read a recorded trace.csv or rosbag) and fit its "
                                               "inertia, damping, Coulomb friction and gravity load")
    identify.add_argument("target", help="a built-in robot, a scenario YAML / name, a trace.csv or a .bag")
    identify.add_argument("--joint", required=True, help="the joint to identify")
    _loop_hardware_arguments(identify)
    identify.add_argument("--topic", help="with a bag: its JointState topic (default: the one naming the joint)")
    identify.add_argument("--controllers", default="position",
                          help="with a robot: the controller file whose position controller excites the joint "
                               "(default position)")
    identify.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                          help="override a scenario field, e.g. initial_positions.joint1=-0.3 (repeatable)")
    identify.add_argument("--joint-type", choices=("prismatic", "revolute", "continuous"),
                          help="with a trace or bag: the joint's type (default: read from --robot)")
    identify.add_argument("--robot", help="with a trace or bag: the built-in robot it was recorded on")
    identify.add_argument("--amplitude", type=float, help="excitation amplitude [m or rad] (default: the safe one)")
    identify.add_argument("--duration-s", type=float, default=10.0, help="excitation length [s] (default 10)")
    identify.add_argument("--f-start-hz", type=float, default=0.2, help="chirp start frequency (default 0.2 Hz)")
    identify.add_argument("--f-end-hz", type=float, default=3.0, help="chirp end frequency (default 3 Hz)")
    identify.add_argument("--no-friction", action="store_true", help="fit without a Coulomb friction term")
    identify.add_argument("--out", type=Path, default=Path("out/identify"), help="output folder")

    bode = sub.add_parser("bode", help="a joint loop's closed-loop frequency response by stepped sines, beside "
                                       "its model; bandwidth, resonance, margins")
    bode.add_argument("target", help="a built-in robot or a scenario YAML / name")
    bode.add_argument("--controller", help="the joint position or velocity controller to sweep (sim and ros)")
    bode.add_argument("--joint", help="with --hardware industrial: the joint whose controller's loop to sweep")
    _loop_hardware_arguments(bode)
    bode.add_argument("--controllers", default=None,
                      help="with a robot: the controller file to load (default: position, or velocity for a "
                           "velocity controller's name)")
    bode.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                      help="override a scenario field (repeatable)")
    bode.add_argument("--f-min-hz", type=float, default=0.5, help="lowest frequency (default 0.5 Hz)")
    bode.add_argument("--f-max-hz", type=float, default=20.0, help="highest frequency (default 20 Hz)")
    bode.add_argument("--points", type=int, default=20, help="frequencies, log-spaced (default 20)")
    bode.add_argument("--amplitude", type=float, help="sine amplitude [m, rad, or per s] (default: the safe one)")
    bode.add_argument("--plant", type=Path, help="an identification's metrics.json for the model's plant "
                                                 "(default: the robot model's)")
    bode.add_argument("--out", type=Path, default=Path("out/bode"), help="output folder")

    tune_gains = sub.add_parser("autotune", help="PD/P gains for a damping ratio and a bandwidth, checked on the "
                                                 "model and on the robot, written as the chapter's YAML")
    tune_gains.add_argument("target", help="a built-in robot or a scenario YAML / name")
    tune_gains.add_argument("--controller", required=True, help="the joint position or velocity controller to tune")
    _loop_hardware_arguments(tune_gains)
    tune_gains.add_argument("--controllers", default=None, help="with a robot: the controller file (default: "
                                                                "position, or velocity for a velocity controller)")
    tune_gains.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                            help="override a scenario field (repeatable)")
    tune_gains.add_argument("--bandwidth-hz", type=float, help="closed-loop -3 dB bandwidth [Hz]")
    tune_gains.add_argument("--zeta", type=float, help="damping ratio of a position loop (default 0.7)")
    tune_gains.add_argument("--overshoot-pct", type=float,
                            help="or: a position loop's step overshoot [%%], with --settling-s")
    tune_gains.add_argument("--settling-s", type=float, help="and the time its step takes to stay within 2 %% [s]")
    tune_gains.add_argument("--step", type=float, default=0.1,
                            help="the largest step [m, rad, or per s] that must not saturate the effort (default 0.1)")
    tune_gains.add_argument("--plant", type=Path, help="an identification's metrics.json (default: the robot model)")
    tune_gains.add_argument("--out", type=Path, default=Path("out/autotune"), help="output folder")
    return parser


def _loop_hardware_arguments(parser: argparse.ArgumentParser) -> None:
    """Where identify, bode and autotune find the joint's loop."""
    parser.add_argument("--hardware", choices=("sim", "ros", "industrial"), default="sim",
                        help="sim: the robot in MuJoCo, in simulated time (default); ros: the robot a node serves "
                             "on the ROS graph (jointctl serve), through its topics and dynamic_reconfigure, in "
                             "real time; industrial: an industrial controller over simple_message (bode only: "
                             "its own servo loop, streamed positions)")
    parser.add_argument("--namespace", help="with --hardware ros: the served robot's namespace (default: the "
                                            "robot's controller file's, e.g. one_DOF_robot)")
    _industrial_arguments(parser)


def _industrial_arguments(parser: argparse.ArgumentParser) -> None:
    """How to reach an industrial controller (serve and bode with --hardware industrial)."""
    parser.add_argument("--robot-ip", help="with --hardware industrial: the robot controller's host name or IPv4 address")
    parser.add_argument("--motion-port", type=int, default=11000, help="the controller's motion port (default 11000)")
    parser.add_argument("--state-port", type=int, default=11002, help="the controller's state port (default 11002)")
    parser.add_argument("--big-endian", action="store_true", help="the controller speaks big-endian (the _bswap drivers)")
    parser.add_argument("--stream-rate-hz", type=float, default=50.0,
                        help="points streamed to the controller per second (default 50)")
    parser.add_argument("--motion", choices=("streaming", "download"), default="streaming",
                        help="the controller's motion handshake: points streamed as a goal runs (default), or "
                             "each goal downloaded whole and executed after its last point")


def _live_target_arguments(parser: argparse.ArgumentParser) -> None:
    """What serve and tune share: a robot and its controller file, or a scenario, run on the wall clock."""
    parser.add_argument("target", help="a built-in robot (with --controllers) or a scenario YAML / name")
    parser.add_argument("--controllers", default=None,
                        help="with a robot: which of its controller files to load and start (default position)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario field (repeatable)")
    parser.add_argument("--speed", type=float, default=1.0, help="loop time per wall-clock time (default 1.0)")


def _live_scenario(args: argparse.Namespace):
    """The scenario of ``serve``/``tune``: a built-in robot with a controller file, or a scenario."""
    from jointctl.scenario.spec import builtin_robots, load_scenario, scenario_for_robot

    if not args.speed > 0:
        raise JointCtlError("must be positive", field="--speed", value=args.speed)
    if args.target in builtin_robots():
        default = ("servo" if args.command == "controller"
                   else "industrial" if getattr(args, "hardware", "sim") == "industrial" else "position")
        return scenario_for_robot(args.target, args.controllers or default, args.overrides)
    return load_scenario(args.target, args.overrides)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return _COMMANDS[args.command](args)
    except JointCtlError as exc:
        print(f"jointctl: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("jointctl: interrupted", file=sys.stderr)
        return 130


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
    from jointctl.scenario.spec import load_scenario

    if not args.speed > 0:
        raise JointCtlError("must be positive", field="--speed", value=args.speed)
    scenario = load_scenario(args.scenario, args.overrides)
    out = args.out or Path("out") / scenario.name
    if args.view:
        from jointctl.tools.viewer import check_display

        check_display()  # before anything runs
    metrics = run_scenario(scenario, out, realtime=args.realtime or args.view, speed=args.speed,
                           package_path=tuple(args.package_path), video=_video_settings(args), view=args.view)
    shown = {k: v for k, v in metrics.items() if k not in ("plant",)}
    print(json.dumps(shown, indent=2))
    print(f"wrote {out}/", file=sys.stderr)
    return 0


def _video_settings(args: argparse.Namespace):
    """``run --video``'s settings, checked before anything runs; None without --video."""
    if not args.video:
        return None
    from jointctl.sim.rendering import CameraView
    from jointctl.tools.video import VideoSettings

    width, height = VideoSettings.parse_size(args.video_size)
    camera = None
    if args.video_camera is not None:
        parts = args.video_camera.split(",")
        try:
            numbers = [float(p) for p in parts]
        except ValueError:
            numbers = []
        if len(numbers) != 6:
            raise JointCtlError("must be six numbers X,Y,Z,DISTANCE,AZIMUTH,ELEVATION", field="--video-camera",
                                value=args.video_camera)
        camera = CameraView.from_config({"lookat": numbers[:3], "distance_m": numbers[3], "azimuth_deg": numbers[4],
                                         "elevation_deg": numbers[5]}, field="--video-camera")
    return VideoSettings(fps=args.video_fps, width=width, height=height, camera=camera)


def _serve(args: argparse.Namespace) -> int:
    from jointctl.scenario.session import Session

    scenario = _live_scenario(args)
    try:
        from jointctl.ros.node import check_actions, check_command_topics, serve
    except ImportError as exc:
        raise JointCtlError(f"ROS 1 is not available ({exc}); install it with 'make ros'") from None
    ros_section = scenario.robot.extras.get("ros") or {}
    source = str(scenario.robot.folder)
    hardware = _industrial_hardware(args, scenario) if args.hardware == "industrial" else None
    session = Session(scenario, hardware=hardware)
    started = {c.name for c in session.manager.active}
    actions = {name: spec for name, spec in check_actions(ros_section.get("actions"), source).items()
               if spec["controller"] in started}
    topics = {topic: name for topic, name in check_command_topics(ros_section.get("command_topics"), source).items()
              if name in started}
    try:
        serve(session, sim_time=args.sim_time, speed=args.speed, actions=actions, command_topics=topics,
              rviz=args.rviz)
    finally:
        if hardware is not None:
            hardware.close()
    return 0


def _controller(args: argparse.Namespace) -> int:
    import signal

    from jointctl.industrial.controller import SimulatedController

    scenario = _live_scenario(args)
    controller = SimulatedController(scenario, host=args.host, motion_port=args.motion_port,
                                     state_port=args.state_port, big_endian=args.big_endian,
                                     state_rate_hz=args.state_rate_hz, speed=args.speed)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: controller.stop())
    order = "big-endian" if args.big_endian else "little-endian"
    print(f"jointctl controller: {scenario.robot.name} (joints "
          f"{', '.join(controller.joint_names)}) on {args.host}, motion port {controller.motion_port}, "
          f"state port {controller.state_port}, {order}", flush=True)
    try:
        controller.run()
    finally:
        controller.close()
    return 0


def _identify(args: argparse.Namespace) -> int:
    from jointctl.identification.identify import identify_on_robot, identify_states, identify_trace
    from jointctl.scenario.spec import builtin_robots, load_scenario, scenario_for_robot

    friction = not args.no_friction
    if args.target.endswith((".csv", ".bag")):
        joint_type = args.joint_type or _joint_type(args.robot, args.joint)
        if args.target.endswith(".csv"):
            _, metrics = identify_trace(args.target, args.joint, joint_type, out_dir=args.out, fit_friction=friction)
        else:
            from jointctl.ros.bag_trace import read_joint

            topic, *states = read_joint(args.target, args.joint, args.topic)
            _, metrics = identify_states(*states, args.joint, joint_type, source=f"{args.target}:{topic}",
                                         out_dir=args.out, fit_friction=friction)
    elif args.hardware == "industrial":
        raise JointCtlError("an industrial controller reports no joint efforts (simple_message's JOINT_POSITION and "
                            "JOINT_FEEDBACK carry none) and servos the joint itself: there is no plant to fit; "
                            "measure its loop with jointctl bode --hardware industrial", field="--hardware",
                            value="industrial")
    elif args.hardware == "ros":
        from jointctl.identification.identify import identify_servoed

        with _served(args, joint=args.joint) as (session, _):
            _, metrics = identify_servoed(session, args.joint, out_dir=args.out, amplitude=args.amplitude,
                                          duration_s=args.duration_s, f_start_hz=args.f_start_hz,
                                          f_end_hz=args.f_end_hz, fit_friction=friction)
    else:
        scenario = (scenario_for_robot(args.target, args.controllers, args.overrides)
                    if args.target in builtin_robots() else load_scenario(args.target, args.overrides))
        _, metrics = identify_on_robot(scenario, args.joint, out_dir=args.out, amplitude=args.amplitude,
                                       duration_s=args.duration_s, f_start_hz=args.f_start_hz,
                                       f_end_hz=args.f_end_hz, fit_friction=friction)
    print(json.dumps(metrics, indent=2))
    print(f"wrote {args.out}/", file=sys.stderr)
    return 0


@contextlib.contextmanager
def _served(args: argparse.Namespace, *, controller: str | None = None, joint: str | None = None):
    """(session, controller name) on the robot a node serves on the ROS graph (``--hardware ros``):
    the built-in robot's model, its loop found on the graph, the session paced to the wall clock;
    the loop's reference put back where it was on the way out."""
    from jointctl.control.manager import read_yaml
    from jointctl.model.loader import load_robot_model
    from jointctl.ros.served_hardware import connect
    from jointctl.scenario.session import Session
    from jointctl.scenario.spec import builtin_robots, scenario_for_robot

    if args.target not in builtin_robots():
        raise JointCtlError("--hardware ros needs a built-in robot (its model)", field="target", value=args.target)
    scenario = scenario_for_robot(args.target, "position",
                                  [*args.overrides, "start_controllers=[joint_state_controller]"])
    namespace = args.namespace
    if namespace is None:
        tree = read_yaml(scenario.controller_file)
        namespace = next(iter(tree)) if isinstance(tree, dict) and len(tree) == 1 else None
        if namespace is None:
            raise JointCtlError("the robot's controller file has no single namespace: give it", field="--namespace")
    names = [j.name for j in load_robot_model(scenario.robot.description).movable_joints]
    hardware, name = connect(namespace, names, controller, joint=joint)
    try:
        yield Session(scenario, hardware=hardware, realtime=True), name
    finally:
        hardware.hold(hardware.set_points)
        hardware.write()
        hardware.close()


def _bode(args: argparse.Namespace) -> int:
    import numpy as np

    from jointctl.identification.frequency_response import bode

    if not (0 < args.f_min_hz < args.f_max_hz):
        raise JointCtlError(f"must be positive and below --f-max-hz ({args.f_max_hz:g})", field="--f-min-hz",
                            value=args.f_min_hz)
    if not 2 <= args.points <= 200:
        raise JointCtlError("must be 2 to 200", field="--points", value=args.points)
    frequencies = np.logspace(np.log10(args.f_min_hz), np.log10(args.f_max_hz), args.points)
    if args.hardware == "industrial":
        result = _bode_industrial(args, frequencies)
    elif args.hardware == "ros":
        result = _bode_served(args, frequencies)
    else:
        if not args.controller:
            raise JointCtlError("is required (the loop to sweep)", field="--controller")
        result = bode(_loop_scenario(args), args.controller, frequencies, plant=_plant_file(args.plant),
                      amplitude=args.amplitude, out_dir=args.out)
    shown = {k: v for k, v in result.items() if not isinstance(v, (list, dict))}
    if "model" in result:
        shown["model"] = {k: v for k, v in result["model"].items() if not isinstance(v, list)}
    print(json.dumps(shown, indent=2, default=float))
    print(f"wrote {args.out}/", file=sys.stderr)
    return 0


def _bode_industrial(args: argparse.Namespace, frequencies) -> dict:
    """``bode --hardware industrial``: the controller's own position loop, measured over the socket in
    real time (no model: its servos are the controller's)."""
    from jointctl.identification.frequency_response import analyse, measure_servoed, write_bode
    from jointctl.scenario.session import Session
    from jointctl.scenario.spec import builtin_robots, scenario_for_robot

    if not args.joint:
        raise JointCtlError("is required with --hardware industrial", field="--joint")
    if args.target not in builtin_robots():
        raise JointCtlError("--hardware industrial needs a built-in robot", field="target", value=args.target)
    scenario = scenario_for_robot(args.target, "industrial", [*args.overrides, "start_controllers=[joint_state_controller]"])
    hardware = _industrial_hardware(args, scenario)
    try:
        session = Session(scenario, hardware=hardware, realtime=True)
        points, context = measure_servoed(session, args.joint, frequencies, amplitude=args.amplitude)
    finally:
        hardware.close()
    result = analyse(points, None)
    result.update(controller=f"{args.robot_ip}:{args.motion_port} (industrial controller)", plant_source=None,
                  **context)
    write_bode(args.out, result, f"{args.joint} through the industrial controller at {args.robot_ip}")
    return result


def _bode_served(args: argparse.Namespace, frequencies) -> dict:
    """``bode --hardware ros``: the served node's loop through its command topic and joint states, in
    real time, beside the model with the gains its dynamic_reconfigure server holds."""
    from jointctl.identification.frequency_response import compare, measure_servoed

    if not args.controller:
        raise JointCtlError("is required (the loop to sweep)", field="--controller")
    plant = _plant_file(args.plant)  # read before the robot moves
    with _served(args, controller=args.controller) as (session, name):
        hardware = session.hardware
        joint = hardware.joint_of(name)
        points, context = measure_servoed(session, joint, frequencies, amplitude=args.amplitude)
        context["gains"] = hardware.gains(name)
        pose = dict(zip(hardware.joint_names, hardware.position))
        pose[joint] = context["rest"]
        return compare(points, context, f"/{hardware.namespace}/{name}", plant, session.robot, pose,
                       out_dir=args.out)


def _plant_file(path: Path | None) -> dict | None:
    if path is None:
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise JointCtlError(f"cannot read the plant ({exc})", field="--plant", value=str(path)) from None


def _loop_scenario(args: argparse.Namespace, overrides=()):
    """The scenario of ``bode``/``autotune``: a built-in robot with the controller file its loop needs."""
    from jointctl.scenario.spec import builtin_robots, load_scenario, scenario_for_robot

    if args.target in builtin_robots():
        controllers = args.controllers or ("velocity" if "velocity" in args.controller else "position")
        return scenario_for_robot(args.target, controllers, [*args.overrides, *overrides])
    return load_scenario(args.target, [*args.overrides, *overrides])


def _autotune_spec(args: argparse.Namespace) -> tuple[float, float, float | None]:
    """(ζ, bandwidth [Hz], settling time [s] or None) from either form of the spec."""
    from jointctl.identification.autotune import spec_from_step

    by_step = args.overshoot_pct is not None or args.settling_s is not None
    if by_step:
        for flag, given in (("--bandwidth-hz", args.bandwidth_hz), ("--zeta", args.zeta)):
            if given is not None:
                raise JointCtlError("give either --bandwidth-hz (and --zeta) or --overshoot-pct and --settling-s",
                                    field=flag, value=given)
        for flag, given in (("--overshoot-pct", args.overshoot_pct), ("--settling-s", args.settling_s)):
            if given is None:
                raise JointCtlError("is required with " + ("--settling-s" if flag == "--overshoot-pct" else
                                                           "--overshoot-pct"), field=flag)
        zeta, bandwidth_hz = spec_from_step(args.overshoot_pct, args.settling_s)
        return zeta, bandwidth_hz, args.settling_s
    if args.bandwidth_hz is None:
        raise JointCtlError("is required (or --overshoot-pct and --settling-s)", field="--bandwidth-hz")
    return (0.7 if args.zeta is None else args.zeta), args.bandwidth_hz, None


def _autotune(args: argparse.Namespace) -> int:
    from jointctl.identification.autotune import autotune

    if args.hardware == "industrial":
        raise JointCtlError("an industrial controller servos its joints with gains of its own, which simple_message "
                            "cannot read or set: there is nothing of jointctl's to tune", field="--hardware",
                            value="industrial")
    zeta, bandwidth_hz, settling_s = _autotune_spec(args)
    plant = _plant_file(args.plant)
    if args.hardware == "ros":
        from jointctl.identification.autotune import autotune_servoed

        with _served(args, controller=args.controller) as (session, name):
            result = autotune_servoed(session, name, bandwidth_hz=bandwidth_hz, zeta=zeta, step=args.step,
                                      plant=plant, out_dir=args.out, settling_s=settling_s)
    else:
        result = autotune(lambda overrides: _loop_scenario(args, overrides), args.controller,
                          bandwidth_hz=bandwidth_hz, zeta=zeta, step=args.step, plant=plant, out_dir=args.out,
                          settling_s=settling_s)
    print(json.dumps(result, indent=2, default=float))
    print(f"wrote {result['yaml']}", file=sys.stderr)
    return 0


def _joint_type(robot: str | None, joint: str) -> str:
    """The type of ``joint`` of built-in ``robot`` (for identifying from a trace)."""
    from jointctl.model.loader import load_robot_model
    from jointctl.scenario.spec import builtin_robots, read_robot_manifest

    if robot is None:
        raise JointCtlError("a trace needs --joint-type or --robot (to read the joint's type)", field="--joint-type")
    robots = builtin_robots()
    if robot not in robots:
        raise JointCtlError(f"no such built-in robot (built-in: {', '.join(robots)})", field="--robot", value=robot)
    model = load_robot_model(read_robot_manifest(robots[robot] / "robot.yaml").description)
    if not model.has_joint(joint):
        raise JointCtlError(f"no such joint on {robot}", field="--joint", value=joint)
    return model.joint(joint).type


def _industrial_hardware(args: argparse.Namespace, scenario):
    """The robot controller behind ``serve --hardware industrial``, connected (or a clear error)."""
    from jointctl.hardware.industrial import IndustrialHardware
    from jointctl.model.loader import load_robot_model

    if not args.robot_ip:
        raise JointCtlError("is required with --hardware industrial", field="--robot-ip")
    robot = load_robot_model(scenario.robot.description)
    hardware = IndustrialHardware([j.name for j in robot.movable_joints], robot_ip=args.robot_ip,
                                  motion_port=args.motion_port, state_port=args.state_port,
                                  big_endian=args.big_endian, stream_rate_hz=args.stream_rate_hz,
                                  motion=args.motion)
    hardware.connect()
    return hardware


def _demo(args: argparse.Namespace) -> int:
    from jointctl.scenario.run import run_demo

    report = run_demo(args.out)
    print(f"wrote {report}")
    return 0


def _prompt(args: argparse.Namespace) -> int:
    from jointctl.clients.arm import prompt_command

    if not args.speed > 0:
        raise JointCtlError("must be positive", field="--speed", value=args.speed)
    return prompt_command(realtime=args.realtime, speed=args.speed, out_dir=args.out, ros=args.ros)


def _play(args: argparse.Namespace) -> int:
    from jointctl.clients.arm import play_command

    if not args.speed > 0:
        raise JointCtlError("must be positive", field="--speed", value=args.speed)
    return play_command(args.pathfile, timing=args.timing, realtime=args.realtime, speed=args.speed,
                        out_dir=args.out, ros=args.ros)


def _ros_clients():
    try:
        from jointctl.ros import clients
    except ImportError as exc:
        raise JointCtlError(f"ROS 1 is not available ({exc}); install it with 'make ros'") from None
    return clients


def _sine(args: argparse.Namespace) -> int:
    return _ros_clients().sine_command(namespace=args.namespace, joint=args.joint)


def _traj_client(args: argparse.Namespace) -> int:
    return _ros_clients().traj_client_command(seed=args.seed, server=args.server)


LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")


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
    check_static_files()
    if args.view:
        from jointctl.tools.viewer import LiveViewer, check_display

        check_display()
    tuner = Tuner(_live_scenario(args), out_dir=args.out)
    viewer = None
    if args.view:
        if tuner.session.world is None:
            raise JointCtlError("the viewer shows the simulation; this robot has none", field="--view")
        viewer = LiveViewer(tuner.session.world, tuner.loop, stop_when_closed=False)
        tuner.loop.add_observer(viewer)
    try:
        serve_tuning(tuner, host=args.host, port=args.port, speed=args.speed)
    finally:
        if viewer is not None:
            viewer.close()  # its window's thread would keep the process alive
    return 0


_COMMANDS = {"serve": _serve, "list": _list, "run": _run, "demo": _demo, "prompt": _prompt, "play": _play,
             "sine": _sine, "traj-client": _traj_client, "tune": _tune, "controller": _controller,
             "identify": _identify, "bode": _bode, "autotune": _autotune}


if __name__ == "__main__":
    sys.exit(main())

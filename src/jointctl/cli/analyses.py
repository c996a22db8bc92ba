"""``jointctl identify``, ``bode`` and ``autotune``: a joint's plant, its loop's frequency response and gains
for a spec, on the simulated robot, a served one (--hardware ros), a ros2_control robot (--hardware ros2) or
an industrial controller."""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

from jointctl.cli.common import (CONTROLLERS_HELP, SET_VALUES, industrial_hardware, loop_hardware_arguments,
                                 safety_arguments, safety_from_args, say_warnings, target_scenario)
from jointctl.errors import JointCtlError
from jointctl.identification.step_design import REMEDY_NAMES
from jointctl.recording.metrics_file import metrics_json


#: The target of identify, bode and autotune.
ROBOT_TARGET_HELP = ("a robot (a built-in name, a folder with a robot.yaml, a robot.yaml, a .urdf or .xacro with "
                     "--controllers) or a scenario; with --hardware ros or ros2 it may be left out: the model is "
                     "read from the served /robot_description")


def add_parsers(sub) -> None:
    identify = sub.add_parser("identify", help="excite a joint (or read a recorded trace.csv or rosbag) and fit its "
                                               "inertia, damping, Coulomb friction and gravity load")
    identify.add_argument("target", nargs="?", help=f"{ROBOT_TARGET_HELP}, a trace.csv or a .bag")
    identify.add_argument("--joint", required=True, help="the joint to identify")
    loop_hardware_arguments(identify)
    identify.add_argument("--topic", help="with a bag: its JointState topic (default: the one naming the joint)")
    identify.add_argument("--controllers", default=None,
                          help=f"{CONTROLLERS_HELP}; its position controller excites the joint")
    identify.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                          help=f"override a scenario field, e.g. initial_positions.joint1=-0.3; {SET_VALUES}")
    identify.add_argument("--joint-type", choices=("prismatic", "revolute", "continuous"),
                          help="with a trace or bag: the joint's type (default: read from --robot)")
    identify.add_argument("--robot", help="with a trace or bag: the robot it was recorded on (a built-in name, a "
                                          "robot folder, robot.yaml, .urdf or .xacro)")
    identify.add_argument("--amplitude", type=float, help="excitation amplitude [m or rad] (default: the safe one)")
    identify.add_argument("--duration-s", type=float, default=10.0, help="excitation length [s] (default 10)")
    identify.add_argument("--f-start-hz", type=float, default=0.2, help="chirp start frequency (default 0.2 Hz)")
    identify.add_argument("--f-end-hz", type=float, default=3.0, help="chirp end frequency (default 3 Hz)")
    identify.add_argument("--no-friction", action="store_true", help="fit without a Coulomb friction term")
    identify.add_argument("--plant", type=Path, help="an earlier identification's metrics.json to plan the excitation "
                                                     "on (default: the robot model)")
    safety_arguments(identify)
    identify.add_argument("--out", type=Path, default=Path("out/identify"), help="output folder")

    bode = sub.add_parser("bode", help="a joint loop's closed-loop frequency response by stepped sines, beside "
                                       "its model; bandwidth, resonance, margins")
    bode.add_argument("target", nargs="?", help=ROBOT_TARGET_HELP)
    bode.add_argument("--controller", help="the joint position or velocity controller to sweep (sim and ros)")
    bode.add_argument("--joint", help="with --hardware industrial: the joint whose controller's loop to sweep; "
                                      "with ros2: which joint of a controller that servos several")
    loop_hardware_arguments(bode)
    bode.add_argument("--controllers", default=None,
                      help=f"{CONTROLLERS_HELP}, or velocity for a velocity controller's name")
    bode.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                      help=f"override a scenario field; {SET_VALUES}")
    bode.add_argument("--f-min-hz", type=float, default=0.5, help="lowest frequency (default 0.5 Hz)")
    bode.add_argument("--f-max-hz", type=float, default=20.0, help="highest frequency (default 20 Hz)")
    bode.add_argument("--points", type=int, default=20, help="frequencies, log-spaced (default 20)")
    bode.add_argument("--amplitude", type=float, help="sine amplitude [m, rad, or per s] (default: the safe one)")
    bode.add_argument("--plant", type=Path, help="an identification's metrics.json for the model's plant "
                                                 "(default: the robot model's)")
    safety_arguments(bode)
    bode.add_argument("--out", type=Path, default=Path("out/bode"), help="output folder")

    tune_gains = sub.add_parser("autotune", help="PD/P gains for a damping ratio and a bandwidth, checked on the "
                                                 "model and on the robot, written as the chapter's YAML")
    tune_gains.add_argument("target", nargs="?", help=ROBOT_TARGET_HELP)
    tune_gains.add_argument("--controller", required=True, help="the joint position or velocity controller to tune")
    tune_gains.add_argument("--joint", help="with --hardware ros2: which joint of a controller that servos several")
    loop_hardware_arguments(tune_gains)
    tune_gains.add_argument("--controllers", default=None,
                            help=f"{CONTROLLERS_HELP}, or velocity for a velocity controller's name")
    tune_gains.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                            help=f"override a scenario field; {SET_VALUES}")
    tune_gains.add_argument("--bandwidth-hz", type=float, help="closed-loop -3 dB bandwidth [Hz]")
    tune_gains.add_argument("--zeta", type=float, help="damping ratio of a position loop (default 0.7)")
    tune_gains.add_argument("--overshoot-pct", type=float,
                            help="or: a position loop's step overshoot [%%], with --settling-s")
    tune_gains.add_argument("--settling-s", type=float, help="and the time its step takes to stay within 2 %% [s]")
    tune_gains.add_argument("--step", type=float,
                            help="the move the gains are designed for and checked at [m, rad, or per s], from the "
                                 "reference the loop holds (default: the scenario's step of the controller, else 0.1)")
    tune_gains.add_argument("--ramp-s", type=float, help="the step along a ramp of this many seconds (default: the "
                                                         "scenario's ramp_s, else 0: a step)")
    tune_gains.add_argument("--remedy", action="append", default=[], choices=REMEDY_NAMES,
                            help="when the spec cannot be met at the step: measurement (derivative on the measured "
                                 "speed: no kick), ramp (the step ramped so its kick fits), integral (i with i_clamp "
                                 "and anti-windup: a loaded joint ends at its reference), feedforward (gravity from "
                                 "the model), lower-bandwidth (the fastest settling the effort allows); repeatable")
    tune_gains.add_argument("--plant", type=Path, help="an identification's metrics.json (default: the robot model)")
    tune_gains.add_argument("--robust", action="append", default=[], metavar="FIELD=LOW:HIGH",
                            help="design against a family of plants: payload_kg or model.<link|joint>.<field> "
                                 "between LOW and HIGH (repeatable); the gains meet the spec at the step on every "
                                 "corner, the centre and --robust-samples draws, each run on the simulated robot "
                                 "(with --remedy as without)")
    tune_gains.add_argument("--robust-samples", type=int, default=8, help="uniform draws inside the ranges (default 8)")
    tune_gains.add_argument("--seed", type=int, default=0, help="the draws' seed (default 0)")
    tune_gains.add_argument("--scheduler", help="with --robust: the Dask scheduler running the check's sweep "
                                                "(default: in this process)")
    tune_gains.add_argument("--workers", type=int, help="with --robust: a local cluster of this many workers")
    safety_arguments(tune_gains)
    tune_gains.add_argument("--out", type=Path, default=Path("out/autotune"), help="output folder")
    identify.set_defaults(handler=_identify)
    bode.set_defaults(handler=_bode)
    tune_gains.set_defaults(handler=_autotune)


def _identify(args: argparse.Namespace) -> int:
    from jointctl.identification.identify import identify_on_robot, identify_states, identify_trace

    friction = not args.no_friction
    safety = safety_from_args(args)
    if args.target is not None and args.target.endswith((".csv", ".bag")):
        if args.dry_run:
            raise JointCtlError("plans an excitation; a recorded trace or bag has none", field="--dry-run")
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
    elif args.hardware in ("ros", "ros2") and not args.dry_run:
        from jointctl.identification.identify import identify_servoed

        plant = _plant_file(args.plant)
        with _served(args, joint=args.joint, tool="identify") as (session, _):
            if args.hardware == "ros2":
                from jointctl.cli.served_ros2 import loop_plant

                plant = loop_plant(session.hardware, session.robot, plant)
            _, metrics = identify_servoed(session, args.joint, out_dir=args.out, amplitude=args.amplitude,
                                          duration_s=args.duration_s, f_start_hz=args.f_start_hz,
                                          f_end_hz=args.f_end_hz, fit_friction=friction, safety=safety, plant=plant)
    else:
        if args.dry_run and args.target is None:
            raise JointCtlError("reads the model from the target: give the robot or scenario (the served "
                                "/robot_description is read only when the robot moves)", field="--dry-run")
        scenario = target_scenario(args)
        if args.dry_run:
            from jointctl.identification.plan import plan_identify

            return _print_plan(plan_identify(scenario, args.joint, amplitude=args.amplitude, duration_s=args.duration_s,
                                             f_start_hz=args.f_start_hz, f_end_hz=args.f_end_hz, safety=safety,
                                             plant=_plant_file(args.plant)))
        _, metrics = identify_on_robot(scenario, args.joint, out_dir=args.out, amplitude=args.amplitude,
                                       duration_s=args.duration_s, f_start_hz=args.f_start_hz,
                                       f_end_hz=args.f_end_hz, fit_friction=friction, safety=safety,
                                       plant=_plant_file(args.plant))
    print(metrics_json(metrics))
    say_warnings(metrics)
    print(f"wrote {args.out}/", file=sys.stderr)
    return 0


@contextlib.contextmanager
def _served(args: argparse.Namespace, *, controller: str | None = None, joint: str | None = None,
            tool: str | None = None):
    """(session, controller name) on the robot a node serves on the ROS graph (``--hardware ros``):
    the model from the target (any robot, or a scenario's) or, without one, from the served
    ``/robot_description``; the loop found on the graph under ``--namespace`` (default: the
    controller file's namespace, else the one namespace holding the joints' loops); the session
    paced to the wall clock; the loop's reference put back where it was on the way out. With
    ``--hardware ros2``: :func:`jointctl.cli.served_ros2.served_ros2`."""
    if args.hardware == "ros2":
        from jointctl.cli.served_ros2 import served_ros2

        with served_ros2(args, controller=controller, joint=joint, tool=tool) as found:
            yield found
        return
    import dataclasses
    import tempfile

    from jointctl.control.manager import read_yaml
    from jointctl.model.loader import load_robot_model
    from jointctl.ros.served_hardware import connect, served_description, served_namespaces
    from jointctl.scenario.session import Session
    from jointctl.scenario.spec import RobotFiles, load_scenario, scenario_for_robot
    from jointctl.scenario.targets import robot_files

    with tempfile.TemporaryDirectory(prefix="jointctl-served-") as folder:
        folder = Path(folder)
        scenario = controller_file = None
        if args.target is None:
            text, param = served_description(args.namespace)
            description = folder / "robot_description.urdf"
            description.write_text(text)
            files, taken = RobotFiles("robot_description", description, {}, folder), f"the model on {param}"
        elif (found := robot_files(args.target)) is not None:
            files, taken = found
            key = args.controllers or "position"
            controller_file = files.controller_files.get(key) or (Path(key) if Path(key).is_file() else None)
            taken = f"{args.target} as {taken}"
        else:
            scenario = load_scenario(args.target, args.overrides)
            files, controller_file, taken = scenario.robot, scenario.controller_file, f"{args.target} as a scenario"
        names = [j.name for j in load_robot_model(files.description).movable_joints]
        namespace = args.namespace or _namespace_of(controller_file and read_yaml(controller_file))
        if namespace is None:
            candidates = served_namespaces(names)
            if len(candidates) != 1:
                raise JointCtlError(f"give the served robot's namespace (namespaces with loops of its joints: "
                                    f"{', '.join(candidates) or 'none'})", field="--namespace")
            namespace = candidates[0]
        states = folder / "joint_state_controller.yaml"
        states.write_text(f"{namespace}:\n  joint_state_controller:\n"
                          "    type: joint_state_controller/JointStateController\n    publish_rate: 50\n")
        if scenario is None:
            scenario = scenario_for_robot(files, str(states), [*args.overrides,
                                                               "start_controllers=[joint_state_controller]"])
        else:
            scenario = dataclasses.replace(scenario, controller_file=states, controller_overrides={}, commands={},
                                           start_controllers=("joint_state_controller",), objects=(), goals=())
        print(f"jointctl: took {taken}; its loops on /{namespace}", file=sys.stderr)
        hardware, name = connect(namespace, names, controller, joint=joint)
        try:
            yield Session(scenario, hardware=hardware, realtime=True), name
        finally:
            hardware.hold(hardware.set_points)
            hardware.write()
            hardware.close()


def _namespace_of(tree) -> str | None:
    """The namespace of a ros_control controller file's tree: its one top-level key holding
    controllers (mappings without a ``type`` of their own), else None."""
    if isinstance(tree, dict) and len(tree) == 1:
        (key, body), = tree.items()
        if isinstance(body, dict) and "type" not in body:
            return str(key)
    return None


def _bode(args: argparse.Namespace) -> int:
    import numpy as np

    from jointctl.identification.frequency_response import bode

    if not (0 < args.f_min_hz < args.f_max_hz):
        raise JointCtlError(f"must be positive and below --f-max-hz ({args.f_max_hz:g})", field="--f-min-hz",
                            value=args.f_min_hz)
    if not 2 <= args.points <= 200:
        raise JointCtlError("must be 2 to 200", field="--points", value=args.points)
    frequencies = np.logspace(np.log10(args.f_min_hz), np.log10(args.f_max_hz), args.points)
    safety = safety_from_args(args)
    if args.dry_run:
        return _print_plan(_bode_plan(args, frequencies, safety))
    if args.hardware == "industrial":
        result = _bode_industrial(args, frequencies, safety)
    elif args.hardware in ("ros", "ros2"):
        result = _bode_served(args, frequencies, safety)
    else:
        if not args.controller:
            raise JointCtlError("is required (the loop to sweep)", field="--controller")
        result = bode(_loop_scenario(args), args.controller, frequencies, plant=_plant_file(args.plant),
                      amplitude=args.amplitude, out_dir=args.out, safety=safety)
    shown = {k: v for k, v in result.items() if not isinstance(v, (list, dict))}
    if "model" in result:
        shown["model"] = {k: v for k, v in result["model"].items() if not isinstance(v, list)}
    print(metrics_json(shown))
    saturated = result.get("saturated_hz") or []
    if saturated:
        print(f"jointctl: warning: the actuator saturated at {', '.join(f'{f:.3g}' for f in saturated)} Hz: those "
              "points are marked and left out of the bandwidth and resonance", file=sys.stderr)
    print(f"wrote {args.out}/", file=sys.stderr)
    return 0


def _bode_plan(args: argparse.Namespace, frequencies, safety) -> dict:
    """``bode --dry-run``'s plan: the loop's scenario (a servo loop's joint with --hardware industrial)."""
    from jointctl.identification.plan import plan_bode

    plant = _plant_file(args.plant)
    if args.target is None:
        raise JointCtlError("reads the model from the target: give the robot or scenario (the served "
                            "/robot_description is read only when the robot moves)", field="--dry-run")
    if args.hardware == "industrial":
        if not args.joint:
            raise JointCtlError("is required with --hardware industrial", field="--joint")
        scenario = target_scenario(args, default_controllers="industrial")
        return plan_bode(scenario, None, frequencies, joint=args.joint, amplitude=args.amplitude, safety=safety)
    if not args.controller:
        raise JointCtlError("is required (the loop to sweep)", field="--controller")
    return plan_bode(_loop_scenario(args), args.controller, frequencies, amplitude=args.amplitude, plant=plant,
                     safety=safety)


def _print_plan(plan: dict) -> int:
    """Print a dry run's plan; nothing moved."""
    from jointctl.identification.plan import format_plan

    print(format_plan(plan))
    return 0


def _bode_industrial(args: argparse.Namespace, frequencies, safety=None) -> dict:
    """``bode --hardware industrial``: the controller's own position loop, measured over the socket in
    real time (no model: its servos are the controller's)."""
    from jointctl.identification.frequency_response import analyse, measure_servoed, write_bode
    from jointctl.scenario.session import Session

    if not args.joint:
        raise JointCtlError("is required with --hardware industrial", field="--joint")
    scenario = target_scenario(args, default_controllers="industrial",
                               robot_overrides=["start_controllers=[joint_state_controller]"])
    hardware = industrial_hardware(args, scenario)
    try:
        session = Session(scenario, hardware=hardware, realtime=True)
        points, context = measure_servoed(session, args.joint, frequencies, amplitude=args.amplitude, safety=safety)
    finally:
        hardware.close()
    result = analyse(points, None)
    result.update(controller=f"{args.robot_ip}:{args.motion_port} (industrial controller)", plant_source=None,
                  **context)
    write_bode(args.out, result, f"{args.joint} through the industrial controller at {args.robot_ip}")
    return result


def _bode_served(args: argparse.Namespace, frequencies, safety=None) -> dict:
    """``bode --hardware ros``: the served node's loop through its command topic and joint states, in
    real time, beside the model with the gains its dynamic_reconfigure server holds. ``--hardware ros2``:
    a ros2_control robot's loop alike, its gains its pid_controller's parameters; a loop with no model
    here (:func:`jointctl.cli.served_ros2.has_model`) is measured alone."""
    from jointctl.control.joint_controllers import derivative_law
    from jointctl.identification.frequency_response import analyse, compare, measure_servoed, write_bode

    if not args.controller:
        raise JointCtlError("is required (the loop to sweep)", field="--controller")
    plant = _plant_file(args.plant)  # read before the robot moves
    ros2 = args.hardware == "ros2"
    with _served(args, controller=args.controller, joint=args.joint if ros2 else None) as (session, name):
        hardware = session.hardware
        joint = hardware.joint_of(name)
        label = hardware.controller_node if ros2 else f"/{hardware.namespace}/{name}"
        if ros2:
            from jointctl.cli.served_ros2 import has_model, loop_plant

            plant = loop_plant(hardware, session.robot, plant)
            if not has_model(hardware):
                points, context = measure_servoed(session, joint, frequencies, amplitude=args.amplitude,
                                                  safety=safety)
                result = analyse(points, None)
                result.update(controller=label, plant_source=None, **context)
                write_bode(args.out, result, f"{joint} through {label} ({hardware.loop.actuation} command)")
                return result
        gains = hardware.gains(name)
        # The law the served controller runs: its parameters' ``derivative``, else ros_controllers' (error).
        law = derivative_law(hardware.controller_parameters().get(name, {}))
        points, context = measure_servoed(session, joint, frequencies, amplitude=args.amplitude, gains=gains,
                                          derivative=law, plant=plant, safety=safety)
        context["gains"] = gains
        context["derivative"] = law
        pose = dict(zip(hardware.joint_names, hardware.position))
        pose[joint] = context["rest"]
        return compare(points, context, label, plant, session.robot, pose, out_dir=args.out)


def _plant_file(path: Path | None) -> dict | None:
    if path is None:
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise JointCtlError(f"cannot read the plant ({exc})", field="--plant", value=str(path)) from None


def _loop_scenario(args: argparse.Namespace, overrides=()):
    """The scenario of ``bode``/``autotune``: a robot with the controller file its loop needs (default
    position, velocity for a velocity controller's name; with ``--hardware ros2`` the robot's ROS 2 file,
    ``ros2``: the simulated twin of a ros2_control robot, its controller of the same name), or a scenario;
    what the target was taken for said once, when no gains under test are set."""
    default = ("ros2" if getattr(args, "hardware", "sim") == "ros2"
               else "velocity" if "velocity" in args.controller else "position")
    return target_scenario(args, default_controllers=default, extra_overrides=overrides, say=not overrides)


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
    if args.robust:
        return _robust_autotune(args, zeta, bandwidth_hz, settling_s)
    plant = _plant_file(args.plant)
    safety = safety_from_args(args)
    if args.dry_run:
        from jointctl.identification.plan import plan_autotune

        return _print_plan(plan_autotune(_loop_scenario(args), args.controller, bandwidth_hz=bandwidth_hz, zeta=zeta,
                                         step=args.step, plant=plant, safety=safety, settling_s=settling_s,
                                         ramp_s=args.ramp_s, remedies=tuple(args.remedy),
                                         integrator="euler" if args.hardware == "sim" else "hold"))
    if args.hardware in ("ros", "ros2"):
        from jointctl.identification.autotune import autotune_servoed

        ros2 = args.hardware == "ros2"
        with _served(args, controller=args.controller, joint=args.joint if ros2 else None,
                     tool="autotune") as (session, name):
            if ros2:
                from jointctl.cli.served_ros2 import loop_plant

                plant = loop_plant(session.hardware, session.robot, plant)
            result = autotune_servoed(session, name, bandwidth_hz=bandwidth_hz, zeta=zeta, step=args.step,
                                      plant=plant, out_dir=args.out, settling_s=settling_s, safety=safety)
    else:
        result = autotune(lambda overrides: _loop_scenario(args, overrides), args.controller,
                          bandwidth_hz=bandwidth_hz, zeta=zeta, step=args.step, plant=plant, out_dir=args.out,
                          settling_s=settling_s, safety=safety, ramp_s=args.ramp_s, remedies=tuple(args.remedy))
    print(metrics_json(result))
    say_warnings(result)
    print(f"wrote {result['yaml']}", file=sys.stderr)
    return 0


def _robust_autotune(args: argparse.Namespace, zeta: float, bandwidth_hz: float, settling_s: float | None) -> int:
    """``autotune --robust``: gains for the spec at the step on every plant of the family (see
    :mod:`jointctl.sweep.robust_design`), each plant run on the simulated robot; what binds said, with the
    remedies checked. With ``--hardware ros2`` the family is the robot's simulated twin's and the design is then
    checked on the robot (:func:`_robust_ros2`)."""
    from jointctl.sweep.robust_design import parse_range, write_robust

    why = "a robust design runs on the simulated robot's model family (with --hardware ros2: then checked on the robot)"
    for flag, unsupported in (("--hardware", args.hardware not in ("sim", "ros2")),
                              ("--plant", args.plant is not None), ("--dry-run", getattr(args, "dry_run", False))):
        if unsupported:
            raise JointCtlError(f"{why}; drop it or --robust", field=flag,
                                value=getattr(args, flag[2:].replace("-", "_")))
    ranges = [parse_range(item) for item in args.robust]  # checked before anything runs
    if args.hardware == "ros2":
        result = _robust_ros2(args, ranges, zeta, bandwidth_hz, settling_s)
    else:
        result = _robust_design(args, ranges, zeta, bandwidth_hz, settling_s, args.controller)
        write_robust(args.out, _loop_scenario(args), args.controller, result)
    print(metrics_json(result))
    say_warnings(result)
    print(f"wrote {result['yaml']}", file=sys.stderr)
    return 0


def _robust_design(args: argparse.Namespace, ranges, zeta: float, bandwidth_hz: float, settling_s: float | None,
                   controller: str, twin_overrides=()) -> dict:
    """:func:`~jointctl.sweep.robust_design.robust_autotune` of ``controller`` on the target's simulated robot,
    ``twin_overrides`` after the user's ``--set``."""
    from jointctl.identification.autotune import overshoot_of
    from jointctl.sweep.robust_design import robust_autotune

    twin = list(twin_overrides)
    controllers = args.controllers or ("ros2" if args.hardware == "ros2" else None)
    return robust_autotune(lambda overrides: _loop_scenario(args, [*twin, *overrides]), controller, ranges,
                           overshoot_pct=100 * overshoot_of(zeta), settling_s=settling_s, zeta=zeta,
                           bandwidth_hz=bandwidth_hz, step=args.step, target=args.target, controllers=controllers,
                           overrides=[*args.overrides, *twin], samples=args.robust_samples, seed=args.seed,
                           scheduler=args.scheduler, workers=args.workers, remedies=tuple(args.remedy),
                           ramp_s=args.ramp_s)


def _robust_ros2(args: argparse.Namespace, ranges, zeta: float, bandwidth_hz: float, settling_s: float | None) -> dict:
    """``autotune --robust --hardware ros2``: the family is the simulated twin's (the target robot with its ROS 2
    controller file, ``--controllers``, default ``ros2``), posed as the robot is (its joint states, the loop's
    joint at the reference it holds) and run at the robot's update rate; its controller of the same name must be
    the pid_controller servoing the same joint. The design runs with the robot left alone (this side off the graph:
    its joint states do not pile up unread while the family runs); then the robot is joined again and the robust
    design checked on it (:func:`~jointctl.sweep.robust_served.check_served`) and written as its controller's
    parameters."""
    from jointctl.control.manager import read_yaml
    from jointctl.control.ros2_parameters import is_ros2_parameters
    from jointctl.identification.plan import configured_loop
    from jointctl.model.loader import load_robot_model
    from jointctl.sweep.robust_design import write_robust
    from jointctl.sweep.robust_served import check_served, ros2_gains, served_warnings

    if args.target is None:
        raise JointCtlError("is required with --robust: the robot (its folder or built-in name, with --controllers for "
                            "its ROS 2 file, default ros2) whose simulated twin the family varies", field="target")
    safety = safety_from_args(args)
    twin = _loop_scenario(args)
    if not is_ros2_parameters(read_yaml(twin.controller_file)):
        raise JointCtlError("must name the robot's ROS 2 controller file (its pid_controller is the twin of the "
                            "robot's)", field="--controllers", value=args.controllers)
    robot = load_robot_model(twin.robot.description)
    with _served(args, controller=args.controller, joint=args.joint, tool="robust") as (session, name):
        hardware, loop = session.hardware, session.hardware.loop
        configured_loop(twin, robot, controller=name, joint=loop.joint)  # the twin's pid_controller of that joint
        hardware.read()
        pose = dict(zip(hardware.joint_names, hardware.position))
        held = (hardware.set_points or {}).get(loop.joint)
        pose[loop.joint] = held if held is not None else pose[loop.joint]
        period, joint = session.loop.period_s, loop.joint
    # A joint resting on a limit sits a little beyond it: the twin starts at the limit.
    overrides = [f"initial_positions.{name_}={_within(robot, name_, value)!r}" for name_, value in pose.items()
                 if robot.has_joint(name_)]
    if abs(twin.loop_period_s - period) > 1e-9 * period:
        overrides.append(f"loop_rate_hz={1 / period!r}")
    print(f"jointctl: the family is {args.target}'s simulated {name}, posed as the robot is, at {1 / period:g} Hz",
          file=sys.stderr)
    result = _robust_design(args, ranges, zeta, bandwidth_hz, settling_s, name, overrides)
    result["twin"] = {"target": args.target, "controllers": args.controllers or "ros2", "overrides": overrides}
    with _served(args, controller=name, joint=joint, tool="robust") as (session, _):
        hardware = session.hardware
        result["robot"] = check_served(session, name, result, safety=safety)
        result["gains_restored"] = hardware.gains(name)
        result["warnings"] = [*result.get("warnings", []), *served_warnings(result)]
        write_robust(args.out, twin, name, result,
                     document=hardware.tuned_parameters(name, ros2_gains(result, hardware.loop.command_dof)))
    return result


def _within(robot, joint: str, value: float) -> float:
    """``value`` [m or rad] within ``joint``'s range (unbounded: as it is)."""
    lower, upper, _ = robot.joint(joint).range_and_speed()
    return float(min(max(value, lower), upper))


def _joint_type(robot: str | None, joint: str) -> str:
    """The type of ``joint`` of ``robot`` (a built-in name or a robot's file; for a trace)."""
    from jointctl.model.loader import load_robot_model
    from jointctl.scenario.targets import robot_files

    if robot is None:
        raise JointCtlError("a trace needs --joint-type or --robot (to read the joint's type)", field="--joint-type")
    found = robot_files(robot)
    if found is None:
        raise JointCtlError("no such robot (a built-in name, a robot folder, robot.yaml, .urdf or .xacro)",
                            field="--robot", value=robot)
    model = load_robot_model(found[0].description)
    if not model.has_joint(joint):
        raise JointCtlError(f"no such joint on {robot}", field="--joint", value=joint)
    return model.joint(joint).type

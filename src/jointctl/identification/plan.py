"""``--dry-run``: what ``identify``, ``bode`` and ``autotune`` would do to a joint, without moving anything.

The plan is made the way the run makes it (:mod:`jointctl.identification.safety`'s rule on the loop
model), from what can be read without a robot: the robot model (URDF/xacro), the scenario's controller
file with its overrides (the loop's gains and derivative law), the scenario's initial position of the
joint as where it rests (the simulated robot starts there; a served robot's pose is read when the
command runs, and the plan made again from it) and its gravity. No session, world, loop or ROS node
is created. Each plan says, for the excited joint: where it starts, the amplitude(s) (per frequency,
or the chirp's over its band), how long it runs, the peak position swing, speed and effort predicted
against each limit, and which limit binds.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np

from jointctl.control.joint_controllers import derivative_law
from jointctl.control.manager import read_yaml, set_dotted
from jointctl.control.ros2_parameters import is_ros2_parameters, read_ros2_controllers
from jointctl.errors import ConfigError
from jointctl.identification.autotune import _gravity_load, the_move, tune
from jointctl.identification.excitation import plan_identification
from jointctl.identification.frequency_response import (LoopModel, loop_model, plan_summary, plan_sweep,
                                                         plant_friction)
from jointctl.identification.identify import SETTLE_AFTER_S, SETTLE_S
from jointctl.identification.safety import Safety, envelope_for, plan_rows
from jointctl.model.loader import load_robot_model

LOOP_TYPES = {"effort_controllers/JointPositionController": "position",
              "effort_controllers/JointVelocityController": "velocity"}
#: ros2_controllers' PID, a position loop when it commands a joint's effort on that joint's position.
PID_TYPE = "pid_controller/PidController"


def _pid_loop(entry: dict, joint: str | None) -> tuple[str, dict, bool] | None:
    """(joint, gains ``{"p", "i", "d"}``, whether the integral acts) of a pid_controller's ROS 2 parameters
    when it is an effort position loop of ``joint`` (of its only dof when None; see
    :mod:`jointctl.control.position_loop`), else None. The ``i`` the loop models is 0 when the clamps are
    both 0 (control_toolbox clamps the term to them: no integral)."""
    dofs = entry.get("dof_names") or []
    states = entry.get("reference_and_state_dof_names") or dofs
    interfaces = entry.get("reference_and_state_interfaces") or []
    if entry.get("command_interface") != "effort" or not interfaces or interfaces[0] != "position":
        return None
    if entry.get("use_external_measured_states") or list(states) != list(dofs):
        return None
    if joint is None:
        if len(dofs) != 1:
            return None
        joint = dofs[0]
    if joint not in dofs:
        return None
    raw = (entry.get("gains") or {}).get(joint) or {}
    acts = bool(float(raw.get("i_clamp_max", 0.0)) or float(raw.get("i_clamp_min", 0.0)))
    gains = {"p": float(raw.get("p", 0.0)), "i": float(raw.get("i", 0.0)) if acts else 0.0,
             "d": float(raw.get("d", 0.0))}
    return joint, gains, bool(gains["i"])


def _ros2_loop(scenario, tree, *, controller: str | None, joint: str | None) -> dict:
    """:func:`configured_loop` of a ROS 2 controller file: its pid_controllers that are effort position loops."""
    source = str(scenario.controller_file)
    ros2 = read_ros2_controllers(tree, source, base_dir=Path(source).parent, read=read_yaml)
    body = {name: dict(entry) for name, entry in ros2.controllers.items()}
    for dotted, value in scenario.controller_overrides.items():
        if dotted.split(".", 1)[0] in body:
            set_dotted(body, dotted, value, source=source)
    pids = {name: entry for name, entry in body.items() if entry.get("type") == PID_TYPE}
    if controller is not None:
        entry = pids.get(controller)
        found = _pid_loop(entry, joint) if entry is not None else None
        if found is None:
            raise ConfigError(f"no pid_controller of that name in {source} commanding a joint's effort on its "
                              f"position (it has: {', '.join(pids) or 'none'})", field="--controller",
                              value=controller)
        name = controller
    else:
        loops = [(n, _pid_loop(e, joint)) for n, e in pids.items()]
        loops = [(n, f) for n, f in loops if f is not None]
        if not loops:
            raise ConfigError("the joint needs a pid_controller commanding its effort on its position to follow "
                              "the excitation", field="--joint", value=joint)
        name, found = loops[0]
    joint, gains, integrates = found
    return {"name": name, "joint": joint, "loop": "position", "gains": gains, "derivative": "error",
            "droops": not integrates}


def configured_loop(scenario, robot, *, controller: str | None = None, joint: str | None = None) -> dict:
    """The joint loop ``controller`` (or the position controller of ``joint``) as the scenario's
    controller file and overrides configure it, read from the file alone: ``name``, ``joint``,
    ``loop`` ("position" or "velocity"), ``gains`` ``{"p", "i", "d"}``, ``derivative`` law and
    ``droops`` (a position loop whose p alone holds gravity). In a ROS 2 file, a pid_controller that
    commands ``joint``'s effort on its position (``joint``: which dof of one that servos several): the
    derivative on the error (a plain position reference). ConfigError naming the flag otherwise."""
    source = str(scenario.controller_file)
    tree = read_yaml(scenario.controller_file)
    if is_ros2_parameters(tree):
        return _ros2_loop(scenario, tree, controller=controller, joint=joint)
    body = tree
    prefix = ""
    if isinstance(tree, dict) and not all(isinstance(v, dict) and "type" in v for v in tree.values()):
        spaces = {k: v for k, v in tree.items() if isinstance(v, dict)}
        key = robot.namespace if robot.namespace in spaces else next(iter(spaces)) if len(spaces) == 1 else None
        if key is None:
            raise ConfigError("cannot tell which namespace holds the controllers", source=source, value=sorted(tree))
        body, prefix = spaces[key], key
    body = copy.deepcopy(body if isinstance(body, dict) else {})
    for dotted, value in scenario.controller_overrides.items():
        if dotted.split(".", 1)[0] in body:
            set_dotted(body, dotted, value, source=source, field_prefix=prefix)
    loops = {name: c for name, c in body.items() if isinstance(c, dict) and c.get("type") in LOOP_TYPES}
    if controller is not None:
        entry = loops.get(controller)
        if entry is None:
            raise ConfigError(f"no joint position or velocity controller of that name in {source} (it has: "
                              f"{', '.join(loops) or 'none'})", field="--controller", value=controller)
        name = controller
    else:
        found = [n for n, c in loops.items() if c.get("joint") == joint and LOOP_TYPES[c["type"]] == "position"]
        if not found:
            raise ConfigError("the joint needs an effort_controllers/JointPositionController to follow the "
                              "excitation (use a position controller file)", field="--joint", value=joint)
        name, entry = found[0], loops[found[0]]
    pid = entry.get("pid") or {}
    gains = {k: float(pid.get(k, 0.0)) for k in ("p", "i", "d")}
    loop = LOOP_TYPES[entry["type"]]
    feedforward = entry.get("feedforward") or {}
    feeds_gravity = isinstance(feedforward, dict) and bool(feedforward.get("gravity"))
    droops = loop == "position" and not gains["i"] and not feeds_gravity
    return {"name": name, "joint": entry.get("joint"), "loop": loop, "gains": gains,
            "derivative": derivative_law(entry), "droops": droops}


def _robot_and_rest(scenario, joint: str):
    robot = load_robot_model(scenario.robot.description)
    if not robot.has_joint(joint) or not robot.joint(joint).is_movable:
        movable = ", ".join(j.name for j in robot.movable_joints)
        raise ConfigError(f"no movable joint of that name (movable: {movable})", field="--joint", value=joint)
    pose = {j.name: float(scenario.initial_positions.get(j.name, 0.0)) for j in robot.movable_joints}
    return robot, pose[joint], pose


def plan_identify(scenario, joint: str, *, amplitude: float | None = None, duration_s: float = 10.0,
                  f_start_hz: float = 0.2, f_end_hz: float = 3.0, safety: Safety | None = None,
                  plant: dict | None = None) -> dict:
    """``identify``'s plan for ``joint`` of the scenario's robot (see the module docstring)."""
    robot, rest, pose = _robot_and_rest(scenario, joint)
    config = configured_loop(scenario, robot, joint=joint)
    chirp, allowance, source = plan_identification(
        robot, joint, rest, pose=pose, loop=(config["gains"], config["derivative"], config["droops"], None),
        period_s=scenario.loop_period_s, gravity_m_s2=scenario.gravity_m_s2, safety=safety, plant=plant,
        amplitude=amplitude, duration_s=duration_s, f_start_hz=f_start_hz, f_end_hz=f_end_hz,
        settle_after_s=SETTLE_AFTER_S)
    return {"command": "identify", "joint": joint, "controller": config["name"], "gains": config["gains"],
            "derivative": config["derivative"], "planned_on": source, "start": rest,
            "excitation": {"amplitude": chirp.amplitude, "safe_amplitude": allowance.amplitude,
                           "f_start_hz": f_start_hz, "f_end_hz": f_end_hz, "duration_s": duration_s},
            "duration_s": SETTLE_S + duration_s + SETTLE_AFTER_S, "binds": allowance.binds,
            "predicted": allowance.predicted(chirp.amplitude), "envelope": allowance.envelope}


def plan_bode(scenario, controller: str | None, frequencies_hz, *, amplitude: float | None = None,
              plant: dict | None = None, safety: Safety | None = None, joint: str | None = None,
              settle_s: float = 1.5, measure_periods: int = 4, measure_s: float = 1.0) -> dict:
    """``bode``'s plan for ``controller`` (or, for a servo loop that is not jointctl's, ``joint``'s position
    loop, planned on the reference alone) of the scenario's robot: per frequency the amplitude and the
    predicted peaks (see the module docstring)."""
    config = None
    if controller is not None:
        robot = load_robot_model(scenario.robot.description)
        config = configured_loop(scenario, robot, controller=controller)
        joint = config["joint"]
    robot, rest, pose = _robot_and_rest(scenario, joint)
    loop = config["loop"] if config else "position"
    model = source = None
    if config is not None:
        model, source = loop_model(robot, joint, pose, config["gains"], scenario.loop_period_s, loop,
                                   config["derivative"], plant)
    envelope = envelope_for(robot, joint, rest, safety, pose=pose, gravity_m_s2=scenario.gravity_m_s2,
                            friction=plant_friction(plant),
                            droop_gain=config["gains"]["p"] if config and config["droops"] else None)
    plan = plan_sweep(frequencies_hz, envelope, model, loop=loop, period_s=scenario.loop_period_s,
                      amplitude=amplitude, settle_s=settle_s, measure_periods=measure_periods, measure_s=measure_s)
    return {"command": "bode", "joint": joint, "controller": controller, "loop": loop, "planned_on": source,
            "gains": config["gains"] if config else None, "derivative": config["derivative"] if config else None,
            "start": rest, "duration_s": plan["duration_s"], "sweep": plan_summary(plan), "envelope": envelope,
            "rows": plan["rows"]}


def plan_autotune(scenario, controller: str, *, bandwidth_hz: float, zeta: float = 0.7, step: float | None,
                  plant: dict | None = None, safety: Safety | None = None, settling_s: float | None = None,
                  ramp_s: float | None = None, remedies: tuple[str, ...] = (), integrator: str = "euler") -> dict:
    """``autotune``'s plan: the gains designed for the spec at the step (``step``, else the scenario's, else
    autotune's default), the step's predicted peaks, and the check sweep's amplitudes (see the module
    docstring); ``integrator`` as :func:`~jointctl.identification.autotune.tune`'s ("euler": the simulated
    robot; "hold": a real one)."""
    robot = load_robot_model(scenario.robot.description)
    config = configured_loop(scenario, robot, controller=controller)
    joint, loop = config["joint"], config["loop"]
    robot, rest, pose = _robot_and_rest(scenario, joint)
    gravity = None if plant is not None else _gravity_load(robot, pose, joint, scenario.gravity_m_s2)
    spec = robot.joint(joint)
    effort_limit = spec.limits.effort if spec.limits is not None and spec.limits.effort > 0 else math.inf
    step, reference, ramp_s = the_move(scenario, controller, step, ramp_s)
    result = tune(controller, joint, loop, scenario.loop_period_s, plant, robot, pose, gravity, effort_limit,
                  config["gains"], bandwidth_hz=bandwidth_hz, zeta=zeta, step=step, settling_s=settling_s,
                  derivative=config["derivative"], safety=safety, gravity_m_s2=scenario.gravity_m_s2,
                  ramp_s=ramp_s or 0.0, reference=reference, remedies=remedies, integrator=integrator)
    gains = result["gains"]
    model = LoopModel(result["mass"], result["damping"], gains["p"], gains["i"], gains["d"], scenario.loop_period_s,
                      loop, config["derivative"])
    envelope = envelope_for(robot, joint, rest, safety, pose=pose, gravity_m_s2=scenario.gravity_m_s2,
                            friction=plant_friction(plant), droop_gain=gains["p"] if config["droops"] else None)
    frequencies = [bandwidth_hz / 20, *np.logspace(math.log10(bandwidth_hz / 2.5), math.log10(bandwidth_hz * 2.5), 15)]
    sweep = plan_sweep(frequencies, envelope, model, loop=loop, period_s=scenario.loop_period_s,
                       amplitude_cap=result["check_step"])
    return {"command": "autotune", "joint": joint, "controller": controller, "loop": loop, "start": rest,
            "gains": gains, "previous_gains": config["gains"], "derivative": config["derivative"],
            "planned_on": result["plant_source"], "step": step, "check_step": result["check_step"],
            "note": result.get("note"), "step_plan": result["step_plan"], "model": result["model"],
            "sweep": plan_summary(sweep), "rows": sweep["rows"], "envelope": envelope,
            "duration_s": 4.0 + 2 * sweep["duration_s"]}


def format_plan(plan: dict) -> str:
    """The plan as the lines ``--dry-run`` prints."""
    env = plan["envelope"]
    unit = env.unit
    effort_unit = "N" if unit == "m" else "N·m"
    lines = [f"{plan['command']} --dry-run: nothing moves. Joint {plan['joint']}"
             + (f", controller {plan['controller']}" if plan.get("controller") else "")
             + f", starting at {plan['start']:.4g} {unit}.",
             "Loop model: " + (f"plant from the {plan['planned_on']}, gains {_gains(plan['gains'])}, derivative on the "
                               f"{plan['derivative']}" if plan.get("planned_on") else
                               "none (a servo loop that is not jointctl's): the reference alone, effort not predicted"),
             "Limits (the excitation plans within the budgets, and stops if the measured motion crosses a user limit):",
             *plan_rows(env)]
    if plan["command"] == "identify":
        x, p = plan["excitation"], plan["predicted"]
        lines += [f"Chirp {x['f_start_hz']:g} to {x['f_end_hz']:g} Hz over {x['duration_s']:g} s, amplitude "
                  f"{x['amplitude']:.4g} {unit} (largest safe {x['safe_amplitude']:.4g}); "
                  f"{plan['duration_s']:g} s with the rests before and after.",
                  _peaks_line(p, unit, effort_unit),
                  f"Binding limit: {plan['binds']} ({env.limit_names()[plan['binds']]})."]
        return "\n".join(lines)
    if plan["command"] == "autotune":
        s = plan["step_plan"]
        lines += [f"Designed gains {_gains(plan['gains'])} (now {_gains(plan['previous_gains'])}); predicted "
                  + ", ".join(f"{k} {v:.4g}" for k, v in plan["model"].items() if isinstance(v, float)) + ".",
                  f"Check step {plan['check_step']:.4g} {unit}{'/s' if plan['loop'] == 'velocity' else ''} "
                  f"(asked {plan['step']:g}): peak swing {s['peak_position']:.4g} {unit} of room {s['room']:.4g}, "
                  f"speed {s['peak_velocity']:.4g} {unit}/s of {s['velocity_limit']:g}, effort "
                  f"{s['peak_effort']:.4g} {effort_unit} of {s['effort_limit']:g} (one cycle); binds: {s['binds']}."]
        if plan.get("note"):
            lines.append(f"Note: {plan['note']}")
        lines.append("Check sweep:")
    lines += [f"{len(plan['rows'])} stepped sines, {plan['sweep']['duration_s']:.1f} s:",
              f"  {'f [Hz]':>8} {'A [' + unit + ']':>11} {'safe':>10} {'swing':>9} {'speed':>9} {'effort':>9}  binds"]
    for row in plan["rows"]:
        p = row["predicted"]
        lines.append(f"  {row['frequency_hz']:8.3g} {row['amplitude']:11.4g} {row['safe_amplitude']:10.4g} "
                     f"{p['position']['peak']:9.4g} {p['velocity']['peak']:9.4g} {p['effort']['peak']:9.4g}  "
                     f"{row['binds']}")
    worst = {k: max(row["predicted"][k]["peak"] for row in plan["rows"]) for k in ("position", "velocity", "effort")}
    lines.append(f"  largest: swing {worst['position']:.4g} {unit} (room {env.room:.4g}), speed "
                 f"{worst['velocity']:.4g} {unit}/s (limit {env.velocity_max:g}), effort {worst['effort']:.4g} "
                 f"{effort_unit} (limit {env.effort_max:g})")
    return "\n".join(lines)


def _peaks_line(p: dict, unit: str, effort_unit: str) -> str:
    return (f"Predicted peaks: swing {p['position']['peak']:.4g} {unit} (budget {p['position']['budget']:.4g} of "
            f"room {p['position']['room']:.4g}), speed {p['velocity']['peak']:.4g} {unit}/s (budget "
            f"{p['velocity']['budget']:.4g}, limit {p['velocity']['limit']:g}), effort {p['effort']['peak']:.4g} "
            f"{effort_unit} (budget {p['effort']['budget']:.4g}, limit {p['effort']['limit']:g}).")


def _gains(gains: dict) -> str:
    return "p {p:.4g}, i {i:.4g}, d {d:.4g}".format(**gains)


def plan_json(plan: dict) -> dict:
    """The plan without its envelope object, for metrics-style JSON."""
    env = plan["envelope"]
    out = {k: v for k, v in plan.items() if k not in ("envelope", "rows")}
    out["limits"] = {"window": list(env.window), "room": env.room, "velocity": env.velocity_max,
                     "effort": env.effort_max, "load_at_rest": env.bias, "droop": env.droop, "budgets": env.budgets()}
    return out


__all__ = ["configured_loop", "format_plan", "plan_autotune", "plan_bode", "plan_identify", "plan_json"]

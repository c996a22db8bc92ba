"""Write a robot folder for a user's own URDF/xacro: what ``jointctl init`` leaves behind.

::

    DIR/
      robot.yaml                    description (relative path to the user's file), controller files,
                                    serve defaults (the home pose), the joint the tuning page plots
      config/<robot>_control.yaml   ros_control YAML under the robot's namespace: a joint_state_controller
                                    and an effort_controllers/JointPositionController per driven joint
      scenarios/step_<joint>.yaml   per driven joint: a step from home (along a ramp where a step's derivative
                                    kick would clamp the effort), with its step analysis

Every command that takes a robot then takes ``DIR`` (or ``DIR/robot.yaml``), and every scenario
may name it (``robot: ..`` from ``scenarios/``). Nothing is overwritten unless asked.
"""

from __future__ import annotations

import os
from pathlib import Path

from jointctl.errors import ConfigError

#: The joint_state_controller's rate [Hz]: the chapter's 50, ros_control's usual; the ROS graph's joint
#: states at that rate (what rviz and robot_state_publisher need, cheap for every subscriber). identify
#: over the graph fits them within a few per cent, and exactly at the loop's rate: the file says how.
JOINT_STATE_RATE_HZ = 50


def planned_files(out_dir: Path, robot_name: str, joints) -> dict[str, Path]:
    """{role: path} of the files :func:`write_robot_folder` writes into ``out_dir``: ``manifest``,
    ``controllers``, ``scenario`` (the first joint's step) and ``scenario:<joint>`` for each of ``joints``."""
    files = {"manifest": out_dir / "robot.yaml", "controllers": out_dir / "config" / f"{robot_name}_control.yaml",
             "scenario": out_dir / "scenarios" / f"step_{joints[0]}.yaml"}
    files.update({f"scenario:{joint}": out_dir / "scenarios" / f"step_{joint}.yaml" for joint in joints[1:]})
    return files


def write_robot_folder(description: Path, out_dir: Path, robot_name: str, loops, *, bandwidth_hz: float,
                       zeta: float, gravity_z_m_s2: float = -9.81, timestep_s: float = 0.001,
                       force: bool = False) -> dict[str, Path]:
    """Write the folder of the module docstring for ``description`` with the starting ``loops``
    (:class:`~jointctl.identification.starting_gains.StartingGains`, at least one); {role: path}.
    A ConfigError naming the file when one exists and ``force`` is false (before anything is written)."""
    files = planned_files(out_dir, robot_name, [loop.joint for loop in loops])
    existing = [str(p) for p in files.values() if p.exists()]
    if existing and not force:
        raise ConfigError("exists; pass --force to overwrite", field="--out", value=existing[0])
    for path in files.values():
        path.parent.mkdir(parents=True, exist_ok=True)
    relative = Path(os.path.relpath(description.resolve(), out_dir.resolve())).as_posix()
    files["manifest"].write_text(_manifest(robot_name, relative, loops))
    files["controllers"].write_text(_controllers(robot_name, description.name, loops, bandwidth_hz, zeta))
    for loop in loops:
        key = "scenario" if loop is loops[0] else f"scenario:{loop.joint}"
        files[key].write_text(_step_scenario(robot_name, loops, loop, gravity_z_m_s2, timestep_s))
    return files


def _number(value: float) -> str:
    return f"{value:.6g}"


def _manifest(robot_name: str, description: str, loops) -> str:
    home = ", ".join(f"{loop.joint}: {_number(loop.home)}" for loop in loops)
    return (f"# {robot_name}: written by jointctl init.\n"
            f"description: {description}\n"
            "controllers:\n"
            f"  position: config/{robot_name}_control.yaml\n"
            "# jointctl serve/tune DIR: start at the home pose.\n"
            "serve:\n"
            f"  initial_positions: {{{home}}}\n"
            "tune:\n"
            f"  joint: {loops[0].joint}\n")


def _controllers(robot_name: str, source: str, loops, bandwidth_hz: float, zeta: float) -> str:
    lines = [f"# ros_control controllers for {robot_name}, written by jointctl init from {source}.",
             f"# Starting gains: {bandwidth_hz:g} Hz closed-loop bandwidth, damping ratio {zeta:g}, from each joint's",
             "# inertia at the home pose (derivative on the error, as ros_controllers' JointPositionController",
             "# computes for a plain position command), checked against the effort limits. Tune them on the",
             "# robot with jointctl autotune.",
             f"{robot_name}:",
             "  joint_state_controller:",
             "    type: joint_state_controller/JointStateController",
             "    # joint_states for rviz and robot_state_publisher; jointctl identify --hardware ros fits them",
             "    # within a few per cent at 50 Hz, exactly every control cycle (serve DIR --set",
             "    # controllers.joint_state_controller.publish_rate=1000).",
             f"    publish_rate: {JOINT_STATE_RATE_HZ}"]
    for loop in loops:
        unit = "kg" if loop.joint_type == "prismatic" else "kg·m²"
        effort = "N" if loop.joint_type == "prismatic" else "N·m"
        lines += ["",
                  f"  # {loop.joint}: inertia {_number(loop.inertia)} {unit}, damping {_number(loop.damping)}, gravity "
                  f"load {_number(loop.gravity_load)} {effort} at home, effort limit "
                  f"{_number(loop.effort_limit)} {effort}"]
        if loop.note:
            lines.append(f"  # {loop.note}")
        gains = loop.gains
        lines += [f"  {loop.controller}:",
                  "    type: effort_controllers/JointPositionController",
                  f"    joint: {loop.joint}",
                  f"    pid: {{p: {_number(gains['p'])}, i: 0.0, d: {_number(gains['d'])}}}"]
    return "\n".join(lines) + "\n"


def _step_scenario(robot_name: str, loops, moved, gravity_z_m_s2: float, timestep_s: float) -> str:
    """The scenario of ``moved``'s step from the home pose, the other joints held by their loops."""
    start, end = moved.home, moved.home + moved.step
    home = ", ".join(f"{loop.joint}: {_number(loop.home)}" for loop in loops)
    started = ", ".join(["joint_state_controller", *(loop.controller for loop in loops)])
    ramp = f", ramp_s: {_number(moved.ramp_s)}" if moved.ramp_s else ""
    how = f"along a {_number(moved.ramp_s)} s ramp (a step's derivative kick would clamp the effort)" \
        if moved.ramp_s else "at once"
    duration = moved.step_at_s + moved.ramp_s + max(2.5, 3 * moved.settling_s)
    return (f"name: {robot_name}_step_{moved.joint}\n"
            "description: >\n"
            f"  {moved.joint} steps by {_number(moved.step)} from the home pose {how}, once the start's sag has "
            "settled; the other joints held by their loops.\n"
            "robot: ..\n"
            "controller_file: position\n"
            f"start_controllers: [{started}]\n"
            f"gravity: {_number(gravity_z_m_s2)}\n"
            f"timestep_s: {_number(timestep_s)}\n"
            f"initial_positions: {{{home}}}\n"
            f"duration_s: {_number(round(duration, 1))}\n"
            "commands:\n"
            f"  {moved.controller}: {{type: step, from: {_number(start)}, to: {_number(end)}, "
            f"at: {_number(moved.step_at_s)}{ramp}}}\n"
            f"analysis: {{type: step_response, joint: {moved.joint}}}\n")


__all__ = ["JOINT_STATE_RATE_HZ", "planned_files", "write_robot_folder"]

"""Write a robot folder for a user's own URDF/xacro: what ``jointctl init`` leaves behind.

::

    DIR/
      robot.yaml                    description (relative path to the user's file), controller files,
                                    serve defaults (the home pose), the joint the tuning page plots
      config/<robot>_control.yaml   ros_control YAML under the robot's namespace: a joint_state_controller
                                    and an effort_controllers/JointPositionController per driven joint
      config/ros2_controllers.yaml  the same loops for ROS 2: controller_manager parameters (update_rate the
                                    loop's), a joint_state_broadcaster and a pid_controller/PidController over the
                                    driven joints (effort; position and velocity), with the same gains
      urdf/<robot>.ros2_control.urdf.xacro
                                    the user's description with a <ros2_control> system (unless it has one):
                                    each driven joint's effort command interface and its position, velocity and
                                    effort state interfaces, the position's initial_value its home;
                                    mock_components/GenericSystem as the hardware plugin (jointctl's simulated
                                    robot stands in for it; a robot's driver or gz_ros2_control replaces it)
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


#: The ROS 2 controller file's name in a robot folder's config/.
ROS2_CONTROLLERS = "ros2_controllers.yaml"
#: The hardware plugin written into the <ros2_control> system: ros2_control's own mock, which every ROS 2
#: install has, so ros2_control_node loads the files as they are.
MOCK_PLUGIN = "mock_components/GenericSystem"


def planned_files(out_dir: Path, robot_name: str, joints, *, ros2_description: bool = True) -> dict[str, Path]:
    """{role: path} of the files :func:`write_robot_folder` writes into ``out_dir``: ``manifest``,
    ``controllers``, ``ros2_controllers``, ``ros2_description`` (with ``ros2_description``), ``scenario`` (the
    first joint's step) and ``scenario:<joint>`` for each of ``joints``."""
    files = {"manifest": out_dir / "robot.yaml", "controllers": out_dir / "config" / f"{robot_name}_control.yaml",
             "ros2_controllers": out_dir / "config" / ROS2_CONTROLLERS,
             "scenario": out_dir / "scenarios" / f"step_{joints[0]}.yaml"}
    if ros2_description:
        files["ros2_description"] = out_dir / "urdf" / f"{robot_name}.ros2_control.urdf.xacro"
    files.update({f"scenario:{joint}": out_dir / "scenarios" / f"step_{joint}.yaml" for joint in joints[1:]})
    return files


def write_robot_folder(description: Path, out_dir: Path, robot_name: str, loops, *, bandwidth_hz: float,
                       zeta: float, gravity_z_m_s2: float = -9.81, timestep_s: float = 0.001,
                       force: bool = False, ros2_description: bool = True) -> dict[str, Path]:
    """Write the folder of the module docstring for ``description`` with the starting ``loops``
    (:class:`~jointctl.identification.starting_gains.StartingGains`, at least one); {role: path}.
    ``ros2_description``: write the description with a <ros2_control> system (false when it has one).
    A ConfigError naming the file when one exists and ``force`` is false (before anything is written)."""
    files = planned_files(out_dir, robot_name, [loop.joint for loop in loops], ros2_description=ros2_description)
    existing = [str(p) for p in files.values() if p.exists()]
    if existing and not force:
        raise ConfigError("exists; pass --force to overwrite", field="--out", value=existing[0])
    for path in files.values():
        path.parent.mkdir(parents=True, exist_ok=True)
    relative = Path(os.path.relpath(description.resolve(), out_dir.resolve())).as_posix()
    files["manifest"].write_text(_manifest(robot_name, relative, loops, ros2_description))
    files["controllers"].write_text(_controllers(robot_name, description.name, loops, bandwidth_hz, zeta))
    files["ros2_controllers"].write_text(_ros2_controllers(robot_name, description.name, loops, bandwidth_hz, zeta,
                                                           timestep_s))
    if ros2_description:
        included = Path(os.path.relpath(description.resolve(), files["ros2_description"].parent.resolve())).as_posix()
        files["ros2_description"].write_text(_ros2_description(robot_name, included, loops))
    for loop in loops:
        key = "scenario" if loop is loops[0] else f"scenario:{loop.joint}"
        files[key].write_text(_step_scenario(robot_name, loops, loop, gravity_z_m_s2, timestep_s))
    return files


def _number(value: float) -> str:
    return f"{value:.6g}"


def _double(value: float) -> str:
    """A number as a ROS 2 double parameter must be written: with a decimal point (``400.0``; ``400`` is an
    integer, which ROS 2 refuses for a double)."""
    text = _number(value)
    return text if any(c in text for c in ".en") else f"{text}.0"


def _manifest(robot_name: str, description: str, loops, ros2_description: bool) -> str:
    home = ", ".join(f"{loop.joint}: {_number(loop.home)}" for loop in loops)
    ros2 = (f"# ROS 2: ros2_control_node takes urdf/{robot_name}.ros2_control.urdf.xacro (the description with its\n"
            f"# <ros2_control>) and config/{ROS2_CONTROLLERS}.\n" if ros2_description else "")
    return (f"# {robot_name}: written by jointctl init.\n"
            f"description: {description}\n"
            f"{ros2}"
            "controllers:\n"
            f"  position: config/{robot_name}_control.yaml\n"
            f"  ros2: config/{ROS2_CONTROLLERS}\n"
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


def _ros2_controllers(robot_name: str, source: str, loops, bandwidth_hz: float, zeta: float,
                      timestep_s: float) -> str:
    """The ROS 2 controller_manager parameters of the same loops (see the module docstring)."""
    rate = round(1.0 / timestep_s)
    joints = ", ".join(loop.joint for loop in loops)
    lines = [f"# ROS 2 (ros2_control) controllers for {robot_name}, written by jointctl init from {source}:",
             f"# ros2_control_node --ros-args --params-file {ROS2_CONTROLLERS}; jointctl runs them as the same types",
             "# compute (docs/ros2_control_files.md). The controller manager's update_rate is the loop's.",
             f"# Starting gains: {bandwidth_hz:g} Hz closed-loop bandwidth, damping ratio {zeta:g} (those of "
             f"{robot_name}_control.yaml):",
             "# pid_controller differentiates the error for a reference without values_dot, as ros_controllers'",
             "# JointPositionController does for a plain command; with values_dot, the velocity error.",
             "# ROS 2 declares the gains doubles: keep the decimal points.",
             "controller_manager:",
             "  ros__parameters:",
             f"    update_rate: {rate}",
             "    joint_state_broadcaster:",
             "      type: joint_state_broadcaster/JointStateBroadcaster",
             "    pid_controller:",
             "      type: pid_controller/PidController",
             "",
             "pid_controller:",
             "  ros__parameters:",
             f"    dof_names: [{joints}]",
             "    command_interface: effort",
             "    reference_and_state_interfaces: [position, velocity]",
             "    gains:"]
    for loop in loops:
        gains = loop.gains
        lines.append(f"      {loop.joint}: {{p: {_double(gains['p'])}, i: 0.0, d: {_double(gains['d'])}, "
                     "i_clamp_max: 0.0, i_clamp_min: 0.0}")
    return "\n".join(lines) + "\n"


def _ros2_description(robot_name: str, included: str, loops) -> str:
    """The user's description (``included``, relative to this file) with a <ros2_control> system for ``loops``."""
    lines = ['<?xml version="1.0"?>',
             f"<!-- {robot_name} for ROS 2, written by jointctl init: the description as it is, and the ros2_control",
             "     hardware of its driven joints (effort commands; position, velocity and effort states, each joint",
             "     starting at its home). -->",
             f'<robot name="{robot_name}" xmlns:xacro="http://www.ros.org/wiki/xacro">',
             f'  <xacro:include filename="{included}"/>',
             f'  <ros2_control name="{robot_name}_system" type="system">',
             "    <hardware>",
             "      <!-- The robot's hardware plugin (its driver; gz_ros2_control/GazeboSimSystem in Gazebo).",
             f"           jointctl's simulated robot stands in for it; {MOCK_PLUGIN} lets",
             "           ros2_control_node load the files as they are. -->",
             f"      <plugin>{MOCK_PLUGIN}</plugin>",
             "    </hardware>"]
    for loop in loops:
        lines += [f'    <joint name="{loop.joint}">',
                  '      <command_interface name="effort"/>',
                  f'      <state_interface name="position"><param name="initial_value">{_double(loop.home)}</param>'
                  "</state_interface>",
                  '      <state_interface name="velocity"/>',
                  '      <state_interface name="effort"/>',
                  "    </joint>"]
    lines += ["  </ros2_control>", "</robot>"]
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


__all__ = ["JOINT_STATE_RATE_HZ", "MOCK_PLUGIN", "ROS2_CONTROLLERS", "planned_files", "write_robot_folder"]

"""identify, bode and autotune on a ros2_control robot (``--hardware ros2``): the session on its loop, and
the plant each tool models that loop with.

What the loop drives decides the plant: a pid_controller commanding ``effort`` moves the joint's mass or
inertia (the robot model's, or ``--plant``); one commanding ``acceleration`` moves a unit one (the
command is q̈ itself: mass 1, no damping, unless ``--plant`` says otherwise); anything else (a velocity or
position command, a forward command controller: the hardware's own servo) has no effort model here:
bode measures it without a model, identify fits it only when its joint states carry the effort, and
autotune refuses it (no gains of ROS's, or none that act as PD on an effort).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import sys
import tempfile
from pathlib import Path

from jointctl.cli.common import ros2_edge
from jointctl.errors import ConfigError

#: The controller commands that move a plant jointctl models (a mass or an inertia driven by an effort).
MODELLED = ("effort", "acceleration")


@contextlib.contextmanager
def served_ros2(args: argparse.Namespace, *, controller: str | None = None, joint: str | None = None,
                tool: str | None = None):
    """(session, controller name) on a ros2_control robot on the ROS 2 graph: the model from the target
    (a robot or a scenario) or, without one, from the robot's ``/robot_description``; the loop found
    through its controller manager under ``--namespace`` and refused before anything is sent when
    ``tool`` cannot work on it (:func:`refuse`); the session paced to the wall clock at the loop's update
    rate; on the way out (an error and Ctrl-C too) the loop's reference and gains put back as they were
    found."""
    graph_module = ros2_edge("graph_client")  # rclpy first: its absence is what a user has to fix
    hardware_module = ros2_edge("served_hardware")
    from jointctl.model.loader import load_robot_model
    from jointctl.scenario.session import Session
    from jointctl.scenario.spec import RobotFiles, load_scenario, scenario_for_robot
    from jointctl.scenario.targets import robot_files

    namespace = (args.namespace or "").strip("/")
    with tempfile.TemporaryDirectory(prefix="jointctl-ros2-") as folder:
        folder = Path(folder)
        graph = graph_module.GraphClient()
        try:
            scenario = None
            if args.target is None:
                text, topic = hardware_module.served_description(graph, namespace)
                description = folder / "robot_description.urdf"
                description.write_text(text)
                files, taken = RobotFiles("robot_description", description, {}, folder), f"the model on {topic}"
            elif (found := robot_files(args.target)) is not None:
                files, taken = found
                taken = f"{args.target} as {taken}"
            else:
                scenario = load_scenario(args.target, args.overrides)
                files, taken = scenario.robot, f"{args.target} as a scenario"
            names = [j.name for j in load_robot_model(files.description).movable_joints]
            hardware = hardware_module.connect(namespace, names, controller, joint=joint, graph=graph,
                                               accept=lambda loop: refuse(loop, tool))
        except BaseException:
            graph.close()
            raise
        try:
            loop = hardware.loop
            if tool == "identify" and not hardware.reports_effort(loop.joint):
                raise ConfigError("the joint states carry no effort for it (is an effort state interface "
                                  "broadcast?): identification fits the effort that moves the joint",
                                  field="--joint", value=loop.joint)
            period = hardware_module.update_period(graph, namespace, loop.controller)
            scenario = _session_scenario(args, files, scenario, folder, period, scenario_for_robot)
            print(f"jointctl: took {taken}; its loop {hardware.controller_node} servos {loop.joint}'s "
                  f"{loop.interface} through its {loop.actuation} at {1 / period:g} Hz", file=sys.stderr)
            session = Session(scenario, hardware=hardware, realtime=True)
            yield session, loop.controller
            say_pace(session)
        finally:
            try:
                hardware.hold(hardware.set_points)
                hardware.write()
            finally:
                hardware.close()


#: A loop that kept less of real time than this (the machine busy) is said to have: the robot, on its own clock,
#: saw the references slower than they were planned.
PACE_WARNING = 0.98


def say_pace(session) -> None:
    """A warning on stderr when this side's loop kept less than ``PACE_WARNING`` of real time."""
    loop = session.loop
    if loop.wall_time_s > 0 and loop.cycle * loop.period_s / loop.wall_time_s < PACE_WARNING:
        print(f"jointctl: warning: this side's loop kept {loop.cycle * loop.period_s / loop.wall_time_s:.2f} of "
              "real time (the machine was busy): the robot saw the references slower than planned, so the figures "
              "are doubtful", file=sys.stderr)


def _session_scenario(args, files, scenario, folder: Path, period: float, scenario_for_robot):
    """The session's scenario: the robot with only a joint state controller of jointctl's (nothing of
    this side commands the joint: the robot's loop does), its loop period the robot's."""
    states = folder / "joint_state_controller.yaml"
    states.write_text("robot:\n  joint_state_controller:\n    type: joint_state_controller/JointStateController\n"
                      "    publish_rate: 50\n")
    if scenario is None:
        return scenario_for_robot(files, str(states), [*args.overrides, "start_controllers=[joint_state_controller]",
                                                       f"timestep_s={period!r}", f"loop_rate_hz={1 / period!r}"])
    return dataclasses.replace(scenario, controller_file=states, controller_overrides={}, commands={},
                               start_controllers=("joint_state_controller",), objects=(), goals=(),
                               loop_period_s=period)


def refuse(loop, tool: str | None) -> None:
    """A ConfigError when ``tool`` needs an effort model ``loop`` (a served
    :class:`~jointctl.ros2.served_hardware.Ros2Loop`) has not: autotune (PD gains on an effort) on anything
    but a pid_controller commanding effort or acceleration, its robust design ("robust": a family of the
    simulated robot, whose pid_controller commands an effort) on anything but one commanding effort, identify
    (the effort must move the plant) on a pid_controller commanding velocity or position."""
    modelled = loop.has_gains and loop.actuation in MODELLED
    if tool == "robust" and modelled and loop.actuation != "effort":
        raise ConfigError(f"the family is the simulated robot's, whose pid_controller commands an effort; "
                          f"{loop.controller} commands {loop.joint}'s {loop.actuation}", field="--robust",
                          value=loop.controller)
    if not modelled and tool in ("autotune", "robust"):
        why = ("a forward command controller has no gains (the hardware servos the joint)" if not loop.has_gains
               else f"it commands {loop.joint}'s {loop.actuation}: jointctl designs PD gains on an effort or an "
                    "acceleration")
        raise ConfigError(f"cannot be tuned: {why}", field="--controller", value=loop.controller)
    if loop.has_gains and not modelled and tool == "identify":
        raise ConfigError(f"{loop.controller} commands its {loop.actuation}, not the effort the joint states "
                          "report: identification needs a loop commanding effort or acceleration", field="--joint",
                          value=loop.joint)


def loop_plant(hardware, robot, plant: dict | None) -> dict | None:
    """The plant the tools model the loop with: ``plant`` (``--plant``) when given, a unit mass or
    inertia for a loop commanding acceleration (said on stderr), else None (the robot model's)."""
    loop = hardware.loop
    if plant is not None or loop.actuation != "acceleration":
        return plant
    prismatic = robot.joint(loop.joint).type == "prismatic"
    print(f"jointctl: {hardware.controller_node} commands {loop.joint}'s acceleration: its plant is a unit "
          f"{'mass' if prismatic else 'inertia'} (the effort is the acceleration; --plant to say otherwise)",
          file=sys.stderr)
    source = {"plant_source": f"{loop.actuation} command (a unit {'mass' if prismatic else 'inertia'})"}
    return ({"mass_kg": 1.0, "damping_n_s_m": 0.0, **source} if prismatic
            else {"inertia_kg_m2": 1.0, "damping_n_m_s_rad": 0.0, **source})


def has_model(hardware) -> bool:
    """Whether the loop's response has a model here (a pid_controller commanding effort or acceleration)."""
    return hardware.loop.has_gains and hardware.loop.actuation in MODELLED


__all__ = ["MODELLED", "PACE_WARNING", "has_model", "loop_plant", "refuse", "say_pace", "served_ros2"]

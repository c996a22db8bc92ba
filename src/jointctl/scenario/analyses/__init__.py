"""Turn a recorded run into metrics and figures, with the theory they are compared to.

A scenario's ``analysis`` names one of :data:`ANALYSES`. Each analysis reads the trace, writes PNG
figures (an SVG beside each) into the output folder and returns the metrics (measured figures plus
an ``expected`` mapping of the same keys computed from the model: moving mass, joint damping,
controller gains, gravity; None, with the reason in ``not_applicable``, where the theory does not
hold). Each experiment's analysis is the module beside it; what they share is
:mod:`jointctl.scenario.analyses.common`. Every analysis ends with ``warnings``
(:mod:`jointctl.scenario.analyses.checks`): figures that miss their expectation or the scenario's
``analysis.spec`` by more than their margin, and joints whose effort sat at its limit.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from jointctl.control.forward_command_controller import ForwardCommandController
from jointctl.control.pid_controller import PidController
from jointctl.control.position_loop import position_loop
from jointctl.errors import ConfigError
from jointctl.trajectory.joint_trajectory_controller import JointTrajectoryController
from jointctl.scenario.analyses.arm import analyse_arm_pose
from jointctl.scenario.analyses.checks import add_warnings, check_spec
from jointctl.scenario.analyses.common import analysed_joint
from jointctl.scenario.analyses.drop_weight import analyse_drop_weight
from jointctl.scenario.analyses.minimal_robot import analyse_minimal_robot_trajectory
from jointctl.scenario.analyses.nac import analyse_nac_drop
from jointctl.scenario.analyses.nac_catch import analyse_nac_catch
from jointctl.scenario.analyses.sine import analyse_sine, analyse_velocity_sine
from jointctl.scenario.analyses.step import analyse_step
from jointctl.scenario.analyses.trajectory import analyse_trajectory_tracking
from jointctl.scenario.session import Session
from jointctl.recording.trace import Trace

#: ros2_controllers' types, which the analyses' loop models do not describe (but a pid_controller's dof that is an
#: effort position loop: :func:`~jointctl.control.position_loop.position_loop`).
ROS2_TYPES = (PidController, ForwardCommandController, JointTrajectoryController)

Analysis = Callable[[Session, Trace, Path, dict[str, Any]], dict[str, Any]]

#: Every analysis a scenario may name: ``type: (function, whether analysis.joint must name a joint)``.
ANALYSES: dict[str, tuple[Analysis, bool]] = {
    "step_response": (analyse_step, True),
    "sine_response": (analyse_sine, True),
    "velocity_sine_response": (analyse_velocity_sine, True),
    "drop_weight": (analyse_drop_weight, True),
    "nac_drop": (analyse_nac_drop, True),
    "nac_catch": (analyse_nac_catch, False),
    "trajectory_tracking": (analyse_trajectory_tracking, True),
    "arm_pose": (analyse_arm_pose, False),
    "minimal_robot_trajectory": (analyse_minimal_robot_trajectory, False),
}


def check_analysis(session: Session) -> Analysis | None:
    """The scenario's analysis function, checked before the run starts; its metrics end with
    ``warnings``."""
    spec = session.scenario.analysis
    if spec is None:
        return None
    entry = ANALYSES.get(spec["type"])
    if entry is None:
        raise ConfigError(f"unknown analysis (known: {', '.join(ANALYSES)})",
                          source=session.scenario.source, field="analysis.type", value=spec["type"])
    analyse, names_a_joint = entry
    if names_a_joint:
        joint = analysed_joint(session, spec)
        controller = session.manager.commanding(joint)
        if isinstance(controller, ROS2_TYPES) and position_loop(controller, joint) is None:
            raise ConfigError(f"the analyses model ros_control's joint controllers and pid_controller's effort "
                              f"position loops; {joint} is commanded by {controller.name!r}, a ROS 2 type that is "
                              "neither (run without an analysis: --set analysis=null, and read the trace)",
                              source=session.scenario.source, field="analysis.joint", value=joint)
    check_spec(session, spec)

    def analyse_and_warn(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
        return add_warnings(session, trace, params, analyse(session, trace, out, params))

    return analyse_and_warn


__all__ = ["ANALYSES", "Analysis", "check_analysis"]

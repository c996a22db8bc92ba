"""A joint's effort position loop as the tuning models read it, whichever controller runs it.

Two controllers close a position loop on a joint's effort, and the tools (the step analysis, identify, bode,
autotune, robust design) model both with one law (:class:`~jointctl.metrics.step_loop.JointLoop`):

- ros_controllers' ``effort_controllers/JointPositionController``
  (:class:`~jointctl.control.joint_controllers.JointPositionController`, ``law`` "ros_control"): the tools read
  it as it is;
- ros2_controllers' ``pid_controller/PidController`` (:class:`~jointctl.control.pid_controller.PidController`,
  ``law`` "control_toolbox"), for a dof it commands through ``command_interface: effort`` while it compares
  ``reference_and_state_interfaces[0]: position`` of the same joint with its reference (the joint's own state,
  not ``use_external_measured_states``): :class:`PidControllerLoop` shows that dof with the names the tools read
  of a JointPositionController (``joint``, ``pid.gains``, ``derivative``, ``effort_limit``, ``set_reference``...).

What differs between the two, and what the view says of the pid_controller:

- the derivative: a plain position reference (a number a cycle: a scenario's command source, the tools' steps and
  sines) carries no ``values_dot``, so control_toolbox differentiates the error, ``(e - e_last)/h``: the
  ``derivative`` is "error", as ros_controllers' law for a plain command (the kick ``d·Δr/h`` on a step);
- the first computation: the PID, configured with a last error of 0, asks ``d·e₀/h`` on its first cycle
  (``kick_on_start``; ros_controllers' first rate is 0);
- the integral: ``i·i_error`` clamped to ``[i_clamp_min, i_clamp_max]`` (or ``i_error`` to them over ``i`` with
  ``antiwindup``): the same term as jointctl's PID with those clamps; with the default clamps 0/0 it is always 0,
  so the gains the models take have ``i`` 0 then (:attr:`LoopGains.i`; ``raw_i`` is the parameter);
- no output limit: the actuator's (the URDF's effort limit, ``effort_limit``) clamps what reaches the joint;
- no feed-forward of the model (``feedforward_terms`` empty; its ``feedforward_gain`` acts on ``values_dot``);
- the gains are ``gains.<dof>.<field>`` of its ROS 2 parameters (:meth:`PidControllerLoop.parameter_path`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from jointctl.control.controller import Controller
from jointctl.control.joint_controllers import DERIVATIVE_ERROR, JointPositionController
from jointctl.control.pid_controller import PidController
from jointctl.hardware.interface import EFFORT, POSITION

#: The ``law`` of each kind of loop (:data:`jointctl.metrics.step_loop.LAWS`).
ROS_CONTROL, CONTROL_TOOLBOX = "ros_control", "control_toolbox"


@dataclass(frozen=True)
class LoopGains:
    """A loop's PID gains with ros_control's names: ``p`` [N/m or N·m/rad], ``i`` (0 when its clamps leave the
    integral nothing), ``d``, the integral term's clamps ``i_clamp_min`` and ``i_clamp_max`` [N or N·m] and
    ``antiwindup``; ``raw_i`` the ``i`` the controller holds."""

    p: float
    i: float
    d: float
    i_clamp_min: float
    i_clamp_max: float
    antiwindup: bool
    raw_i: float


class _ToolboxPidView:
    """``pid`` of :class:`PidControllerLoop`: the dof's gains and its integral term, as JointPositionController's
    :class:`~jointctl.control.pid.Pid` shows them."""

    def __init__(self, controller: PidController, k: int) -> None:
        self._controller, self._k = controller, k

    @property
    def gains(self) -> LoopGains:
        g = self._controller.gains[self._k]
        acts = g.i_clamp_max != 0.0 or g.i_clamp_min != 0.0
        return LoopGains(g.p, g.i if acts else 0.0, g.d, g.i_clamp_min, g.i_clamp_max, g.antiwindup, g.i)

    @property
    def i_state(self) -> float:
        """The integral term [N or N·m]: ``i·i_error``."""
        g = self._controller.gains[self._k]
        return g.i * self._controller.pids[self._k].i_error

    @i_state.setter
    def i_state(self, term: float) -> None:
        g = self._controller.gains[self._k]
        if g.i:
            self._controller.pids[self._k].i_error = float(term) / g.i


class PidControllerLoop:
    """One dof of a :class:`~jointctl.control.pid_controller.PidController` commanding ``joint``'s effort on its
    position, seen as a joint position controller (see the module docstring)."""

    law = CONTROL_TOOLBOX
    derivative = DERIVATIVE_ERROR
    kick_on_start = True
    feedforward_terms: tuple[str, ...] = ()
    controlled = "position"

    def __init__(self, controller: PidController, k: int, effort_limit: float) -> None:
        self.controller = controller
        self.name = controller.name
        self.joint = controller.dof_names[k]
        self.joints = (self.joint,)
        self.dof = k
        self.index = controller.command_index[k]
        self.effort_limit = effort_limit
        self.pid = _ToolboxPidView(controller, k)

    def parameter_path(self, field: str) -> str:
        """The dotted path of the dof's gain ``field`` in the controller's parameters: ``gains.<dof>.<field>``."""
        return f"gains.{self.joint}.{field}"

    @property
    def reference_input(self) -> tuple[float, float, float]:
        """(position reference [m or rad], 0, 0): the one given for the next cycle, else the one in use, else
        (none given yet: the controller commands nothing) where the joint is (the hardware read)."""
        pending = self.controller._pending_reference
        value = pending[0][self.dof] if pending is not None else math.nan
        if value != value:
            value = self.controller.reference[self.dof]
        if value != value:
            hardware = self.controller.hardware
            hardware.read()
            value = hardware.position[self.index]
        return float(value), 0.0, 0.0

    def set_reference(self, position: float) -> None:
        """A plain position reference [m or rad] for this dof (``~/reference`` without ``values_dot``), the
        other dofs' kept (NaN)."""
        values = [math.nan] * len(self.controller.state_dof_names)
        values[self.dof] = position
        self.controller.set_reference(values)


def position_loop(controller: Controller | None, joint: str | None = None):
    """``controller`` as the effort position loop of ``joint`` (default: its only joint): a
    JointPositionController (or a :class:`PidControllerLoop`) as it is, a pid_controller's dof as a
    :class:`PidControllerLoop`; None for anything
    else (a velocity loop, a pid_controller commanding another interface or comparing another state, a forward
    command controller...)."""
    if isinstance(controller, (JointPositionController, PidControllerLoop)):
        return controller if joint in (None, controller.joint) else None
    if not isinstance(controller, PidController) or controller.command_interface != EFFORT:
        return None
    if controller.interfaces[0] != POSITION or controller.use_external_measured_states:
        return None
    if joint is None:
        if len(controller.dof_names) != 1:
            return None
        joint = controller.dof_names[0]
    if joint not in controller.dof_names:
        return None
    k = controller.dof_names.index(joint)
    if controller.state_dof_names[k] != joint or not hasattr(controller, "command_index"):
        return None
    robot = controller.context.robot if controller.context is not None else None
    limits = robot.joint(joint).limits if robot is not None and robot.has_joint(joint) else None
    limit = limits.effort if limits is not None and limits.effort > 0 else math.inf
    return PidControllerLoop(controller, k, limit)


def law_of(loop) -> str:
    """The :class:`~jointctl.metrics.step_loop.JointLoop` ``law`` of a loop :func:`position_loop` gave."""
    return getattr(loop, "law", ROS_CONTROL)


__all__ = ["CONTROL_TOOLBOX", "LoopGains", "PidControllerLoop", "ROS_CONTROL", "law_of", "position_loop"]

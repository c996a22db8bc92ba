"""What controllers of one manager share: per-joint reference interfaces and the model feed-forward.

The *reference interfaces* (ros2_control's word) are the one way into a joint controller: lists
per hardware joint, written by whoever gives the controller of that joint its reference and read
by that controller in its update:

- ``reference_positions`` [m or rad], ``reference_velocities`` [m/s or rad/s] and
  ``reference_accelerations`` [m/s² or rad/s²]: a position controller reads all three (the
  velocity as feed-forward through its derivative, the acceleration through the model's inertia
  feed-forward); a velocity controller reads ``reference_velocities``.

An upstream controller in the same loop (a trajectory executor, an admittance controller) writes
them directly, every cycle, as a chained ros2_control controller writes its downstream's
reference interfaces; an edge (a topic, a command source, the tuning page) goes through the
controller's validating door, ``set_reference``, which writes the same slots.

``references`` holds, per hardware joint, the reference *in use* by the controller commanding
it (after clamping to the joint's range or velocity limit; NaN when no controller commands it):
what the trace records as ``<joint>.reference``. :class:`ModelFeedforward` computes gravity and
inertia efforts of the robot model once per cycle for every joint.
"""

from __future__ import annotations

import math

import numpy as np

from jointctl.hardware.interface import HardwareInterface
from jointctl.model.dynamics import RobotDynamics
from jointctl.model.robot_model import RobotModel


class ModelFeedforward:
    """Gravity ``g(q)`` and inertia ``M(q)·q̈_ref`` efforts at the measured ``q``, for every joint.

    The manager runs :meth:`update` once per cycle, right before the first controller that uses
    it (so after upstream controllers have written this cycle's reference accelerations); the
    controllers then read ``gravity`` and ``inertia`` (lists per hardware joint, N or N·m).
    """

    def __init__(self, context: ControlContext) -> None:
        self.context = context
        self.dynamics = RobotDynamics(context.robot, context.gravity_m_s2)
        hw_names = context.hardware.joint_names
        self._to_model = np.array([self.dynamics.joint_names.index(n) for n in hw_names], dtype=int)
        self._q = np.zeros(len(self.dynamics.joint_names))
        self._qdd = np.zeros(len(self.dynamics.joint_names))
        self.gravity = [0.0] * len(hw_names)
        self.inertia = [0.0] * len(hw_names)
        self.wants_inertia = False
        self._same_order = np.array_equal(self._to_model, np.arange(len(self._to_model))) and \
            len(self._to_model) == len(self.dynamics.joint_names)

    def update(self, time_s: float, period_s: float) -> None:
        dynamics, context = self.dynamics, self.context
        if self._same_order:  # the usual case: hardware joints are the model's, in its order
            dynamics.set_pose(context.hardware.position, inertia=self.wants_inertia)
            self.gravity = dynamics.gravity_at_pose().tolist()
            if self.wants_inertia:
                self.inertia = dynamics.inertia_at_pose(context.reference_accelerations).tolist()
            return
        self._q[self._to_model] = context.hardware.position
        dynamics.set_pose(self._q, inertia=self.wants_inertia)
        self.gravity = dynamics.gravity_at_pose()[self._to_model].tolist()
        if self.wants_inertia:
            self._qdd[self._to_model] = context.reference_accelerations
            self.inertia = dynamics.inertia_at_pose(self._qdd)[self._to_model].tolist()


class ControlContext:
    """Shared by the controllers of one :class:`~jointctl.control.manager.ControllerManager`."""

    def __init__(self, hardware: HardwareInterface, robot: RobotModel,
                 gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)) -> None:
        self.hardware = hardware
        self.robot = robot
        self.gravity_m_s2 = tuple(gravity_m_s2)
        n = len(hardware.joint_names)
        self.references: list[float] = [math.nan] * n
        self.reference_positions: list[float] = [0.0] * n
        self.reference_velocities: list[float] = [0.0] * n
        self.reference_accelerations: list[float] = [0.0] * n
        self._feedforward: ModelFeedforward | None = None

    def set_gravity(self, gravity_m_s2: tuple[float, float, float]) -> None:
        """The gravity the model feed-forward compensates [m/s², world frame], from the next cycle."""
        self.gravity_m_s2 = tuple(float(g) for g in gravity_m_s2)
        if self._feedforward is not None:
            self._feedforward.dynamics.set_gravity(self.gravity_m_s2)

    @property
    def has_feedforward(self) -> bool:
        """Whether the model feed-forward has been built."""
        return self._feedforward is not None

    @property
    def feedforward(self) -> ModelFeedforward:
        """The model feed-forward, built on first use (it compiles the robot's dynamics model)."""
        if self._feedforward is None:
            self._feedforward = ModelFeedforward(self)
        return self._feedforward

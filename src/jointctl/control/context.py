"""What controllers of one manager share: per-joint references and the model feed-forward.

``references`` holds, per hardware joint, the reference in use by the
controller commanding it (a position or a velocity); ``acceleration_references``
the acceleration that comes with a position reference (from a trajectory),
used by the inertia feed-forward. :class:`ModelFeedforward` computes gravity
and inertia efforts of the robot model once per cycle for every joint.
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
    it (so after upstream controllers have set this cycle's acceleration references); the
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
                self.inertia = dynamics.inertia_at_pose(context.acceleration_references).tolist()
            return
        self._q[self._to_model] = context.hardware.position
        dynamics.set_pose(self._q, inertia=self.wants_inertia)
        self.gravity = dynamics.gravity_at_pose()[self._to_model].tolist()
        if self.wants_inertia:
            self._qdd[self._to_model] = context.acceleration_references
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
        self.acceleration_references: list[float] = [0.0] * n
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

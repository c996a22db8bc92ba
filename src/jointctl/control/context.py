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
from jointctl.model.robot_model import RobotModel


class ModelFeedforward:
    """Gravity ``g(q)`` and inertia ``M(q)·q̈_ref`` efforts at the measured ``q``, computed at
    most once per cycle (one pose computation shared by both)."""

    def __init__(self, context: ControlContext) -> None:
        from jointctl.sim.dynamics import RobotDynamics  # the model's dynamics, not the simulated world

        self.context = context
        self.dynamics = RobotDynamics(context.robot, context.gravity_m_s2)
        hw_names = context.hardware.joint_names
        self._to_model = np.array([self.dynamics.joint_names.index(n) for n in hw_names], dtype=int)
        self._q = np.zeros(len(self.dynamics.joint_names))
        self._qdd = np.zeros(len(self.dynamics.joint_names))
        self._pose_time = self._gravity_time = self._inertia_time = math.nan
        self._gravity = [0.0] * len(hw_names)
        self._inertia = [0.0] * len(hw_names)

    def _pose(self, time_s: float) -> None:
        if time_s != self._pose_time:
            self._q[self._to_model] = self.context.hardware.position
            self.dynamics.set_pose(self._q)
            self._pose_time = time_s

    def gravity(self, time_s: float) -> list[float]:
        """Per hardware joint, the effort [N or N·m] that holds the measured pose against gravity."""
        if time_s != self._gravity_time:
            self._pose(time_s)
            self._gravity = self.dynamics.gravity_at_pose()[self._to_model].tolist()
            self._gravity_time = time_s
        return self._gravity

    def inertia(self, time_s: float) -> list[float]:
        """Per hardware joint, ``M(q)·q̈_ref`` [N or N·m] for the acceleration references."""
        if time_s != self._inertia_time:
            self._pose(time_s)
            self._qdd[self._to_model] = self.context.acceleration_references
            self._inertia = self.dynamics.inertia_at_pose(self._qdd)[self._to_model].tolist()
            self._inertia_time = time_s
        return self._inertia


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

    @property
    def feedforward(self) -> ModelFeedforward:
        """The model feed-forward, built on first use (it compiles the robot's dynamics model)."""
        if self._feedforward is None:
            self._feedforward = ModelFeedforward(self)
        return self._feedforward

"""Natural admittance control of one joint (chapter 11.4), chained to a velocity controller.

The controller makes the joint behave like a virtual mass-spring-damper
(mass ``M``, stiffness ``K``, damping ``B``, rest point ``attractor``) pushed by
the force measured at the robot's force-torque sensor. Each cycle::

    f = K·(x_att - x) - B·v + F_sensed
    v_ref += f / M · dt,   clamped to ±max_velocity
    velocity_controller's reference = v_ref

At rest ``x = x_att + F/K``. Units: m, m/s, N, kg, N/m, N·s/m for a prismatic
joint (rad, N·m... for a revolute one).

Two optional rates model a controller that runs outside the loop and is fed over topics, as the
chapter's ``nac_controller`` node is: ``joint_state_rate_hz`` samples position *and* velocity (one
``sensor_msgs/JointState`` message carries both) at that rate and holds them in between;
``force_rate_hz`` does the same for the sensed force (one ``geometry_msgs/WrenchStamped``). The
integration of ``v_ref`` and the command stay at the loop rate either way, as in the node. The
chapter's setup is ``joint_state_rate_hz: 50`` (the joint state controller's ``publish_rate``) with
the force fresh every cycle (the sensor plugin's ``updateRate`` is 1000); both at 50 Hz is the
fully stale case. Unset, a signal is read every cycle.
"""

from __future__ import annotations


from jointctl.control.controller import Controller
from jointctl.control.joint_controllers import JointVelocityController
from jointctl.control.params import Params
from jointctl.errors import ConfigError
from jointctl.hardware.interface import HardwareInterface
from jointctl.model.robot_model import RobotModel
from jointctl.validate import finite_number

_AXES = {"x": 0, "y": 1, "z": 2}


class AdmittanceController(Controller):
    """Turns sensed force into a velocity reference for ``velocity_controller``."""

    def __init__(self, name: str, params: Params) -> None:
        super().__init__(name, params)
        self.joint = params.string("joint")
        self.joints = ()  # it commands a controller, not a joint's hardware interface
        self.sensor = params.string("sensor")
        axis = params.string("force_axis", "z")
        if axis not in _AXES:
            raise params.error("must be x, y or z", "force_axis", axis)
        self.force_index = _AXES[axis]
        self.velocity_controller = params.string("velocity_controller")
        self.downstream = (self.velocity_controller,)
        self.mass = params.number("mass", positive=True)
        self.stiffness = params.number("stiffness", minimum=0)
        self.damping = params.number("damping", minimum=0)
        self.attractor = params.number("attractor")
        self.max_velocity = params.number("max_velocity", positive=True)
        self.joint_state_rate_hz = params.number("joint_state_rate_hz", None, positive=True)
        self.force_rate_hz = params.number("force_rate_hz", None, positive=True)
        params.reject_unknown({"type"})
        self.velocity_reference = 0.0

    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        return ((self.velocity_controller, "reference"),)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        self.index = hardware.joint_index(self.joint, source=self.source, field=f"{self.field}.joint")
        if self.sensor not in hardware.sensor_names:
            known = ", ".join(hardware.sensor_names) or "none"
            raise ConfigError(f"no force-torque sensor of that name (sensors: {known})",
                              source=self.source, field=f"{self.field}.sensor", value=self.sensor)
        limits = robot.joint(self.joint).limits
        if limits is not None and limits.lower is not None and not limits.lower <= self.attractor <= limits.upper:
            raise ConfigError(f"outside the joint's range [{limits.lower}, {limits.upper}]",
                              source=self.source, field=f"{self.field}.attractor", value=self.attractor)
        self.hardware = hardware
        self.wrench = hardware.wrenches[self.sensor]
        self.joint_state_period_s = 1.0 / self.joint_state_rate_hz if self.joint_state_rate_hz else 0.0
        self.force_period_s = 1.0 / self.force_rate_hz if self.force_rate_hz else 0.0

    def bind_downstream(self, controllers: dict[str, Controller]) -> None:
        """Receive the velocity controller this controller commands."""
        target = controllers[self.velocity_controller]
        if not isinstance(target, JointVelocityController) or target.joints != (self.joint,):
            raise ConfigError("must name a velocity controller of the same joint", source=self.source,
                              field=f"{self.field}.velocity_controller", value=self.velocity_controller)
        self.target = target
        # Its reference interface (chained mode): written in place every cycle.
        self._velocities, self._target_index = target.context.reference_velocities, target.index

    def set_gains(self, *, mass: float | None = None, stiffness: float | None = None,
                  damping: float | None = None) -> None:
        """Change M, K or B while running (validated; applied at the next cycle)."""
        changes = {}
        for name, value, positive in (("mass", mass, True), ("stiffness", stiffness, False),
                                      ("damping", damping, False)):
            if value is None:
                continue
            number = finite_number(value)
            if number is None or number < 0 or (positive and number == 0):
                raise ConfigError("must be a finite number" + (" above zero" if positive else " >= 0"),
                                  source=self.name, field=name, value=value)
            changes[name] = float(value)
        for name, value in changes.items():  # all or nothing
            setattr(self, name, value)

    def start(self, time_s: float) -> None:
        self.hardware.read()
        self.velocity_reference = 0.0
        self._next_joint_state_s = self._next_force_s = time_s
        self._sample(time_s)

    def _sample(self, time_s: float) -> None:
        """Take the signals that are due (every cycle for those without a rate); hold the others."""
        if time_s + 1e-9 >= self._next_joint_state_s:
            hw, i = self.hardware, self.index
            self.position, self.velocity = hw.position[i], hw.velocity[i]
            self._next_joint_state_s += self.joint_state_period_s
        if time_s + 1e-9 >= self._next_force_s:
            self.force = self.wrench[self.force_index]
            self._next_force_s += self.force_period_s

    def update(self, time_s: float, period_s: float) -> None:
        self._sample(time_s)
        f = self.stiffness * (self.attractor - self.position) - self.damping * self.velocity + self.force
        v_ref = self.velocity_reference + f / self.mass * period_s
        limit = self.max_velocity
        v_ref = limit if v_ref > limit else -limit if v_ref < -limit else v_ref
        self.velocity_reference = v_ref
        self._velocities[self._target_index] = v_ref

"""A command source against the limits of the joint controller it feeds.

A joint position controller clamps its reference to the joint's range (the URDF's ``<limit lower upper>``), as
ros_control's ``effort_controllers/JointPositionController`` does (``enforceJointLimits``); a joint velocity
controller clamps its reference to the joint's speed limit (``<limit velocity>``). Neither happens silently:

- :func:`check_within_limits`: a source whose values are known before it runs (a constant, a step, a sine) and
  would be clamped is refused, a :class:`~jointctl.errors.ConfigError` naming the source's key, its value and
  the limit;
- :func:`clamp_warning`: a reference the controller clamped as the run went (an expression's, an edge's) is a
  sentence naming the furthest value, the limit and how long.

Units: m and m/s for a prismatic joint, rad and rad/s otherwise.
"""

from __future__ import annotations

from jointctl.commands.sources import CommandSource
from jointctl.control.joint_controllers import JointPositionController, JointVelocityController
from jointctl.errors import ConfigError
from jointctl.model.robot_model import RobotModel


def reference_limits(controller, robot: RobotModel) -> tuple[float, float, str, str] | None:
    """(lowest and highest reference the controller passes unclamped, the name of that range with its unit
    ("joint1's range [-1, 0] m"), the unit), or None for a controller that clamps no reference."""
    if not isinstance(controller, (JointPositionController, JointVelocityController)):
        return None
    unit = "m" if robot.joint(controller.joint).is_prismatic else "rad"
    if isinstance(controller, JointPositionController):
        low, high = controller.lower, controller.upper
        return low, high, f"{controller.joint}'s range [{low:g}, {high:g}] {unit}", unit
    limit, unit = controller.velocity_limit, f"{unit}/s"
    return -limit, limit, f"{controller.joint}'s speed limit ±{limit:g} {unit}", unit


def check_within_limits(source: CommandSource, controller, robot: RobotModel, *, field: str,
                        source_file: str | None) -> None:
    """Refuse ``source`` when one of its :meth:`~jointctl.commands.sources.CommandSource.extremes` lies outside
    what ``controller`` passes unclamped: a ConfigError naming ``field.<key>`` and the value."""
    limits = reference_limits(controller, robot)
    if limits is None:
        return
    low, high, described, unit = limits
    for key, value in source.extremes():
        if not low <= value <= high:
            clamped = min(max(value, low), high)
            raise ConfigError(f"outside {described}: {controller.name} would clamp it to {clamped:g} {unit}",
                              source=source_file, field=f"{field}.{key}", value=value)


def clamp_warning(controller, robot: RobotModel, period_s: float) -> str | None:
    """The sentence saying that ``controller`` clamped its reference during the run (None if it never did): in
    how many cycles (and seconds at the loop's ``period_s``), the furthest reference and the limit."""
    cycles = getattr(controller, "clamped_cycles", 0)
    limits = reference_limits(controller, robot)
    if not cycles or limits is None:
        return None
    _, _, described, unit = limits
    return (f"{controller.name}: its reference reached {controller.clamped_furthest:g} {unit}, outside "
            f"{described}, and was clamped to it in {cycles} cycles ({cycles * period_s:.3g} s), as "
            "ros_control's controllers do")


__all__ = ["check_within_limits", "clamp_warning", "reference_limits"]

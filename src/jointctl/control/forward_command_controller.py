"""``forward_command_controller/ForwardCommandController`` and ``effort_controllers/JointGroupEffortController``:
ros2_controllers' controllers that write the values they are given, one per joint, every cycle.

Parameters (``ros__parameters``)::

    effort_controller:
      ros__parameters:
        joints: [joint1, joint2]
        interface_name: effort        # ForwardCommandController only; JointGroupEffortController's is effort

As ros2_controllers 4.18: until the first command nothing is written (the hardware keeps what it has);
then the last command is written every cycle; starting again forgets it. JointGroupEffortController
writes 0 to its joints when it stops. The door is :meth:`ForwardCommandController.set_commands` (the
``~/commands`` topic, std_msgs/Float64MultiArray): one finite number per joint, in ``joints`` order
[the interface's unit: N or N·m for effort], taken at the start of the next cycle. Where the ROS 2
controller errors in its update on a wrong-sized message (and passes NaN on), the door refuses the
command at once with :class:`~jointctl.errors.InvalidCommand` and the last command stays.
"""

from __future__ import annotations

from collections.abc import Sequence

from jointctl.control.controller import Controller
from jointctl.control.params import Params
from jointctl.control.pid_controller import string_list
from jointctl.errors import ConfigError, InvalidCommand
from jointctl.hardware.interface import EFFORT, HardwareInterface
from jointctl.model.robot_model import RobotModel
from jointctl.validate import finite_number


class ForwardCommandController(Controller):
    """Writes the commands it is given to ``interface_name`` of each of ``joints``."""

    #: The interface a subclass fixes (JointGroupEffortController's effort), or None to read ``interface_name``.
    fixed_interface: str | None = None

    def __init__(self, name: str, params: Params) -> None:
        super().__init__(name, params)
        self.joints = string_list(params, "joints", required=True)
        if self.fixed_interface is None:
            self.interface_name = params.string("interface_name")
        else:
            self.interface_name = params.string("interface_name", self.fixed_interface)
            if self.interface_name != self.fixed_interface:
                raise params.error(f"is {self.fixed_interface} for this controller type", "interface_name",
                                   self.interface_name)
        params.reject_unknown({"type"})
        #: The commands in force (None before the first): one value per joint, in ``joints`` order.
        self.commands: tuple[float, ...] | None = None

    def claimed_interfaces(self) -> tuple[tuple[str, str], ...]:
        return tuple((joint, self.interface_name) for joint in self.joints)

    def configure(self, hardware: HardwareInterface, robot: RobotModel) -> None:
        self.index = [hardware.joint_index(j, source=self.source, field=f"{self.field}.joints[{k}]")
                      for k, j in enumerate(self.joints)]
        for joint in self.joints:
            offered = hardware.command_interfaces(joint)
            if self.interface_name not in offered:
                raise ConfigError(f"joint {joint!r} has no {self.interface_name} command interface on this hardware "
                                  f"(it has: {', '.join(sorted(offered)) or 'none'})", source=self.source,
                                  field=f"{self.field}.interface_name", value=self.interface_name)
        self.buffer = hardware.command_buffer(self.interface_name)

    def set_commands(self, values: Sequence[float]) -> None:
        """The ``~/commands`` door: one finite number per joint, in ``joints`` order; written from the next cycle
        on until the next command. InvalidCommand (nothing changed) for a wrong count or a value that is not a
        finite number."""
        values = list(values)
        if len(values) != len(self.joints):
            raise InvalidCommand(f"needs {len(self.joints)} values, one per joint ({', '.join(self.joints)})",
                                 source=self.name, field="commands", value=values)
        checked = []
        for k, value in enumerate(values):
            number = finite_number(value)
            if number is None:
                raise InvalidCommand("must be a finite number", source=self.name,
                                     field=f"commands[{self.joints[k]}]", value=value)
            checked.append(number)
        self.commands = tuple(checked)

    def set_reference(self, value: float) -> None:
        """A scalar command source's door (a scenario's ``commands``): the same value for every joint."""
        self.set_commands([value] * len(self.joints))

    def start(self, time_s: float) -> None:
        self.commands = None

    def update(self, time_s: float, period_s: float) -> None:
        commands = self.commands
        if commands is None:
            return
        buffer = self.buffer
        for i, value in zip(self.index, commands):
            buffer[i] = value


class JointGroupEffortController(ForwardCommandController):
    """``effort_controllers/JointGroupEffortController``: the effort interface; 0 N (N·m) written when it stops."""

    fixed_interface = EFFORT

    def stop(self, time_s: float) -> None:
        for i in self.index:
            self.buffer[i] = 0.0
        self.commands = None


__all__ = ["ForwardCommandController", "JointGroupEffortController"]

"""The handles a controller is loaned at configure time, as ros2_control loans interfaces.

A :class:`HardwareLoan` shows one controller the hardware's state handles (the ``position``,
``velocity`` and ``effort`` lists and the sensors' ``wrenches``: the hardware's own lists, updated
in place every cycle, so a controller may keep them and index them in the loop) and hands out
command lists only for the interfaces the controller claimed: asking for another is refused at
configure, with a :class:`~jointctl.errors.ConfigError` naming the controller and the interface.
"""

from __future__ import annotations

from collections.abc import Iterable

from jointctl.errors import ConfigError
from jointctl.hardware.interface import HardwareInterface


class HardwareLoan:
    """One controller's view of ``hardware``: every state handle, the command handles it claimed."""

    def __init__(self, hardware: HardwareInterface, claims: Iterable[tuple[str, str]], *, borrower: str,
                 source: str | None = None) -> None:
        self._hardware = hardware
        self._claimed_interfaces = frozenset(interface for _, interface in claims)
        self.borrower = borrower
        self._source = source
        self.joint_names = hardware.joint_names
        self.sensor_names = hardware.sensor_names
        self.position = hardware.position
        self.velocity = hardware.velocity
        self.effort = hardware.effort
        self.wrenches = hardware.wrenches

    @property
    def fault(self) -> str | None:
        """Why the hardware cannot be commanded now, or None (see ``HardwareInterface.fault``)."""
        return self._hardware.fault

    def joint_index(self, name: str, *, source: str | None = None, field: str = "joint") -> int:
        return self._hardware.joint_index(name, source=source, field=field)

    def command_interfaces(self, joint: str) -> frozenset[str]:
        return self._hardware.command_interfaces(joint)

    def command_buffer(self, interface: str) -> list[float]:
        """The command list of ``interface`` (one entry per joint), if the controller claimed it."""
        if interface not in self._claimed_interfaces:
            raise ConfigError(f"asks for the {interface} command handles but claims no {interface} interface "
                              f"(claims: {', '.join(sorted(self._claimed_interfaces)) or 'none'})",
                              source=self._source, field=self.borrower, value=interface)
        return self._hardware.command_buffer(interface)

    @property
    def in_motion(self) -> bool | None:
        """The hardware's own word on whether the robot moves, or None (see ``HardwareInterface.in_motion``)."""
        return self._hardware.in_motion

    @property
    def takes_trajectories(self) -> bool:
        """Whether the hardware executes whole trajectories (see ``HardwareInterface.execute_trajectory``)."""
        return self._hardware.takes_trajectories

    @property
    def trajectory_sample_period_s(self) -> float | None:
        """None: the hardware takes a goal's own points; else the period to sample a goal at [s]."""
        return self._hardware.trajectory_sample_period_s

    @property
    def executing(self) -> bool:
        """Whether a trajectory handed to the hardware is still being sent or executed."""
        return self._hardware.executing

    def execute_trajectory(self, joint_indices, times_s, positions, velocities=None, accelerations=None) -> None:
        """Execute a trajectory by the hardware's own means (see ``HardwareInterface.execute_trajectory``)."""
        self._hardware.execute_trajectory(joint_indices, times_s, positions, velocities, accelerations)

    def stop_motion(self) -> None:
        """Bring the joints to rest by the hardware's own means (see ``HardwareInterface.stop_motion``)."""
        self._hardware.stop_motion()

    def read(self) -> None:
        """Refresh the state handles now (a controller starting between cycles wants the present)."""
        self._hardware.read()

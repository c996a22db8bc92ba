"""The MuJoCo world as a :class:`HardwareInterface`.

Every actuated joint takes effort commands (its transmission's
EffortJointInterface); the effort reported is MuJoCo's actuator force, i.e.
the command after the actuator's force limit. Wrenches follow the chapter's
(Gazebo ft_sensor) convention: the force and torque the sensor link's subtree
exerts on its parent, in the sensor link's frame, so a load resting on the
1-DOF robot's disk reads negative force z.
"""

from __future__ import annotations

import numpy as np
from mujoco import mj_step

from jointctl.errors import ConfigError
from jointctl.hardware.interface import EFFORT, HardwareInterface
from jointctl.sim.world import MujocoWorld


class MujocoHardware(HardwareInterface):
    """Joint handles backed by one :class:`~jointctl.sim.world.MujocoWorld`."""

    def __init__(self, world: MujocoWorld) -> None:
        super().__init__(world.joint_names, tuple(s.name for s in world.robot.sensors))
        self.world = world
        d = world.data
        # Cached numpy views; a slice when the addresses are consecutive (the usual case).
        self._qpos = _view(d.qpos, world.qpos_adr, world)
        self._qvel = _view(d.qvel, world.dof_adr, world)
        actuated = world.actuator_ids >= 0
        self._actuated = frozenset(n for n, a in zip(world.joint_names, actuated) if a)
        self._all_actuated = bool(actuated.all())
        act_ids = world.actuator_ids[actuated]
        self._act_joint_idx = np.flatnonzero(actuated)
        self._force = _view(d.actuator_force, act_ids, world)
        self._ctrl_ids = act_ids
        self._ctrl_slice = world.contiguous(act_ids) if self._all_actuated else None
        self._effort_cmd = self.command_buffer(EFFORT)
        self._sensordata = world.data.sensordata
        self._sensor_slots = tuple(
            (self.wrenches[name], *world.sensor_adr(name)) for name in self.sensor_names
        )
        self._model, self._data = world.model, world.data
        self._period_s, self._nstep = world.timestep_s, 1

    def command_interfaces(self, joint: str) -> frozenset[str]:
        return frozenset({EFFORT}) if joint in self._actuated else frozenset()

    def read(self) -> None:
        self.position = self._qpos().tolist()
        self.velocity = self._qvel().tolist()
        force = self._force().tolist()
        if self._all_actuated:
            self.effort = force
        else:
            effort = [0.0] * len(self.joint_names)
            for k, f in zip(self._act_joint_idx, force):
                effort[k] = f
            self.effort = effort
        if self._sensor_slots:
            data = self._sensordata.tolist()
            for w, f, t in self._sensor_slots:
                w[0], w[1], w[2] = -data[f], -data[f + 1], -data[f + 2]
                w[3], w[4], w[5] = -data[t], -data[t + 1], -data[t + 2]

    def write(self) -> None:
        ctrl = self.world.data.ctrl
        if self._ctrl_slice is not None:
            ctrl[self._ctrl_slice] = self._effort_cmd
        else:
            cmd = self._effort_cmd
            for k, act in zip(self._act_joint_idx, self._ctrl_ids):
                ctrl[act] = cmd[k]

    def advance(self, period_s: float) -> None:
        if period_s != self._period_s:
            self._nstep = _steps(period_s, self.world.timestep_s)
            self._period_s = period_s
        mj_step(self._model, self._data, self._nstep)

    def reset(self) -> None:
        self.world.reset()
        for buf in self._commands.values():
            buf[:] = [0.0] * len(buf)
        self.read()


def _steps(period_s: float, timestep_s: float) -> int:
    steps = round(period_s / timestep_s)
    if steps < 1 or abs(steps * timestep_s - period_s) > 1e-9 * max(1.0, period_s):
        raise ConfigError(
            f"the control period must be a whole number of physics steps of {timestep_s} s",
            field="period_s", value=period_s,
        )
    return steps


def _view(array: np.ndarray, adr: np.ndarray, world: MujocoWorld):
    """A zero-argument function returning ``array[adr]`` as cheaply as possible."""
    sl = world.contiguous(adr)
    if sl is not None:
        view = array[sl]
        return lambda: view
    idx = np.asarray(adr, dtype=int)
    return lambda: array[idx]

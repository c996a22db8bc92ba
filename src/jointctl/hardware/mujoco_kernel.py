"""The compiled form of :class:`~jointctl.hardware.mujoco_hardware.MujocoHardware`: its ``read``, ``write`` and
``advance`` on the world's MjData arrays, with ``mj_step`` called in C (MuJoCo's own library, the one the
``mujoco`` wheel ships).

The joints' handles (position, velocity, effort, command) and the sensors' wrenches are arrays while a compiled
stretch runs; :class:`MujocoArrays` makes them from the hardware and puts them back into its lists. Warnings are
read every ``WARNING_CHECK_CYCLES`` cycles as the Python ``advance`` reads them: a new one ends the stretch at
that cycle and :meth:`~jointctl.hardware.mujoco_hardware.MujocoHardware._check_warnings` raises it.

One difference from the Python path: an *error* of MuJoCo's (not a warning: an invalid model or an exhausted
arena) inside a compiled stretch ends the process with MuJoCo's message instead of raising ``mujoco.FatalError``;
a scenario's ``loop: python`` runs it where that matters.
"""

from __future__ import annotations

import numpy as np

from jointctl.hardware.mujoco_hardware import MujocoHardware
from jointctl.jit import kernel
from jointctl.model.mujoco_functions_kernel import mj_step

#: The hardware's integer state: cycles to the next warning check, and the check's period.
UNTIL_CHECK, CHECK_EVERY = range(2)


class MujocoArrays:
    """The arrays the compiled cycle works on for ``hardware`` (its world's current MjData)."""

    def __init__(self, hardware: MujocoHardware, period_s: float) -> None:
        from jointctl.hardware.mujoco_hardware import WARNING_CHECK_CYCLES
        from jointctl.sim.steps import physics_steps

        self.hardware = hardware
        world = hardware.world
        m, d = hardware._model, hardware._data
        self.model_address, self.data_address = m._address, d._address
        if period_s != hardware._period_s:  # as advance() does when the period changes
            hardware._nstep = physics_steps(period_s, world.timestep_s)
            hardware._period_s = period_s
        self.nstep = hardware._nstep
        self.qpos, self.qvel, self.actuator_force, self.ctrl = d.qpos, d.qvel, d.actuator_force, d.ctrl
        self.sensordata = d.sensordata
        self.warnings = d.warning.number  # a view into MjData (each warning's count)
        n = len(hardware.joint_names)
        self.qpos_adr = np.asarray(world.qpos_adr, dtype=np.int64)
        self.dof_adr = np.asarray(world.dof_adr, dtype=np.int64)
        self.actuator = np.full(n, -1, dtype=np.int64)
        self.reduction = np.ones(n)
        for k, act, red in zip(hardware._act_joint_idx, hardware._ctrl_ids, hardware._reduction):
            self.actuator[k], self.reduction[k] = act, red
        self.sensors = np.array([[f, t] for _, f, t in hardware._sensor_slots], dtype=np.int64).reshape(-1, 2)
        self.position = np.array(hardware.position, dtype=float)
        self.velocity = np.array(hardware.velocity, dtype=float)
        self.effort = np.array(hardware.effort, dtype=float)
        self.wrench = np.array([hardware.wrenches[s] for s in hardware.sensor_names], dtype=float).reshape(-1, 6)
        self.command = np.array(hardware._effort_cmd, dtype=float)
        self.counters = np.array([hardware._until_warning_check, WARNING_CHECK_CYCLES], dtype=np.int64)
        self.warnings_seen = np.array(hardware._warnings_seen, dtype=np.int64)

    def unpack(self) -> None:
        """Put the handles, the commands and the warning bookkeeping back into the hardware."""
        hw = self.hardware
        hw.position[:] = self.position.tolist()
        hw.velocity[:] = self.velocity.tolist()
        hw.effort[:] = self.effort.tolist()
        for name, row in zip(hw.sensor_names, self.wrench.tolist()):
            hw.wrenches[name][:] = row
        hw._effort_cmd[:] = self.command.tolist()
        hw._until_warning_check = int(self.counters[UNTIL_CHECK])
        hw._warnings_seen = self.warnings_seen.tolist()


@kernel
def mujoco_read(qpos, qvel, actuator_force, sensordata, qpos_adr, dof_adr, actuator, reduction, sensors,
                position, velocity, effort, wrench):
    """``MujocoHardware.read``: joint state and the force-torque sensors' wrenches (negated: the chapter's sign)."""
    for j in range(position.shape[0]):
        position[j] = qpos[qpos_adr[j]]
        velocity[j] = qvel[dof_adr[j]]
        a = actuator[j]
        if a >= 0:
            effort[j] = actuator_force[a] * reduction[j]
    for s in range(sensors.shape[0]):
        f, t = sensors[s, 0], sensors[s, 1]
        for axis in range(3):
            wrench[s, axis] = -sensordata[f + axis]
            wrench[s, 3 + axis] = -sensordata[t + axis]


@kernel
def mujoco_write(ctrl, actuator, reduction, command):
    """``MujocoHardware.write``: each actuated joint's effort command to its actuator (through its reduction)."""
    for j in range(command.shape[0]):
        a = actuator[j]
        if a >= 0:
            ctrl[a] = command[j] / reduction[j]


@kernel
def mujoco_advance(model_address, data_address, nstep, warnings, counters, warnings_seen):
    """``MujocoHardware.advance``: ``nstep`` physics steps; True when a warning check finds a new warning (the
    seen counts are then left for the Python check to compare and raise)."""
    for _ in range(nstep):
        mj_step(model_address, data_address)
    counters[UNTIL_CHECK] -= 1
    if counters[UNTIL_CHECK] != 0:
        return False
    counters[UNTIL_CHECK] = counters[CHECK_EVERY]
    for k in range(warnings.shape[0]):
        if warnings[k] > warnings_seen[k]:
            return True
    for k in range(warnings.shape[0]):
        warnings_seen[k] = warnings[k]
    return False

"""The MuJoCo world as a :class:`HardwareInterface`.

Every actuated joint takes effort commands (its transmission's
EffortJointInterface); the effort reported is MuJoCo's actuator force, i.e.
the command after the actuator's force limit. Commands and state are the
joint's, as ros_control's joint-space interfaces: through a transmission's
reduction n (SimpleTransmission) the actuator is commanded joint effort / n
and the joint's effort is n times the actuator's. Wrenches follow the chapter's
(Gazebo ft_sensor) convention: the force and torque the sensor link's subtree
exerts on its parent, in the sensor link's frame, so a load resting on the
1-DOF robot's disk reads negative force z.
"""

from __future__ import annotations

import numpy as np
from mujoco import mj_name2id, mj_objectVelocity, mj_step, mjtObj, mjtWarning

from jointctl.errors import PhysicsError
from jointctl.hardware.interface import EFFORT, HardwareInterface, SimulationDoor
from jointctl.sim.steps import physics_steps
from jointctl.sim.world import MujocoWorld


#: MuJoCo's warnings, by index into ``MjData.warning``.
WARNINGS = {int(getattr(mjtWarning, n)): n for n in dir(mjtWarning) if n.startswith("mjWARN_")}
#: Cycles between reads of the warning counters: a warning ends the run within this many cycles
#: (reading them every cycle would cost about as much as the rest of a 1-DOF cycle's Python).
WARNING_CHECK_CYCLES = 100


class MujocoSimulation(SimulationDoor):
    """The simulation door of a :class:`MujocoHardware`: its world's gravity, objects and poses."""

    def __init__(self, world: MujocoWorld) -> None:
        self._world = world
        self._velocity = np.zeros(6)

    @property
    def gravity_m_s2(self) -> tuple[float, float, float]:
        return self._world.gravity_m_s2

    def set_gravity(self, gravity_m_s2: tuple[float, float, float]) -> None:
        self._world.set_gravity(gravity_m_s2)

    @property
    def floor(self) -> bool:
        return bool(self._world.settings.floor)

    @property
    def spawned(self) -> tuple:
        return tuple(self._world.spawned)

    def has_body(self, name: str) -> bool:
        return self._world.has_body(name)

    def spawn(self, spec) -> None:
        self._world.spawn(spec)

    def remove(self, name: str):
        return self._world.remove(name)

    def remove_spawned(self) -> None:
        self._world.remove_spawned()

    def body_state(self, name: str) -> tuple:
        world = self._world
        position, quaternion = world.body_pose(name)
        body = mj_name2id(world.model, mjtObj.mjOBJ_BODY, name)
        mj_objectVelocity(world.model, world.data, mjtObj.mjOBJ_BODY, body, self._velocity, 0)
        return position, quaternion, self._velocity[:3].copy(), self._velocity[3:].copy()

    @property
    def solver(self) -> dict[str, float]:
        opt = self._world.model.opt
        return {"iterations": int(opt.iterations), "tolerance": float(opt.tolerance)}

    def on_rebuild(self, listener) -> None:
        self._world.on_rebuild(listener)


class MujocoHardware(HardwareInterface):
    """Joint handles backed by one :class:`~jointctl.sim.world.MujocoWorld`."""

    def __init__(self, world: MujocoWorld) -> None:
        super().__init__(world.joint_names, tuple(s.name for s in world.robot.sensors))
        self.world = world
        self.simulation = MujocoSimulation(world)
        self._effort_cmd = self.command_buffer(EFFORT)
        self._bind()
        world.on_rebuild(self._bind)

    def _bind(self) -> None:
        """Resolve addresses and cache views into the world's current MjData."""
        world = self.world
        d = world.data
        actuated = world.actuator_ids >= 0
        self._actuated = frozenset(n for n, a in zip(world.joint_names, actuated) if a)
        self._act_joint_idx = np.flatnonzero(actuated)
        self._ctrl_ids = world.actuator_ids[actuated]
        # Each actuator's transmission reduction n: joint effort = n · actuator effort (SimpleTransmission).
        self._reduction = np.array([world.robot.transmission_for(world.joint_names[k]).mechanical_reduction
                                    for k in self._act_joint_idx], dtype=float)
        geared = bool(np.any(self._reduction != 1.0))
        qpos_sl, qvel_sl = world.contiguous(world.qpos_adr), world.contiguous(world.dof_adr)
        ctrl_sl = world.contiguous(self._ctrl_ids) if actuated.all() else None
        if qpos_sl is not None and qvel_sl is not None and ctrl_sl is not None and not geared:
            # The usual case: cached numpy views, one tolist() per quantity per cycle.
            self._qpos_view, self._qvel_view = d.qpos[qpos_sl], d.qvel[qvel_sl]
            self._force_view, self._ctrl_view = d.actuator_force[ctrl_sl], d.ctrl[ctrl_sl]
            self.read, self.write = self._read_contiguous, self._write_contiguous
        else:
            self.read, self.write = self._read_indexed, self._write_indexed
        self._sensordata = world.data.sensordata
        self._sensor_slots = tuple(
            (self.wrenches[name], *world.sensor_adr(name)) for name in self.sensor_names
        )
        self._model, self._data = world.model, world.data
        self._period_s, self._nstep = world.timestep_s, 1
        self._until_warning_check = WARNING_CHECK_CYCLES
        self._warnings_seen = [world.data.warning[k].number for k in range(len(world.data.warning))]
        self.write()  # carry the current commands into a freshly bound MjData

    def command_interfaces(self, joint: str) -> frozenset[str]:
        return frozenset({EFFORT}) if joint in self._actuated else frozenset()

    def read(self) -> None:  # replaced per instance by the fastest fitting variant
        raise NotImplementedError

    def write(self) -> None:  # replaced per instance by the fastest fitting variant
        raise NotImplementedError

    # State lists are updated in place: they are the stable handles controllers were loaned.
    def _read_contiguous(self) -> None:
        self.position[:] = self._qpos_view.tolist()
        self.velocity[:] = self._qvel_view.tolist()
        self.effort[:] = self._force_view.tolist()
        if self._sensor_slots:
            self._read_sensors()

    def _write_contiguous(self) -> None:
        self._ctrl_view[:] = self._effort_cmd

    def _read_indexed(self) -> None:
        d = self.world.data
        self.position[:] = d.qpos[self.world.qpos_adr].tolist()
        self.velocity[:] = d.qvel[self.world.dof_adr].tolist()
        effort = self.effort
        for k, act, n in zip(self._act_joint_idx, self._ctrl_ids, self._reduction):
            effort[k] = float(d.actuator_force[act] * n)
        if self._sensor_slots:
            self._read_sensors()

    def _write_indexed(self) -> None:
        ctrl, cmd = self.world.data.ctrl, self._effort_cmd
        for k, act, n in zip(self._act_joint_idx, self._ctrl_ids, self._reduction):
            ctrl[act] = cmd[k] / n

    def _read_sensors(self) -> None:
        data = self._sensordata.tolist()
        for w, f, t in self._sensor_slots:
            w[0], w[1], w[2] = -data[f], -data[f + 1], -data[f + 2]
            w[3], w[4], w[5] = -data[t], -data[t + 1], -data[t + 2]

    def advance(self, period_s: float) -> None:
        """Step the physics by ``period_s``; :class:`PhysicsError` naming MuJoCo's warning, within
        ``WARNING_CHECK_CYCLES`` cycles, when the simulation became invalid."""
        if period_s != self._period_s:
            self._nstep = physics_steps(period_s, self.world.timestep_s)
            self._period_s = period_s
        mj_step(self._model, self._data, self._nstep)
        self._until_warning_check -= 1
        if not self._until_warning_check:
            self._check_warnings()

    def _check_warnings(self) -> None:
        # MuJoCo counts each warning; resetting an unstable simulation zeroes the counts and then
        # counts the warning that caused it, so a count above the last one seen is always new.
        self._until_warning_check = WARNING_CHECK_CYCLES
        warning = self._data.warning  # indexed, not iterated: pybind11 ends an iteration with a C++ exception
        counts = [warning[k].number for k in range(len(warning))]
        new = [k for k, (now, seen) in enumerate(zip(counts, self._warnings_seen)) if now > seen]
        self._warnings_seen = counts
        if new:
            raise PhysicsError(f"MuJoCo warned by t = {self._data.time:.3f} s: the simulation is no longer valid "
                               "(unstable gains or contacts, a non-finite force, or too many contacts)",
                               field=", ".join(WARNINGS.get(k, str(k)) for k in new),
                               value=[self._data.warning[k].lastinfo for k in new])

    def reset(self) -> None:
        self.world.reset()
        self._warnings_seen = [self._data.warning[k].number for k in range(len(self._data.warning))]
        for buf in self._commands.values():
            buf[:] = [0.0] * len(buf)
        self.read()

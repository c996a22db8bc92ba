"""A compiled MuJoCo world holding one robot, with named access to its joints.

:class:`MujocoWorld` owns ``MjModel``/``MjData``, resolves joint, actuator and
sensor names to MuJoCo addresses once, and steps the physics. Joint values
are in the URDF's units (m for prismatic, rad for revolute joints).

For a URDF with ``<ros2_control>`` the world stands in for its hardware plugin: the joints with an
``effort`` command interface get effort actuators, each starts at the ``initial_value`` of its
``position`` state interface (unless ``initial_positions`` says otherwise), and a joint whose
command interfaces are only ``velocity``/``position`` (or others) is refused with
:func:`check_simulated_interfaces`: the world simulates effort-driven joints.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import mujoco
import numpy as np

from jointctl.errors import ConfigError, ModelError
from jointctl.model.robot_model import RobotModel
from jointctl.sim.mjcf_builder import WorldSettings, build_spec, rpy_to_quat, sensor_site_name
from jointctl.sim.objects import ObjectSpec

_GEOM = {"cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER, "box": mujoco.mjtGeom.mjGEOM_BOX,
         "sphere": mujoco.mjtGeom.mjGEOM_SPHERE}


def check_simulated_interfaces(robot: RobotModel) -> None:
    """Refuse a ``<ros2_control>`` joint with command interfaces none of which is ``effort`` (and no
    ``<transmission>`` with an EffortJointInterface driving it): the simulated robot's actuators take
    efforts; a velocity or position interface is a drive's own servo, which the world does not invent."""
    driven = {t.joint for t in robot.transmissions if "EffortJointInterface" in t.hardware_interfaces}
    for component in robot.ros2_control:
        for joint in component.joints:
            if joint.command_interfaces and joint.name not in driven:
                raise ModelError("jointctl's simulated robot drives joints through an effort command interface "
                                 "only (add <command_interface name=\"effort\"/>)", source=robot.source,
                                 field=f"ros2_control[{component.name}].joint[{joint.name}].command_interface",
                                 value=", ".join(joint.command_names))


class MujocoWorld:
    """The robot in a MuJoCo world.

    ``joint_names`` lists the robot's movable joints in document order; the
    arrays ``qpos_adr``/``dof_adr``/``actuator_ids`` follow that order
    (``-1`` where a joint has no actuator).
    """

    def __init__(
        self,
        robot: RobotModel,
        settings: WorldSettings = WorldSettings(),
        *,
        initial_positions: Mapping[str, float] | None = None,
        source: str | None = None,
    ) -> None:
        self.robot = robot
        self.settings = settings
        check_simulated_interfaces(robot)
        self.spec = build_spec(robot, settings)
        try:
            self.model = self.spec.compile()
        except Exception as exc:  # MuJoCo reports model errors as ValueError
            raise ModelError(f"MuJoCo refused the model: {exc}", source=robot.source) from None
        self.data = mujoco.MjData(self.model)
        self.joint_names: tuple[str, ...] = tuple(j.name for j in robot.movable_joints)
        self._resolve_addresses()
        # ros2_control's initial values first (checked against the limits by the URDF parser), then the caller's.
        self.initial_positions = {**robot.initial_positions, **self._check_initial(initial_positions or {}, source)}
        self.spawned: list[ObjectSpec] = []
        #: What is derived from the robot simulated alone (its dynamics, for an analysis), kept with the world for
        #: the runs that restart it (:meth:`~jointctl.scenario.session.Session.dynamics`).
        self.derived: dict = {}
        #: Whether MuJoCo recompiled the model since it was built (objects spawned, even if removed again).
        self._recompiled = False
        self._rebuild_listeners: list[Callable[[], None]] = []
        self.reset()

    def _resolve_addresses(self) -> None:
        m = self.model
        jids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in self.joint_names]
        self.qpos_adr = np.array([m.jnt_qposadr[j] for j in jids], dtype=int)
        self.dof_adr = np.array([m.jnt_dofadr[j] for j in jids], dtype=int)
        self.actuator_ids = np.array(
            [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in self.joint_names],
            dtype=int,
        )

    def on_rebuild(self, listener: Callable[[], None]) -> None:
        """Call ``listener`` after ``model``/``data`` are replaced (an object was spawned)."""
        self._rebuild_listeners.append(listener)

    def has_body(self, name: str) -> bool:
        return self.spec.body(name) is not None

    def spawn(self, obj: ObjectSpec) -> None:
        """Add ``obj`` as a free body at its pose, at rest, keeping the current state of
        everything else (MuJoCo recompiles the model and copies the state across)."""
        if self.has_body(obj.name):
            raise ConfigError("an object or link of that name already exists", field="objects.name",
                              value=obj.name)
        # The centre of mass at the body's origin, stated: MjSpec leaves ``ipos`` unset (NaN) and the
        # compiler would then put it at ``pos`` in the body frame (4 m above a weight spawned at z = 4).
        body = self.spec.worldbody.add_body(
            name=obj.name, pos=list(obj.xyz), quat=list(rpy_to_quat(obj.rpy)), mass=obj.mass_kg,
            inertia=list(obj.principal_inertia), ipos=[0.0, 0.0, 0.0], iquat=[1.0, 0.0, 0.0, 0.0],
            explicitinertial=True)
        body.add_freejoint(name=f"{obj.name}_free")
        body.add_geom(name=f"{obj.name}_geom", type=_GEOM[obj.shape], size=obj.mujoco_size,
                      friction=[obj.friction, 0.005, 0.0001], rgba=[0.6, 0.3, 0.2, 1.0])
        try:
            self.model, self.data = self.spec.recompile(self.model, self.data)
        except Exception as exc:
            raise ConfigError(f"MuJoCo refused the object: {exc}", field="objects", value=obj.name) from None
        self._recompiled = True
        mujoco.mj_forward(self.model, self.data)  # derived quantities (poses, forces, sensors) now
        self.spawned.append(obj)
        self._resolve_addresses()
        for listener in self._rebuild_listeners:
            listener()

    def remove(self, name: str) -> ObjectSpec:
        """Take the spawned object ``name`` out of the world (MuJoCo recompiles the model); the
        robot and the other objects keep their state. Returns the object's spec."""
        index = next((k for k, obj in enumerate(self.spawned) if obj.name == name), None)
        if index is None:
            raise ConfigError("no spawned object of that name", field="objects.name", value=name)
        self.spec.delete(self.spec.body(name))
        self.model, self.data = self.spec.recompile(self.model, self.data)
        mujoco.mj_forward(self.model, self.data)
        obj = self.spawned.pop(index)
        self._resolve_addresses()
        for listener in self._rebuild_listeners:
            listener()
        return obj

    def remove_spawned(self) -> None:
        """Take every spawned object out of the world again (MuJoCo recompiles the model);
        the robot's state is kept. :meth:`reset` then starts over as if nothing was spawned."""
        if not self.spawned:
            return
        for obj in self.spawned:
            self.spec.delete(self.spec.body(obj.name))
        self.model, self.data = self.spec.recompile(self.model, self.data)
        mujoco.mj_forward(self.model, self.data)
        self.spawned = []
        self._resolve_addresses()
        for listener in self._rebuild_listeners:
            listener()

    @property
    def gravity_m_s2(self) -> tuple[float, float, float]:
        """World-frame gravity [m/s²] (z up: Earth is (0, 0, -9.81))."""
        return tuple(float(g) for g in self.model.opt.gravity)

    def set_gravity(self, gravity_m_s2: tuple[float, float, float]) -> None:
        """Change gravity from the next step on; kept when objects are spawned (the spec holds it too)."""
        values = [float(g) for g in gravity_m_s2]
        if len(values) != 3 or not all(math.isfinite(g) for g in values):
            raise ConfigError("must be three finite numbers [m/s²]", field="gravity", value=gravity_m_s2)
        self.model.opt.gravity[:] = values
        self.spec.option.gravity = values

    def body_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """World position [m] and orientation quaternion (w, x, y, z) of body ``name``."""
        bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if bid < 0:
            raise ConfigError("no body of that name", field="body", value=name)
        return self.data.xpos[bid].copy(), self.data.xquat[bid].copy()

    def _check_initial(self, positions: Mapping[str, float], source: str | None) -> dict[str, float]:
        checked = {}
        for name, value in positions.items():
            field = f"initial_positions.{name}"
            if name not in self.joint_names:
                raise ConfigError(f"no movable joint of that name (joints: {', '.join(self.joint_names)})",
                                  source=source, field=field, value=name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError("must be a finite number", source=source, field=field, value=value)
            lim = self.robot.joint(name).limits
            if lim is not None and lim.lower is not None and not lim.lower <= value <= lim.upper:
                raise ConfigError(f"outside the joint's limits [{lim.lower}, {lim.upper}]",
                                  source=source, field=field, value=value)
            checked[name] = float(value)
        return checked

    @property
    def timestep_s(self) -> float:
        return float(self.model.opt.timestep)

    @property
    def time_s(self) -> float:
        return float(self.data.time)

    def restart(self, initial_positions: Mapping[str, float] | None = None, *, source: str | None = None) -> None:
        """Start over as a new world of the same robot and settings starts: at rest at time zero, at
        ``initial_positions`` (checked as the constructor checks them), MuJoCo's data reset whole
        (``mj_resetData``: state, warnings, controls), the listeners of the model's rebuilds dropped (their owners,
        the last run's hardware, are gone). The compiled model is kept: a world whose model changed (an object
        spawned, gravity set) cannot restart (RuntimeError); build a new one."""
        if not self.is_as_built():
            raise RuntimeError("the world's model changed since it was built (an object spawned or gravity set)")
        checked = self._check_initial(initial_positions or {}, source)
        self.initial_positions = {**self.robot.initial_positions, **checked}
        self._rebuild_listeners = []
        self.reset()

    def is_as_built(self) -> bool:
        """Whether the model is still the one compiled from the robot and settings: no object spawned (or removed:
        MuJoCo recompiled it), gravity the settings'."""
        built = [float(g) for g in self.settings.gravity_m_s2]
        return not self.spawned and not self._recompiled and [float(g) for g in self.model.opt.gravity] == built

    def reset(self) -> None:
        """Back to time zero, at rest, at the initial joint positions."""
        mujoco.mj_resetData(self.model, self.data)
        for name, value in self.initial_positions.items():
            self.data.qpos[self.qpos_adr[self.joint_names.index(name)]] = value
        mujoco.mj_forward(self.model, self.data)

    def step(self) -> None:
        mujoco.mj_step(self.model, self.data)

    def contiguous(self, adr: np.ndarray) -> slice | None:
        """A slice covering ``adr`` when the addresses are consecutive, else None."""
        if len(adr) and np.array_equal(adr, np.arange(adr[0], adr[0] + len(adr))):
            return slice(int(adr[0]), int(adr[0]) + len(adr))
        return None

    def sensor_adr(self, sensor_name: str) -> tuple[int, int]:
        """Data addresses of the force and torque triples of a force-torque sensor."""
        m = self.model
        ids = []
        for part in ("force", "torque"):
            sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, f"{sensor_name}_{part}")
            if sid < 0:
                raise ConfigError("no force-torque sensor of that name", field="sensor",
                                  value=sensor_name)
            ids.append(int(m.sensor_adr[sid]))
        return ids[0], ids[1]

    def site_id(self, sensor_name: str) -> int:
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, sensor_site_name(sensor_name))

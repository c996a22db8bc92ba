"""The robot as a MuJoCo model (an ``MjSpec``), from a :class:`RobotModel` alone.

jointctl writes the MuJoCo model itself instead of letting MuJoCo import the
URDF, because that import drops transmissions (so every actuator), Gazebo
sensors and velocity limits, fuses fixed children into their parents and
loses the mass of a root fixed to the world. Here:

- every link is a body; fixed joints and *locked* joints (lower == upper) are
  welds (a body without a joint), so the force-sensor link survives as a body;
- contacts between the two links of every joint are excluded;
- one motor actuator per transmission with an effort interface, geared by its
  ``mechanicalReduction`` n as ros_control's SimpleTransmission (joint effort =
  n · actuator effort, actuator position = n · joint position), its force range
  the joint's effort limit over |n| (the URDF's limit is the joint's); other
  transmission types are refused;
- every force-torque sensor becomes a site at its link's origin with MuJoCo
  ``force`` and ``torque`` sensors;
- every limited joint's limit is a stiff stop: its solver parameters come from
  the timestep (:func:`limit_solref`, docs/simulation.md), not MuJoCo's soft default;
- gravity and timestep are given by the caller, not read from the URDF;
- a visual without a colour of its own takes its link's default colour: dark grey for the base
  (the root link and the links fixed to it), then one of :data:`LINK_COLOURS` per other link in
  the URDF's order, so that a robot whose URDF names no materials is not a grey robot on a grey
  floor.

:func:`robot_spec` is the robot alone (what :mod:`jointctl.model.dynamics` computes
with); the simulated world (:mod:`jointctl.sim.mjcf_builder`) starts from
:func:`empty_spec`, adds its floor and then the robot with :func:`add_robot`.
"""

from __future__ import annotations

import math
import mujoco
import numpy as np

from jointctl.errors import ModelError
from jointctl.model.robot_model import Joint, Link, RobotModel, Shape

WORLD_LINK = "world"

_GEOM_TYPES = {
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "mesh": mujoco.mjtGeom.mjGEOM_MESH,
}
VISUAL_GROUP = 2
COLLISION_GROUP = 3
#: Default colours (RGBA, 0..1) of links whose visuals name none: the base's, then the others' in turn.
ROOT_LINK_COLOUR = (0.35, 0.36, 0.4, 1.0)
LINK_COLOURS = (
    (0.22, 0.47, 0.78, 1.0),  # blue
    (0.95, 0.55, 0.15, 1.0),  # orange
    (0.3, 0.66, 0.36, 1.0),   # green
    (0.83, 0.27, 0.27, 1.0),  # red
    (0.58, 0.42, 0.74, 1.0),  # violet
    (0.2, 0.7, 0.74, 1.0),    # teal
)


# -- joint limits as stops ------------------------------------------------------
#
# MuJoCo's limit is a soft constraint. With solref = (tau, zeta) and impedance d, an active limit's
# penetration r (m or rad) obeys, for d near dmax,
#     r'' + (2/tau) r' + r/(zeta tau)^2 = (1 - d) a0,
# a mass-spring-damper with time constant tau, where a0 = f * invweight is the acceleration the push f
# (N or N·m) would give the free joint (invweight: MuJoCo's inverse joint inertia, 1/kg or 1/(kg·m²)).
# At rest MuJoCo's solution is exactly
#     r = (1 - d)/d² · dmax² · tau² · zeta² · invweight · f,
# i.e. a stop of stiffness f/r = 1 / ((1 - d)/d² · dmax² · tau² · zeta² · invweight).
# MuJoCo's default tau = 0.02 s leaves the 1-DOF piston (1.01 kg) 3.8 mm past its limit under 200 N
# (19.6 mm under its 1000 N effort limit).
# The stiffest stop that stays stable is tau = 2 timesteps (MuJoCo's own rule and floor:
# it raises any smaller tau to 2·timestep); critical damping (zeta = 1) stops without bouncing.
# The impedance is MuJoCo's default, stated here because the bound below depends on it.

LIMIT_TIMECONST_STEPS = 2.0
"""The limits' time constant in physics steps: MuJoCo's minimum for a stable constraint."""
LIMIT_DAMPRATIO = 1.0
"""Critical damping: a joint driven into its limit stops without bouncing back."""
LIMIT_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)
"""Limit impedance (dmin, dmax, width [m or rad], midpoint, power): MuJoCo's default."""


def limit_solref(timestep_s: float) -> tuple[float, float]:
    """The joint-limit ``solref`` (time constant [s], damping ratio) for a physics step [s]."""
    return (LIMIT_TIMECONST_STEPS * timestep_s, LIMIT_DAMPRATIO)


def limit_overshoot_bound(effort: float, invweight: float, timestep_s: float) -> float:
    """Largest steady overshoot past a limit [m or rad] under a constant push ``effort`` [N or N·m].

    ``invweight`` is MuJoCo's inverse inertia of the joint (``MjModel.dof_invweight0``, 1/kg or
    1/(kg·m²)). The impedance d lies in [dmin, dmax] and (1 - d)/d² falls as d grows, so d = dmin
    bounds the resting penetration (1 - d)/d² · dmax² · tau² · zeta² · invweight · effort from above.
    """
    dmin, dmax = LIMIT_SOLIMP[0], LIMIT_SOLIMP[1]
    tau, zeta = limit_solref(timestep_s)
    return (1.0 - dmin) / dmin**2 * dmax**2 * tau**2 * zeta**2 * invweight * abs(effort)


def sensor_site_name(sensor_name: str) -> str:
    return f"{sensor_name}_site"


def empty_spec(name: str, *, timestep_s: float = 0.001,
               gravity_m_s2=(0.0, 0.0, -9.81)) -> mujoco.MjSpec:
    """An ``MjSpec`` with jointctl's compiler settings, ``timestep_s`` [s] and ``gravity_m_s2``
    [m/s², world frame, z up], and nothing in it yet."""
    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.compiler.autolimits = True
    spec.compiler.degree = False  # URDF angles are radians; MjSpec's default is degrees
    spec.option.timestep = timestep_s
    spec.option.gravity = [float(g) for g in gravity_m_s2]
    return spec


def add_robot(spec: mujoco.MjSpec, robot: RobotModel) -> None:
    """Add ``robot`` (bodies, joints, contact excludes, actuators, sensors) to ``spec``; its
    joint limits are stops for the spec's timestep."""
    _Builder(robot, spec).build()


def robot_spec(robot: RobotModel, *, timestep_s: float = 0.001,
               gravity_m_s2=(0.0, 0.0, -9.81)) -> mujoco.MjSpec:
    """An uncompiled ``MjSpec`` of ``robot`` alone: no floor, no objects."""
    spec = empty_spec(robot.name, timestep_s=timestep_s, gravity_m_s2=gravity_m_s2)
    add_robot(spec, robot)
    return spec


def compile_robot(robot: RobotModel, *, timestep_s: float = 0.001,
                  gravity_m_s2=(0.0, 0.0, -9.81)) -> mujoco.MjModel:
    """The compiled :func:`robot_spec`; MuJoCo's refusal becomes a :class:`ModelError`."""
    try:
        return robot_spec(robot, timestep_s=timestep_s, gravity_m_s2=gravity_m_s2).compile()
    except ValueError as exc:  # MuJoCo reports model errors as ValueError
        raise ModelError(f"MuJoCo refused the model: {exc}", source=robot.source) from None


class _Builder:
    def __init__(self, robot: RobotModel, spec: mujoco.MjSpec) -> None:
        self.robot = robot
        self.spec = spec
        self.limit_solref = list(limit_solref(spec.option.timestep))
        self.meshes: dict[tuple[str, tuple[float, float, float]], str] = {}

    def error(self, message: str, field: str, value=None) -> ModelError:
        return ModelError(message, source=self.robot.source, field=field, value=value)

    def build(self) -> None:
        robot = self.robot
        root = robot.root_link
        if root == WORLD_LINK:
            parent_body = self.spec.worldbody
            self.add_shapes(parent_body, robot.link(root))
        else:
            # A robot without a "world" link is bolted to the world at its root.
            parent_body = self.spec.worldbody.add_body(name=root)
            self.add_link_contents(parent_body, robot.link(root))
        self.add_children(parent_body, root)
        for joint in robot.joints:
            if joint.parent != WORLD_LINK or root != WORLD_LINK:
                self.spec.add_exclude(bodyname1=joint.parent, bodyname2=joint.child)
        self.add_actuators()
        self.add_sensors()

    def add_children(self, body, link_name: str) -> None:
        for joint in self.robot.child_joints(link_name):
            pos, quat = self.child_frame(joint)
            child = body.add_body(name=joint.child, pos=pos, quat=quat)
            self.add_joint(child, joint)
            self.add_link_contents(child, self.robot.link(joint.child))
            self.add_children(child, joint.child)

    @staticmethod
    def child_frame(joint: Joint) -> tuple[list[float], list[float]]:
        """The child's frame in the parent's: the joint origin, moved by a locked joint's value."""
        rotation = rpy_to_matrix(joint.origin.rpy)
        pos = np.array(joint.origin.xyz, dtype=float)
        if joint.is_locked and joint.limits.lower != 0.0:
            axis = np.array(joint.axis)
            if joint.is_prismatic:
                pos = pos + rotation @ (axis * joint.limits.lower)
            else:
                turn = np.zeros(9)
                quat_turn = np.zeros(4)
                mujoco.mju_axisAngle2Quat(quat_turn, axis, joint.limits.lower)
                mujoco.mju_quat2Mat(turn, quat_turn)
                rotation = rotation @ turn.reshape(3, 3)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rotation.ravel())
        return pos.tolist(), quat.tolist()

    def add_joint(self, body, joint: Joint) -> None:
        if joint.type in ("fixed",) or joint.is_locked:
            return
        if joint.type in ("floating", "planar"):
            raise self.error("joint type not supported by the MuJoCo builder",
                             f"joint[{joint.name}].type", joint.type)
        jtype = mujoco.mjtJoint.mjJNT_SLIDE if joint.is_prismatic else mujoco.mjtJoint.mjJNT_HINGE
        kwargs = dict(name=joint.name, type=jtype, axis=list(joint.axis),
                      damping=joint.damping, frictionloss=joint.friction, armature=joint.armature)
        lim = joint.limits
        if lim is not None and lim.lower is not None:
            kwargs.update(limited=mujoco.mjtLimited.mjLIMITED_TRUE, range=[lim.lower, lim.upper],
                          solref_limit=self.limit_solref, solimp_limit=list(LIMIT_SOLIMP))
        else:
            kwargs.update(limited=mujoco.mjtLimited.mjLIMITED_FALSE)
        body.add_joint(**kwargs)

    def add_link_contents(self, body, link: Link) -> None:
        inertial = link.inertial
        if inertial is not None:
            body.mass = inertial.mass_kg
            body.ipos = list(inertial.origin.xyz)
            ixx, iyy, izz, ixy, ixz, iyz = inertial.inertia
            rotation = rpy_to_matrix(inertial.origin.rpy)
            tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
            tensor = rotation @ tensor @ rotation.T  # into the link frame
            body.fullinertia = [tensor[0, 0], tensor[1, 1], tensor[2, 2],
                                tensor[0, 1], tensor[0, 2], tensor[1, 2]]
            body.explicitinertial = True
        self.add_shapes(body, link)

    def add_shapes(self, body, link: Link) -> None:
        for k, shape in enumerate(link.collisions):
            self.add_geom(body, shape, f"{link.name}_collision_{k}", collision=True)
        for k, shape in enumerate(link.visuals):
            self.add_geom(body, shape, f"{link.name}_visual_{k}", collision=False,
                          default_rgba=self.default_colour(link.name))

    def default_colour(self, link_name: str) -> tuple[float, float, float, float]:
        """The colour of ``link_name``'s visuals that name none (see the module docstring)."""
        base = self.base_links()
        if link_name in base:
            return ROOT_LINK_COLOUR
        moving = [link.name for link in self.robot.links if link.name not in base]
        return LINK_COLOURS[moving.index(link_name) % len(LINK_COLOURS)]

    def base_links(self) -> set[str]:
        """The root link and the links fixed to it (through fixed joints only): the robot's base."""
        base, todo = set(), [self.robot.root_link]
        while todo:
            name = todo.pop()
            base.add(name)
            todo.extend(j.child for j in self.robot.child_joints(name) if j.type == "fixed")
        return base

    def add_geom(self, body, shape: Shape, name: str, *, collision: bool,
                 default_rgba: tuple[float, float, float, float] = ROOT_LINK_COLOUR) -> None:
        g = shape.geometry
        kwargs = dict(name=name, type=_GEOM_TYPES[g.kind], pos=list(shape.origin.xyz),
                      quat=list(rpy_to_quat(shape.origin.rpy)))
        if g.kind == "box":
            kwargs["size"] = [s / 2 for s in g.size_m]
        elif g.kind == "cylinder":
            kwargs["size"] = [g.radius_m, g.length_m / 2, 0.0]
        elif g.kind == "sphere":
            kwargs["size"] = [g.radius_m, 0.0, 0.0]
        else:
            kwargs["meshname"] = self.mesh(g.mesh_path, g.scale)
        if collision:
            kwargs.update(group=COLLISION_GROUP, contype=1, conaffinity=1, rgba=[0.5, 0.5, 0.9, 0.0])
        else:
            kwargs.update(group=VISUAL_GROUP, contype=0, conaffinity=0)
            kwargs["rgba"] = list(shape.rgba if shape.rgba is not None else default_rgba)
        body.add_geom(**kwargs)

    def mesh(self, path: str, scale) -> str:
        key = (path, tuple(scale))
        if key not in self.meshes:
            name = f"mesh_{len(self.meshes)}"
            self.spec.add_mesh(name=name, file=path, scale=list(scale))
            self.meshes[key] = name
        return self.meshes[key]

    def add_actuators(self) -> None:
        robot = self.robot
        for tr in robot.transmissions:
            joint = robot.joint(tr.joint)
            if not joint.is_movable:
                raise self.error("transmission on a joint that cannot move",
                                 f"transmission[{tr.name}].joint", tr.joint)
            if "EffortJointInterface" not in tr.hardware_interfaces:
                raise self.error(
                    "the MuJoCo hardware drives joints through EffortJointInterface only",
                    f"transmission[{tr.name}].hardwareInterface", ", ".join(tr.hardware_interfaces))
            if tr.type.rsplit("/", 1)[-1] != "SimpleTransmission":
                raise self.error("jointctl models transmission_interface/SimpleTransmission only (one actuator, "
                                 "one joint, a mechanicalReduction)", f"transmission[{tr.name}].type", tr.type)
            # SimpleTransmission with reduction n: joint effort = n·actuator effort, actuator position = n·joint
            # position (MuJoCo's gear). The URDF's effort limit is the joint's; the actuator's is that over |n|.
            n = tr.mechanical_reduction
            act = self.spec.add_actuator(name=tr.joint, target=tr.joint,
                                         trntype=mujoco.mjtTrn.mjTRN_JOINT, gear=[n, 0, 0, 0, 0, 0])
            act.set_to_motor()
            effort = joint.limits.effort if joint.limits is not None else 0.0
            if effort > 0:
                act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
                act.forcerange = [-effort / abs(n), effort / abs(n)]

    def add_sensors(self) -> None:
        for sensor in self.robot.sensors:
            body = self.spec.body(sensor.link)
            if body is None:
                raise self.error("sensor link does not exist", f"sensor[{sensor.name}].link",
                                 sensor.link)
            site = sensor_site_name(sensor.name)
            body.add_site(name=site, size=[0.01, 0.01, 0.01])
            self.spec.add_sensor(name=f"{sensor.name}_force", type=mujoco.mjtSensor.mjSENS_FORCE,
                                 objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site)
            self.spec.add_sensor(name=f"{sensor.name}_torque", type=mujoco.mjtSensor.mjSENS_TORQUE,
                                 objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site)


def rpy_to_matrix(rpy) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw [rad] to a rotation matrix R = Rz(y) Ry(p) Rx(r)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def rpy_to_quat(rpy) -> tuple[float, float, float, float]:
    """URDF roll-pitch-yaw [rad] to a MuJoCo quaternion (w, x, y, z)."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rpy_to_matrix(rpy).ravel())
    return tuple(float(q) for q in quat)

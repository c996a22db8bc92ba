"""Gazebo's world services on the wire, so the chapter's steps that spawn the weight and change
gravity work against ``jointctl serve`` as they did against Gazebo (gazebo_msgs, MD5s as upstream):

- ``/gazebo/spawn_sdf_model``, ``/gazebo/spawn_urdf_model`` (gazebo_msgs/SpawnModel): the model
  XML (either service takes SDF or URDF, by its root element, as Gazebo does) becomes one rigid
  body (:mod:`jointctl.sim.model_xml`), placed by ``initial_pose`` in the world frame
  (``reference_frame`` empty, ``world`` or ``map``); ``robot_namespace`` is unused (it serves
  plugins, which are refused). What jointctl cannot represent is refused, ``success`` false, the
  element named in ``status_message``, nothing spawned. What was adapted for MuJoCo (the inertia,
  friction) is said in ``status_message`` and logged. The answer comes once the object is in the
  world (or MuJoCo refused it), as Gazebo's does.
- ``/gazebo/delete_model`` (gazebo_msgs/DeleteModel): removes a spawned object (the robot cannot be).
- ``/gazebo/get_physics_properties``: gravity; ``time_step`` is the loop's period; ``max_update_rate``
  the loop's cycles per wall-clock second (its speed / period); ``pause`` false; ``ode_config``
  holds MuJoCo's nearest settings (solver iterations, tolerance), zero where it has none.
- ``/gazebo/set_physics_properties``: gravity (any finite vector), for the physics and the
  controllers' model feed-forward. ``time_step`` and ``max_update_rate`` cannot change while
  running: a request whose values differ from what get reports is refused, naming the field, and
  changes nothing. ``ode_config`` is not applied (MuJoCo has no ODE solver); the answer says so.
- ``/gazebo/model_states`` (gazebo_msgs/ModelStates) at :data:`MODEL_STATES_RATE_HZ` while someone
  listens: ``ground_plane`` (when the world has a floor), the robot's base (by the robot's name) and
  every spawned object, with pose and twist (world frame: linear velocity of the model frame's
  origin, angular velocity).

Doors: requests are checked on rospy's threads, completely, before anything is queued; the change
itself runs at the start of a loop cycle (MuJoCo is only touched by the loop thread) and the service
answers when it has. A request the loop does not take within :data:`APPLY_TIMEOUT_S` (loop
stopped) is withdrawn and answered as failed. These are simulation doors: when the session's
hardware is not simulated the services answer so (``success`` false) and no states are published.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import rospy
from gazebo_msgs.msg import ModelStates, ODEPhysics
from gazebo_msgs.srv import (
    DeleteModel,
    DeleteModelResponse,
    GetPhysicsProperties,
    GetPhysicsPropertiesResponse,
    SetPhysicsProperties,
    SetPhysicsPropertiesResponse,
    SpawnModel,
    SpawnModelResponse,
)
from geometry_msgs.msg import Pose, Twist, Vector3

from jointctl.errors import JointCtlError
from jointctl.sim.model_xml import UnsupportedModel, check_model_name, parse_model_xml

NAMESPACE = "/gazebo"
MODEL_STATES_RATE_HZ = 100.0
#: Messages model_states' publisher holds for a subscriber's connection (gazebo_ros advertises it with
#: 10): a tenth of a second at 100 Hz before a slow connection loses one.
MODEL_STATES_QUEUE = 10
APPLY_TIMEOUT_S = 10.0
WORLD_FRAMES = ("", "world", "map", "/map")
GROUND_PLANE = "ground_plane"
WORLD_BODY = "world"  # the simulated world's own body: where the ground plane is


class _Request:
    """A change for the loop: ``apply(time_s)`` returns a message or raises JointCtlError."""

    def __init__(self, apply: Callable[[float], str]) -> None:
        self.apply = apply
        self.lock = threading.Lock()
        self.done = threading.Event()
        self.withdrawn = False
        self.ok = False
        self.message = ""


@dataclass(frozen=True)
class _Tracked:
    """A model listed in model_states: its body, and its model frame in the body frame."""

    name: str
    body: str
    frame_pos: np.ndarray
    frame_quat: np.ndarray


class WorldServices:
    """The ``/gazebo`` services and ``model_states`` of one node."""

    def __init__(self, node) -> None:
        self.node = node
        session = node.session
        self.loop = session.loop
        self.manager = session.manager
        self.robot = session.robot
        #: The hardware's simulation door (None on real hardware: every service says so).
        self.sim = session.hardware.simulation
        self.hardware_name = type(session.hardware).__name__
        # Names taken: the robot's model name and the objects the scenario spawns by itself later.
        self.reserved = {self.robot.name, GROUND_PLANE, *(o.name for o in session.scenario.objects)}
        self._pending: deque[_Request] = deque()
        self._frames: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # model frame in body frame
        self._tracked: tuple[_Tracked, ...] = ()
        self._physics = self._physics_snapshot()
        ns = NAMESPACE
        self.services = [
            rospy.Service(f"{ns}/spawn_sdf_model", SpawnModel, self._spawn),
            rospy.Service(f"{ns}/spawn_urdf_model", SpawnModel, self._spawn),
            rospy.Service(f"{ns}/delete_model", DeleteModel, self._delete),
            rospy.Service(f"{ns}/get_physics_properties", GetPhysicsProperties, self._get_physics),
            rospy.Service(f"{ns}/set_physics_properties", SetPhysicsProperties, self._set_physics),
        ]
        self.loop.add_input(self._cycle_start)
        if self.sim is not None:
            self._base = self._base_body()
            self._track()
            self.sim.on_rebuild(self._track)
            self._publisher = rospy.Publisher(f"{ns}/model_states", ModelStates, queue_size=MODEL_STATES_QUEUE)
            self._every = max(1, round(1.0 / (MODEL_STATES_RATE_HZ * self.loop.period_s)))
            self._count = 0
            self.loop.add_observer(self._publish_states)

    # -- the door (loop thread) ----------------------------------------------------------------
    def _cycle_start(self, time_s: float) -> None:
        pending = self._pending
        while pending:
            request = pending.popleft()
            with request.lock:
                if request.withdrawn:
                    continue
                try:
                    request.message = request.apply(time_s)
                    request.ok = True
                except JointCtlError as exc:
                    request.message = str(exc)
                request.done.set()

    def _submit(self, apply: Callable[[float], str]) -> tuple[bool, str]:
        """Queue ``apply`` for the next cycle and wait for it (a rospy thread)."""
        request = _Request(apply)
        self._pending.append(request)
        if not request.done.wait(APPLY_TIMEOUT_S):
            with request.lock:
                if not request.done.is_set():
                    request.withdrawn = True
                    return False, (f"the control loop did not take the request within {APPLY_TIMEOUT_S:g} s "
                                   "(is it running?); nothing changed")
        return request.ok, request.message

    def _not_simulated(self) -> str:
        return (f"jointctl's hardware ({self.hardware_name}) is not simulated: there is no world to spawn into, "
                "delete from or change the physics of")

    # -- spawn and delete ----------------------------------------------------------------------
    def _spawn(self, req) -> SpawnModelResponse:
        if self.sim is None:
            return SpawnModelResponse(False, "SpawnModel: " + self._not_simulated())
        try:
            name = check_model_name(req.model_name)
            self._check_free(name)
            if req.reference_frame not in WORLD_FRAMES:
                raise UnsupportedModel("jointctl places spawned models in the world frame only "
                                       "(reference_frame '', 'world' or 'map')", field="reference_frame",
                                       value=req.reference_frame)
            p, q = req.initial_pose.position, req.initial_pose.orientation
            model = parse_model_xml(req.model_xml, name=name, position=(p.x, p.y, p.z),
                                    orientation=(q.w, q.x, q.y, q.z), floor=self.sim.floor)
        except JointCtlError as exc:
            rospy.logwarn("jointctl: refused to spawn %r: %s", req.model_name, exc)
            return SpawnModelResponse(False, f"SpawnModel: refused, nothing spawned: {exc}")
        description = model.describe()

        def apply(time_s: float) -> str:
            self._check_free(name)
            self._frames[name] = (np.array(model.frame_xyz), np.array(model.frame_quat))
            try:
                self.sim.spawn(model.spec)
            except JointCtlError:
                del self._frames[name]
                raise
            return f"SpawnModel: spawned at loop time {time_s:.3f} s: {description}"

        ok, message = self._submit(apply)
        if ok:
            rospy.loginfo("jointctl: %s", message)
        else:
            rospy.logwarn("jointctl: could not spawn %r: %s", name, message)
            message = message if message.startswith("SpawnModel") else f"SpawnModel: failed, nothing spawned: {message}"
        return SpawnModelResponse(ok, message)

    def _check_free(self, name: str) -> None:
        taken = (name in self.reserved or any(o.name == name for o in self.sim.spawned)
                 or self.robot.has_link(name))
        if taken:
            raise UnsupportedModel("a model (or a link of the robot) of that name already exists",
                                   field="model_name", value=name)

    def _delete(self, req) -> DeleteModelResponse:
        if self.sim is None:
            return DeleteModelResponse(False, "DeleteModel: " + self._not_simulated())
        name = req.model_name
        if name in (self.robot.name, GROUND_PLANE):
            return DeleteModelResponse(False, f"DeleteModel: {name!r} is part of jointctl's world and cannot be "
                                              "deleted (only spawned models can)")

        def apply(time_s: float) -> str:
            if not any(o.name == name for o in self.sim.spawned):
                raise UnsupportedModel("model does not exist", field="model_name", value=name)
            self.sim.remove(name)
            self._frames.pop(name, None)
            return f"DeleteModel: deleted {name!r} at loop time {time_s:.3f} s"

        ok, message = self._submit(apply)
        (rospy.loginfo if ok else rospy.logwarn)("jointctl: %s", message)
        return DeleteModelResponse(ok, message if ok else f"DeleteModel: {message}")

    # -- physics properties --------------------------------------------------------------------
    def _physics_snapshot(self) -> dict:
        """What get_physics_properties reports; taken here and by the loop after each change
        (never read from MuJoCo on a rospy thread)."""
        if self.sim is None:
            return {}
        solver = self.sim.solver
        return {
            "gravity": self.sim.gravity_m_s2,
            "ode": ODEPhysics(auto_disable_bodies=False, sor_pgs_precon_iters=0, sor_pgs_iters=int(solver["iterations"]),
                              sor_pgs_w=0.0, sor_pgs_rms_error_tol=float(solver["tolerance"]), contact_surface_layer=0.0,
                              contact_max_correcting_vel=0.0, cfm=0.0, erp=0.0, max_contacts=0),
        }

    def _rates(self) -> tuple[float, float]:
        """(time_step, max_update_rate): the loop's period [s] and cycles per wall-clock second."""
        period = self.loop.period_s
        return period, self.node.speed / period

    def _get_physics(self, req) -> GetPhysicsPropertiesResponse:
        if self.sim is None:
            return GetPhysicsPropertiesResponse(success=False,
                                                status_message="GetPhysicsProperties: " + self._not_simulated())
        snapshot = self._physics
        time_step, rate = self._rates()
        return GetPhysicsPropertiesResponse(
            time_step=time_step, pause=False, max_update_rate=rate, gravity=Vector3(*snapshot["gravity"]),
            ode_config=snapshot["ode"], success=True,
            status_message="GetPhysicsProperties: jointctl's MuJoCo world (ode_config: MuJoCo's nearest settings)")

    def _set_physics(self, req) -> SetPhysicsPropertiesResponse:
        if self.sim is None:
            return SetPhysicsPropertiesResponse(False, "SetPhysicsProperties: " + self._not_simulated())
        time_step, rate = self._rates()
        for field, asked, have, unit in (("time_step", req.time_step, time_step, "s"),
                                         ("max_update_rate", req.max_update_rate, rate, "Hz")):
            if not (math.isfinite(asked) and math.isclose(asked, have, rel_tol=1e-6, abs_tol=1e-12)):
                message = (f"SetPhysicsProperties: refused, nothing changed: {field}: jointctl's loop runs at "
                           f"{have:g} {unit} and cannot change it while running (got {asked:g}; send {have:g}, "
                           "as get_physics_properties reports)")
                rospy.logwarn("jointctl: %s", message)
                return SetPhysicsPropertiesResponse(False, message)
        gravity = (req.gravity.x, req.gravity.y, req.gravity.z)
        if not all(math.isfinite(g) for g in gravity):
            return SetPhysicsPropertiesResponse(False, "SetPhysicsProperties: refused, nothing changed: gravity: "
                                                       f"must be finite (got {list(gravity)})")
        ode_note = ""
        if req.ode_config != self._physics["ode"]:
            ode_note = "; ode_config not applied (jointctl runs MuJoCo, not ODE)"

        def apply(time_s: float) -> str:
            self.sim.set_gravity(gravity)
            self.manager.context.set_gravity(gravity)
            self._physics = self._physics_snapshot()
            return (f"SetPhysicsProperties: gravity ({gravity[0]:g}, {gravity[1]:g}, {gravity[2]:g}) m/s^2 "
                    f"from loop time {time_s:.3f} s{ode_note}")

        ok, message = self._submit(apply)
        (rospy.loginfo if ok else rospy.logwarn)("jointctl: %s", message)
        return SetPhysicsPropertiesResponse(ok, message if ok else f"SetPhysicsProperties: {message}")

    # -- model states (loop thread) ------------------------------------------------------------
    def _base_body(self) -> str | None:
        """The robot's base: its root link, or the root's first child when the root is the world."""
        robot = self.robot
        root = robot.root_link
        candidates = [root] + [j.child for j in robot.joints if j.parent == root]
        for link in candidates:
            if link != WORLD_BODY and self.sim.has_body(link):
                return link
        return None

    def _track(self) -> None:
        """The listed models' bodies (at start and whenever the world is rebuilt)."""
        identity = (np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
        tracked = []
        if self.sim.floor:
            tracked.append(_Tracked(GROUND_PLANE, WORLD_BODY, *identity))
        if self._base is not None:
            tracked.append(_Tracked(self.robot.name, self._base, *identity))
        for obj in self.sim.spawned:
            tracked.append(_Tracked(obj.name, obj.name, *self._frames.get(obj.name, identity)))
        self._tracked = tuple(tracked)

    def _publish_states(self, time_s: float) -> None:
        self._count += 1
        if self._count % self._every or not self._publisher.get_num_connections():
            return
        msg = ModelStates()
        for item in self._tracked:
            body_pos, body_quat, angular, body_linear = self.sim.body_state(item.body)
            # The model frame: the body's pose composed with the model frame's pose in the body;
            # its velocity in world axes, moved from the body's origin to the model frame.
            offset = _rotate(body_quat, item.frame_pos)
            pos = body_pos + offset
            quat = _multiply(body_quat, item.frame_quat)
            linear = body_linear + np.cross(angular, offset)
            pose = Pose()
            pose.position.x, pose.position.y, pose.position.z = pos
            pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z = quat
            twist = Twist()
            twist.linear.x, twist.linear.y, twist.linear.z = linear
            twist.angular.x, twist.angular.y, twist.angular.z = angular
            msg.name.append(item.name)
            msg.pose.append(pose)
            msg.twist.append(twist)
        self._publisher.publish(msg)


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` rotated by the unit quaternion ``q`` (w, x, y, z)."""
    w, u = q[0], q[1:]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def _multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The quaternion product ``a·b`` (w, x, y, z)."""
    return np.array([a[0] * b[0] - a[1:] @ b[1:], *(a[0] * b[1:] + b[0] * a[1:] + np.cross(a[1:], b[1:]))])


def attach_world_services(node) -> WorldServices:
    """Advertise the ``/gazebo`` world services and ``model_states`` for ``node`` (a RosNode)."""
    return WorldServices(node)


__all__ = ["APPLY_TIMEOUT_S", "MODEL_STATES_RATE_HZ", "WorldServices", "attach_world_services"]

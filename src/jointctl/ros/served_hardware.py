"""A robot served by another node on the ROS graph, as jointctl hardware: ``--hardware ros``.

The other node (``jointctl serve``, or a ros_control robot with the chapter's names) runs the
joints' controllers; this side sees what any ROS client sees:

- state: ``/<namespace>/joint_states`` (sensor_msgs/JointState: position [m or rad], velocity, and
  effort [N or N·m], the effort applied during the served loop's last period), stamped by the
  served node. :meth:`ServedRobotHardware.read` takes the newest message; every message is kept
  as well while :meth:`ServedRobotHardware.start_recording` is on, so an identification sees the
  publisher's full rate, whatever this side's loop does;
- commands: each joint's position (or velocity) reference goes to its controller's
  ``/<namespace>/<controller>/command`` (std_msgs/Float64), published when it changes. The joint
  has the ``position`` command interface when an ``effort_controllers/JointPositionController``
  commands it, ``velocity`` for a ``JointVelocityController``: the served loop servos it;
- gains: the controller's PID through its dynamic_reconfigure server ``<controller>/pid``
  (:meth:`ServedRobotHardware.gains`, :meth:`ServedRobotHardware.set_gains`).

The controllers are found on the parameter server, where the served node loaded its controller
YAML (``/<namespace>/<controller>/type`` and ``joint``); a controller counts only while some node
subscribes to its command topic (a started one). ``fault`` is set while no joint state arrives for
``stale_after_s``: then the hardware has nothing trustworthy to report.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import rosgraph
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from jointctl.errors import ConfigError, JointCtlError
from jointctl.hardware.interface import POSITION, VELOCITY, HardwareInterface
from jointctl.hardware.joint_state_inbox import JointStateInbox

#: ros_control controller types whose reference is a joint position / velocity.
LOOP_TYPES = {"effort_controllers/JointPositionController": POSITION,
              "effort_controllers/JointVelocityController": VELOCITY}


class ServedRobotHardware(HardwareInterface):
    """The served robot's joints ``joint_names`` under ``namespace`` (see the module docstring).
    ``controllers`` maps each commanded joint to ``(interface, controller name)``."""

    def __init__(self, namespace: str, joint_names: Sequence[str], controllers: dict[str, tuple[str, str]], *,
                 stale_after_s: float = 0.5) -> None:
        super().__init__(tuple(joint_names))
        self.namespace = namespace.strip("/")
        self.controllers = dict(controllers)
        self.stale_after_s = stale_after_s
        self._states = JointStateInbox(self.joint_names, f"/{self.namespace}/joint_states")
        self._publishers = {joint: rospy.Publisher(f"/{self.namespace}/{name}/command", Float64, queue_size=10)
                            for joint, (_, name) in self.controllers.items()}
        self._sent: dict[str, float] = {}
        # (joint, its command list, its index, its publisher): resolved once, used every cycle by write().
        self._outputs = [(joint, self.command_buffer(interface), self.joint_index(joint), self._publishers[joint])
                         for joint, (interface, _) in self.controllers.items()]
        #: Each loop's reference when this side connected (joint -> value or None), restored on leaving.
        self.set_points: dict[str, float | None] = {}
        self.fault = "no joint state yet"
        # rospy drops the oldest messages once its queue is full: 100 was a tenth of a second at the
        # publisher's 1 kHz, and a busy machine stalls this process's callbacks longer than that
        # (identification then refused its recording for the gap). Ten seconds' worth is held instead.
        self._subscriber = rospy.Subscriber(f"/{self.namespace}/joint_states", JointState, self._on_state,
                                            queue_size=10_000, tcp_nodelay=True)

    # -- state -------------------------------------------------------------------------------------
    def _on_state(self, msg: JointState) -> None:
        self._states.take(msg.name, msg.header.stamp.to_sec(), msg.position, msg.velocity, msg.effort)

    def wait_for_subscribers(self, timeout_s: float = 5.0) -> None:
        """Block until the served node has connected to every command topic: a message published
        before that is lost, and a reference is published only when it changes."""
        deadline = time.monotonic() + timeout_s
        for publisher in self._publishers.values():
            while publisher.get_num_connections() == 0:
                if time.monotonic() > deadline:
                    raise JointCtlError(f"no node connected to the command topic within {timeout_s:g} s",
                                        field=publisher.resolved_name, value=None)
                time.sleep(0.01)

    def wait_for_state(self, timeout_s: float = 5.0) -> None:
        """Block until a joint state naming every joint has arrived; a clear error otherwise."""
        deadline = time.monotonic() + timeout_s
        while not self._states.complete():
            if time.monotonic() > deadline:
                raise self._states.missing_error(timeout_s, "is the robot served? jointctl serve ROBOT")
            time.sleep(0.02)
        self.read()

    def start_recording(self) -> None:
        """Keep every joint state from now on (see :meth:`recorded`)."""
        self._states.start_recording()

    def recorded(self, joint: str) -> tuple[list[float], list[float], list[float], list[float]]:
        """(stamp [s], position, velocity, effort) of ``joint`` in every joint state kept since
        :meth:`start_recording`; recording stops."""
        k = self.joint_index(joint)
        stamps, positions, velocities, efforts = self.recorded_all(joint)
        return stamps, [r[k] for r in positions], [r[k] for r in velocities], [r[k] for r in efforts]

    def recorded_all(self, joint: str) -> tuple[list[float], list[tuple], list[tuple], list[tuple]]:
        """(stamp [s], positions, velocities, efforts) of every joint state kept since
        :meth:`start_recording`, each a row of the joints in :attr:`joint_names`' order (the chain's
        motion, which loads ``joint``); recording stops. Refused when a state lacks the joints'
        velocities or ``joint``'s effort (identification needs them)."""
        return self._states.recorded_all(self.joint_index(joint))

    def read(self) -> None:
        self.fault = self._states.read_into(self.position, self.velocity, self.effort, self.stale_after_s)

    # -- commands ----------------------------------------------------------------------------------
    def command_interfaces(self, joint: str) -> frozenset[str]:
        self.joint_index(joint)
        entry = self.controllers.get(joint)
        return frozenset({entry[0]}) if entry else frozenset()

    def write(self) -> None:
        for joint, command, index, publisher in self._outputs:
            value = command[index]
            if self._sent.get(joint) != value:
                publisher.publish(Float64(value))
                self._sent[joint] = value

    def joint_of(self, controller: str) -> str:
        """The joint ``controller`` commands; a ConfigError naming ``--controller`` if none here."""
        for joint, (_, name) in self.controllers.items():
            if name == controller:
                return joint
        raise ConfigError("not a loop of this hardware", field="--controller", value=controller)

    def advance(self, period_s: float) -> None:
        """Nothing: the served robot runs on its own clock (pace the loop with the wall clock)."""

    def hold(self, references: dict[str, float] | None = None) -> None:
        """Make each commanded joint's reference ``references[joint]`` (the loop's own set point, read
        from its ``state`` topic by :func:`connect`) or else where it is (a position loop) or at rest
        (a velocity loop), so that writing it moves nothing."""
        self.read()
        for joint, (interface, _) in self.controllers.items():
            k = self.joint_index(joint)
            given = (references or {}).get(joint)
            if given is None:
                given = self.position[k] if interface == POSITION else 0.0
            self.command_buffer(interface)[k] = given

    def close(self) -> None:
        """Send the commands written last (a publisher sends from its own thread) and leave the topics."""
        time.sleep(0.3)
        self._subscriber.unregister()
        for publisher in self._publishers.values():
            publisher.unregister()

    # -- gains -------------------------------------------------------------------------------------
    def gains(self, controller: str) -> dict:
        """The controller's PID gains as its dynamic_reconfigure server holds them."""
        return {k: float(v) for k, v in self._reconfigure(controller).get_configuration(timeout=5.0).items()
                if k in ("p", "i", "d")}

    def set_gains(self, controller: str, gains: dict) -> dict:
        """Change the controller's ``p``, ``i``, ``d`` on the served node; the configuration it answers."""
        answered = self._reconfigure(controller).update_configuration({k: float(gains[k]) for k in ("p", "i", "d")})
        if any(abs(float(answered[k]) - float(gains[k])) > 1e-9 * max(1.0, abs(gains[k])) for k in ("p", "i", "d")):
            raise JointCtlError("the served node refused the gains (it answered its previous ones)",
                                field=f"/{self.namespace}/{controller}/pid", value=gains)
        return answered

    def controller_parameters(self) -> dict:
        """The served node's controller parameters (``/<namespace>`` on the parameter server: its
        controller YAML as loaded, with the gains as they are now)."""
        return rospy.get_param(f"/{self.namespace}")

    def _reconfigure(self, controller: str):
        from dynamic_reconfigure.client import Client

        server = f"/{self.namespace}/{controller}/pid"
        try:
            return Client(server, timeout=5.0)
        except rospy.ROSException:
            raise JointCtlError("no dynamic_reconfigure server answers (is the controller started?)",
                                field="--controller", value=server) from None


def served_controllers(namespace: str, joint_names: Sequence[str]) -> dict[str, tuple[str, str]]:
    """The served node's started joint loops: ``{controller: (joint, interface)}`` read from the
    parameter server (``/<namespace>/<controller>/type``, ``joint``) and kept when some node
    subscribes to ``/<namespace>/<controller>/command``."""
    ns = namespace.strip("/")
    try:
        tree = rospy.get_param(f"/{ns}")
    except KeyError:
        raise JointCtlError("no controller parameters on the parameter server (is the robot served?)",
                            field="namespace", value=f"/{ns}") from None
    _, subscribers, _ = rosgraph.Master("/jointctl_served").getSystemState()
    subscribed = {topic for topic, nodes in subscribers if nodes}
    found = {}
    for name, spec in (tree.items() if isinstance(tree, dict) else ()):
        if not isinstance(spec, dict) or spec.get("type") not in LOOP_TYPES:
            continue
        if spec.get("joint") in joint_names and f"/{ns}/{name}/command" in subscribed:
            found[name] = (spec["joint"], LOOP_TYPES[spec["type"]])
    return found


def served_description(namespace: str | None = None) -> tuple[str, str]:
    """(URDF text, parameter name) of the served robot's model: ``/<namespace>/robot_description``
    when there is one, else ``/robot_description`` (where ``jointctl serve`` and ros_control's
    launch files load it); a ConfigError when neither is set."""
    from jointctl.ros.clients import init_client_node

    init_client_node("jointctl_tools")
    names = ([f"/{namespace.strip('/')}/robot_description"] if namespace else []) + ["/robot_description"]
    for name in names:
        if rospy.has_param(name):
            text = rospy.get_param(name)
            if isinstance(text, str) and text.strip():
                return text, name
    raise ConfigError("no robot model on the parameter server (is the robot served?); give its .urdf/.xacro or "
                      "robot folder as the target", field="robot_description", value=" or ".join(names))


def served_namespaces(joint_names: Sequence[str]) -> list[str]:
    """The namespaces on the parameter server that hold joint loops (``LOOP_TYPES``) of any of
    ``joint_names``: where a served robot's controllers are (``one_DOF_robot`` for the chapter's)."""
    from jointctl.ros.clients import init_client_node

    init_client_node("jointctl_tools")
    tree = rospy.get_param("/")
    found = []
    for ns, body in (tree.items() if isinstance(tree, dict) else ()):
        if isinstance(body, dict) and any(isinstance(c, dict) and c.get("type") in LOOP_TYPES
                                          and c.get("joint") in joint_names for c in body.values()):
            found.append(ns)
    return sorted(found)


def connect(namespace: str, joint_names: Sequence[str], controller: str | None = None, *,
            joint: str | None = None) -> tuple[ServedRobotHardware, str]:
    """Join the graph and return (hardware, controller name) for ``controller``, or for ``joint``'s
    started position loop; a ConfigError naming the flag when there is none."""
    from jointctl.ros.clients import init_client_node

    init_client_node("jointctl_tools")
    loops = served_controllers(namespace, joint_names)
    started = ", ".join(sorted(loops)) or "none"
    if controller is None:
        candidates = [n for n, (j, kind) in loops.items() if j == joint and kind == POSITION]
        if not candidates:
            raise ConfigError(f"no started position controller commands it on /{namespace.strip('/')} "
                              f"(started joint loops: {started})", field="--joint", value=joint)
        controller = sorted(candidates)[0]
    elif controller not in loops:
        raise ConfigError(f"not a started joint position or velocity controller on /{namespace.strip('/')} "
                          f"(started: {started})", field="--controller", value=controller)
    joint_of, interface = loops[controller]
    hardware = ServedRobotHardware(namespace, joint_names, {joint_of: (interface, controller)})
    hardware.wait_for_state()
    hardware.wait_for_subscribers()
    hardware.set_points = {joint_of: set_point(namespace, controller)}
    hardware.hold(hardware.set_points)
    return hardware, controller


def set_point(namespace: str, controller: str, timeout_s: float = 2.0) -> float | None:
    """The loop's reference now, from its ``state`` topic (control_msgs/JointControllerState), or
    None when it publishes none: the reference this side starts from (a loop under gravity does not
    rest at its reference, so the measured position would move it)."""
    from control_msgs.msg import JointControllerState

    try:
        msg = rospy.wait_for_message(f"/{namespace.strip('/')}/{controller}/state", JointControllerState,
                                     timeout=timeout_s)
    except rospy.ROSException:
        return None
    return float(msg.set_point)


__all__ = ["LOOP_TYPES", "ServedRobotHardware", "connect", "served_controllers", "served_description",
           "served_namespaces"]

"""A ros2_control robot on the ROS 2 graph, as jointctl hardware: ``--hardware ros2``.

The robot's ``controller_manager`` runs its joints' controllers; this side sees what any ROS 2 client
sees, under the robot's namespace (``""`` for the root):

- state: ``/joint_states`` (sensor_msgs/msg/JointState, from its ``joint_state_broadcaster``):
  position [m or rad], velocity and effort, stamped by the controller manager at the cycle that read
  them. :meth:`ServedRos2Hardware.read` takes the newest message; every message is kept as well while
  :meth:`ServedRos2Hardware.start_recording` is on. A NaN (an interface the joint lacks) counts as
  missing;
- the loops: the active controllers the controller manager lists (``list_controllers``), read from
  their parameters:

  * ``pid_controller/PidController``: a loop on each of its ``reference_and_state_dof_names`` (else
    ``dof_names``), of the quantity ``reference_and_state_interfaces[0]`` (``position`` or
    ``velocity``) it servos, driving the hardware's ``command_interface`` (its *actuation*: effort,
    acceleration, velocity...). The reference goes to ``~/reference`` (control_msgs/msg/MultiDOFCommand,
    best effort, depth 1: it is sent again every ``REPEAT_S`` while it holds), every other dof NaN
    (kept where it is) and ``values_dot`` NaN: a plain position reference, on which the controller
    differentiates the error (control_toolbox's ``Pid::computeCommand``). Its gains are the parameters
    ``gains.<dof>.p|i|d|i_clamp_max|i_clamp_min|antiwindup|feedforward_gain|angle_wraparound``, read and
    written through the controller node's parameter services; a chained pid_controller (its reference
    from another controller) is no loop of this side's;
  * the forward command controllers (``forward_command_controller/ForwardCommandController`` and the
    ``JointGroup*Controller`` of position_controllers and velocity_controllers) with the ``position``
    or ``velocity`` interface: the hardware's own servo of that joint, no gains. The command goes to
    ``~/commands`` (std_msgs/msg/Float64MultiArray, one value per joint of its ``joints``, the others
    held where they were when this side connected, or at rest).

``fault`` is set while no joint state arrives for ``stale_after_s``. :meth:`ServedRos2Hardware.close`
sends the last reference again and, when this side set gains, puts back every gain parameter of the loop
that is not as it was found (a change someone else made while a tool only measured is left alone).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

from control_msgs.msg import MultiDOFCommand, MultiDOFStateStamped
from controller_manager_msgs.srv import ListControllers
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String

from jointctl.errors import ConfigError, JointCtlError
from jointctl.hardware.interface import POSITION, VELOCITY, HardwareInterface
from jointctl.hardware.joint_state_inbox import JointStateInbox
from jointctl.ros2.graph_client import GraphClient

PID_TYPE = "pid_controller/PidController"
#: Forward command controllers: their ``interface_name`` (None: read it from the parameter).
FORWARD_TYPES = {"forward_command_controller/ForwardCommandController": None,
                 "position_controllers/JointGroupPositionController": POSITION,
                 "velocity_controllers/JointGroupVelocityController": VELOCITY}
#: A pid_controller's gain parameters per dof (``gains.<dof>.<name>``), as control_toolbox's PidROS declares them.
GAIN_NAMES = ("p", "i", "d", "i_clamp_max", "i_clamp_min", "antiwindup", "feedforward_gain", "angle_wraparound")
#: A held reference is sent again this often [s]: best effort may drop one, and the controller keeps the last.
REPEAT_S = 0.05


@dataclass(frozen=True)
class Ros2Loop:
    """One joint's loop on the robot: ``controller`` (its name) of ``type`` servos ``joint``'s
    ``interface`` (POSITION or VELOCITY: what this side writes, the loop's reference), driving the
    hardware's ``actuation`` command interface; ``dofs`` are the controller's dofs (or joints) in the order
    its messages carry them, ``command_dof`` the one that commands ``joint`` (a pid_controller's
    ``dof_names`` entry, whose gains these are); ``chained`` when another controller gives its reference."""

    controller: str
    type: str
    joint: str
    interface: str
    actuation: str
    dofs: tuple[str, ...]
    command_dof: str
    chained: bool = False

    @property
    def has_gains(self) -> bool:
        return self.type == PID_TYPE


def node_name(namespace: str, name: str) -> str:
    """The graph name of ``name`` under ``namespace`` (``/ns/name``, or ``/name`` at the root)."""
    ns = namespace.strip("/")
    return f"/{ns}/{name}" if ns else f"/{name}"


def served_loops(graph: GraphClient, namespace: str, joint_names: Sequence[str]) -> dict[str, list[Ros2Loop]]:
    """The active controllers of the robot's controller manager that servo any of ``joint_names``:
    ``{controller: [its loops]}`` (see the module docstring)."""
    manager = node_name(namespace, "controller_manager")
    response = graph.call(ListControllers, f"{manager}/list_controllers", ListControllers.Request())
    found: dict[str, list[Ros2Loop]] = {}
    for state in response.controller:
        if state.state != "active":
            continue
        node = node_name(namespace, state.name)
        if state.type == PID_TYPE:
            p = graph.get_parameters(node, ["dof_names", "reference_and_state_dof_names", "command_interface",
                                            "reference_and_state_interfaces"])
            dofs = tuple(p.get("dof_names") or ())
            servoed = tuple(p.get("reference_and_state_dof_names") or ()) or dofs
            interfaces = p.get("reference_and_state_interfaces") or [POSITION]
            if interfaces[0] not in (POSITION, VELOCITY) or len(servoed) != len(dofs):
                continue
            loops = [Ros2Loop(state.name, state.type, joint, interfaces[0], str(p.get("command_interface", "")),
                              servoed, command_dof, bool(state.is_chained))
                     for joint, command_dof in zip(servoed, dofs) if joint in joint_names]
        elif state.type in FORWARD_TYPES:
            p = graph.get_parameters(node, ["joints", "interface_name"])
            interface = FORWARD_TYPES[state.type] or p.get("interface_name")
            joints = tuple(p.get("joints") or ())
            if interface not in (POSITION, VELOCITY):
                continue
            loops = [Ros2Loop(state.name, state.type, joint, interface, interface, joints, joint)
                     for joint in joints if joint in joint_names]
        else:
            continue
        if loops:
            found[state.name] = loops
    return found


class ServedRos2Hardware(HardwareInterface):
    """The robot's joints ``joint_names`` under ``namespace`` (see the module docstring), through
    ``graph``, commanding ``loop``'s joint. Owns ``graph``: :meth:`close` closes it."""

    def __init__(self, graph: GraphClient, namespace: str, joint_names: Sequence[str], loop: Ros2Loop, *,
                 stale_after_s: float = 0.5) -> None:
        super().__init__(tuple(joint_names))
        self.graph = graph
        self.namespace = namespace.strip("/")
        self.loop = loop
        #: joint -> (interface, controller): the commanded joint, as ``--hardware ros``'s hardware has it.
        self.controllers = {loop.joint: (loop.interface, loop.controller)}
        self.stale_after_s = stale_after_s
        self._states = JointStateInbox(self.joint_names, self._topic("joint_states"))
        self._commanded = self.joint_index(loop.joint)
        self._command = self.command_buffer(loop.interface)
        self._sent: float | None = None
        self._sent_at = -math.inf
        #: The other dofs' commands of a forward command controller (joint -> value), held as found.
        self._others: dict[str, float] = {}
        #: The loop's reference when this side connected (joint -> value or None), put back on leaving.
        self.set_points: dict[str, float | None] = {}
        #: The loop's gain parameters as found (parameter name -> value), put back on leaving if this side set any.
        self.gains_found: dict[str, object] = {}
        self._gains_set = False
        self.fault = "no joint state yet"
        node = graph.node
        topic = self._topic("joint_states")
        # Every state is kept for identification: a deep queue (the publisher sends every cycle).
        self._subscription = node.create_subscription(
            JointState, topic, self._on_state,
            QoSProfile(depth=10_000, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE))
        if loop.has_gains:
            self._publisher = node.create_publisher(
                MultiDOFCommand, self._topic(f"{loop.controller}/reference"),
                QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        else:
            self._publisher = node.create_publisher(Float64MultiArray, self._topic(f"{loop.controller}/commands"),
                                                    QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))

    def _topic(self, name: str) -> str:
        return node_name(self.namespace, name)

    @property
    def controller_node(self) -> str:
        return self._topic(self.loop.controller)

    # -- state -------------------------------------------------------------------------------------
    def _on_state(self, msg: JointState) -> None:
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        self._states.take(msg.name, stamp, msg.position, msg.velocity, msg.effort)

    def wait_for_state(self, timeout_s: float = 5.0) -> None:
        """Block until a joint state naming every joint has arrived; a clear error otherwise."""
        if not self.graph.wait(self._states.complete, timeout_s):
            raise self._states.missing_error(timeout_s, "is a joint_state_broadcaster active?")
        self.read()

    def reports_effort(self, joint: str) -> bool:
        """Whether the newest joint state carries ``joint``'s effort (a number, not NaN or left out)."""
        effort = self._states.effort_of(self.joint_index(joint))
        return effort is not None and math.isfinite(effort)

    def wait_for_subscribers(self, timeout_s: float = 5.0) -> None:
        """Block until the controller subscribes to what this side publishes."""
        if not self.graph.wait(lambda: self._publisher.get_subscription_count() > 0, timeout_s):
            raise JointCtlError(f"the controller did not subscribe within {timeout_s:g} s",
                                field=self._publisher.topic_name, value=None)

    def start_recording(self) -> None:
        """Keep every joint state from now on (see :meth:`recorded_all`)."""
        self._states.start_recording()

    def recorded_all(self, joint: str) -> tuple[list[float], list[tuple], list[tuple], list[tuple]]:
        """(stamp [s], positions, velocities, efforts) of every joint state kept since
        :meth:`start_recording`, each a row of the joints in :attr:`joint_names`' order; recording stops.
        Refused when a state lacks the joints' velocities or ``joint``'s effort (identification needs them)."""
        return self._states.recorded_all(self.joint_index(joint))

    def read(self) -> None:
        self.fault = self._states.read_into(self.position, self.velocity, self.effort, self.stale_after_s)

    # -- commands ----------------------------------------------------------------------------------
    def command_interfaces(self, joint: str) -> frozenset[str]:
        self.joint_index(joint)
        return frozenset({self.loop.interface}) if joint == self.loop.joint else frozenset()

    def write(self) -> None:
        value = self._command[self._commanded]
        now = time.monotonic()
        if value != self._sent or now - self._sent_at > REPEAT_S:
            self._send(value)
            self._sent, self._sent_at = value, now

    def _send(self, value: float) -> None:
        loop = self.loop
        if value != value:  # NaN: nothing to send
            return
        if loop.has_gains:
            values = [value if dof == loop.joint else math.nan for dof in loop.dofs]
            self._publisher.publish(MultiDOFCommand(dof_names=list(loop.dofs), values=values,
                                                    values_dot=[math.nan] * len(loop.dofs)))
        else:
            values = [value if dof == loop.joint else self._others.get(dof, 0.0) for dof in loop.dofs]
            self._publisher.publish(Float64MultiArray(data=values))

    def joint_of(self, controller: str) -> str:
        """The joint ``controller`` commands; a ConfigError naming ``--controller`` if none here."""
        if controller == self.loop.controller:
            return self.loop.joint
        raise ConfigError("not a loop of this hardware", field="--controller", value=controller)

    def advance(self, period_s: float) -> None:
        """Nothing: the robot runs on its own clock (pace the loop with the wall clock)."""

    def hold(self, references: dict[str, float] | None = None) -> None:
        """Make the loop's reference ``references[joint]`` (the reference it held when this side
        connected) or else where the joint is (a position loop) or rest (a velocity loop); the other
        joints of a forward command controller where they are (position) or at rest (velocity)."""
        self.read()
        given = (references or {}).get(self.loop.joint)
        if given is None:
            given = self.position[self._commanded] if self.loop.interface == POSITION else 0.0
        self._command[self._commanded] = given
        if not self.loop.has_gains and not self._others:
            for dof in self.loop.dofs:
                if dof != self.loop.joint and dof in self.joint_names:
                    self._others[dof] = (self.position[self.joint_index(dof)]
                                         if self.loop.interface == POSITION else 0.0)

    def close(self) -> None:
        """Send the last reference a few times more (best effort), put back the gains found changed,
        and leave the graph."""
        try:
            value = self._command[self._commanded]
            for _ in range(5):
                self._send(value)
                time.sleep(0.02)
            self.restore_gains()
        finally:
            self.graph.close()

    # -- gains -------------------------------------------------------------------------------------
    def _gain_parameters(self) -> list[str]:
        return [f"gains.{self.loop.command_dof}.{name}" for name in GAIN_NAMES]

    def read_gains_found(self) -> None:
        """Remember the loop's gain parameters as they are now: :meth:`restore_gains` puts them back."""
        if self.loop.has_gains:
            self.gains_found = self.graph.get_parameters(self.controller_node, self._gain_parameters())

    def restore_gains(self) -> None:
        """Set back every gain parameter that differs from what :meth:`read_gains_found` found, when this side
        set gains (:meth:`set_gains`)."""
        if not self.gains_found or not self._gains_set:
            return
        now = self.graph.get_parameters(self.controller_node, list(self.gains_found))
        changed = {k: v for k, v in self.gains_found.items() if now.get(k) != v}
        if changed:
            self.graph.set_parameters(self.controller_node, changed)

    def gains(self, controller: str) -> dict | None:
        """The loop's PID gains ``{"p", "i", "d"}`` as the controller's parameters hold them now; None for a
        forward command controller (the hardware's own loop: no gains of ROS's)."""
        self.joint_of(controller)
        if not self.loop.has_gains:
            return None
        names = [f"gains.{self.loop.command_dof}.{k}" for k in ("p", "i", "d")]
        found = self.graph.get_parameters(self.controller_node, names)
        return {k: float(found.get(name, 0.0)) for k, name in zip(("p", "i", "d"), names)}

    def set_gains(self, controller: str, gains: dict) -> dict:
        """Set the loop's ``p``, ``i``, ``d`` as the controller's parameters, and any other of its gain
        parameters ``gains`` names (``i_clamp_max``, ``i_clamp_min``, ``antiwindup``: :data:`GAIN_NAMES`); the
        gains ``{"p", "i", "d"}`` it then holds."""
        self.joint_of(controller)
        if not self.loop.has_gains:
            raise ConfigError("a forward command controller has no gains (the hardware servos the joint)",
                              field="--controller", value=controller)
        unknown = sorted(set(gains) - set(GAIN_NAMES))
        if unknown:
            raise ConfigError(f"pid_controller's gains are {', '.join(GAIN_NAMES)}", field="gains", value=unknown[0])
        self._gains_set = True
        values = {k: (bool(v) if isinstance(v, bool) else float(v)) for k, v in gains.items()}
        # The clamps before i: the controller never runs an integral under the clamps it is leaving.
        order = sorted(values, key=lambda k: k in ("p", "i", "d"))
        self.graph.set_parameters(self.controller_node, {f"gains.{self.loop.command_dof}.{k}": values[k]
                                                         for k in order})
        answered = self.gains(controller)
        if any(abs(answered[k] - float(gains[k])) > 1e-9 * max(1.0, abs(gains[k])) for k in ("p", "i", "d")):
            raise JointCtlError("the controller kept other gains than those set", field=self.controller_node,
                                value=gains)
        return answered

    def controller_parameters(self) -> dict:
        """``{controller: {"type": ..., its parameters...}}``: the loop's controller as it runs now (no
        ``derivative``: a pid_controller fed a plain position reference differentiates the error)."""
        loop = self.loop
        entry: dict = {"type": loop.type}
        if loop.has_gains:
            names = ["dof_names", "reference_and_state_dof_names", "command_interface",
                     "reference_and_state_interfaces", *[f"gains.{dof}.{g}" for dof in loop.dofs for g in GAIN_NAMES]]
            for name, value in self.graph.get_parameters(self.controller_node, names).items():
                where = entry
                *path, leaf = name.split(".")
                for part in path:
                    where = where.setdefault(part, {})
                where[leaf] = value
        else:
            entry.update(self.graph.get_parameters(self.controller_node, ["joints", "interface_name"]))
        return {loop.controller: entry}

    def tuned_parameters(self, controller: str, gains: dict) -> tuple[str, dict]:
        """(file name, document) of the loop's controller with ``gains`` as a ros2_control parameters
        file (``<controller>: {ros__parameters: ...}``, for ``--params-file``)."""
        parameters = self.controller_parameters()[controller]
        parameters.pop("type")
        dof = parameters.setdefault("gains", {}).setdefault(self.loop.command_dof, {})
        dof.update({k: v if isinstance(v, bool) else round(float(v), 6) for k, v in gains.items()})
        return f"{controller}_tuned.yaml", {controller: {"ros__parameters": parameters}}

    def reference_now(self, timeout_s: float = 2.0) -> float | None:
        """The pid_controller's reference for the joint now, from its ``~/controller_state``; None when
        it has none yet (NaN), publishes none, or for a forward command controller."""
        if not self.loop.has_gains:
            return None
        got: list = []
        done = threading.Event()

        def take(msg: MultiDOFStateStamped) -> None:
            got.append(msg)
            done.set()

        subscription = self.graph.node.create_subscription(MultiDOFStateStamped,
                                                           self._topic(f"{self.loop.controller}/controller_state"),
                                                           take, 10)
        try:
            done.wait(timeout_s)
        finally:
            self.graph.node.destroy_subscription(subscription)
        for state in (got[0].dof_states if got else ()):
            if state.name == self.loop.joint and math.isfinite(state.reference):
                return float(state.reference)
        return None


def served_description(graph: GraphClient, namespace: str = "", timeout_s: float = 5.0) -> tuple[str, str]:
    """(URDF text, topic) of the robot's model, from its ``/robot_description`` (transient local, as
    robot_state_publisher keeps it); a ConfigError when none arrives."""
    topic = node_name(namespace, "robot_description")
    msg = graph.latched(String, topic, timeout_s)
    if msg is None or not msg.data.strip():
        raise ConfigError(f"no robot model on the ROS 2 graph within {timeout_s:g} s (is robot_state_publisher "
                          "running?); give its .urdf/.xacro or robot folder as the target", field="robot_description",
                          value=topic)
    return msg.data, topic


def update_period(graph: GraphClient, namespace: str, controller: str) -> float:
    """The loop's period [s]: its controller's ``update_rate`` [Hz] when set, else its controller
    manager's."""
    for node in (node_name(namespace, controller), node_name(namespace, "controller_manager")):
        rate = graph.get_parameters(node, ["update_rate"]).get("update_rate")
        if isinstance(rate, (int, float)) and rate > 0:
            return 1.0 / float(rate)
    raise JointCtlError("the controller manager has no update_rate", field="update_rate",
                        value=node_name(namespace, "controller_manager"))


def connect(namespace: str, joint_names: Sequence[str], controller: str | None = None, *,
            joint: str | None = None, graph: GraphClient | None = None, accept=None) -> ServedRos2Hardware:
    """Join the graph (or use ``graph``) and return the hardware commanding ``controller``'s loop of
    ``joint`` (its only one when ``joint`` is None), or ``joint``'s position loop when ``controller`` is
    None; a ConfigError naming the flag when there is none, or when ``accept(loop)`` raises one. Nothing
    is published before the loop is found and accepted. The loop then holds the reference it had (a
    pid_controller's), else where the joint is."""
    graph = graph or GraphClient()
    try:
        loops = served_loops(graph, namespace, joint_names)
        loop = _pick(loops, namespace, controller, joint)
        if accept is not None:
            accept(loop)
        hardware = ServedRos2Hardware(graph, namespace, joint_names, loop)
    except BaseException:
        graph.close()
        raise
    try:
        hardware.wait_for_state()
        hardware.wait_for_subscribers()
        hardware.read_gains_found()
        hardware.set_points = {loop.joint: hardware.reference_now()}
        hardware.hold(hardware.set_points)
        hardware.write()
    except BaseException:
        hardware.close()
        raise
    return hardware


def _pick(loops: dict[str, list[Ros2Loop]], namespace: str, controller: str | None, joint: str | None) -> Ros2Loop:
    where = node_name(namespace, "controller_manager")
    listed = ", ".join(f"{name} ({', '.join(loop.joint for loop in found)})" for name, found in sorted(loops.items()))
    listed = listed or "none"
    if controller is None:
        candidates = [loop for found in loops.values() for loop in found
                      if loop.joint == joint and loop.interface == POSITION and not loop.chained]
        if not candidates:
            raise ConfigError(f"no active position loop of {where} servos it (active loops: {listed})",
                              field="--joint", value=joint)
        return sorted(candidates, key=lambda loop: loop.controller)[0]
    if controller not in loops:
        raise ConfigError(f"not an active pid_controller or position/velocity forward command controller of {where} "
                          f"(active loops: {listed})", field="--controller", value=controller)
    found = loops[controller]
    if joint is not None:
        found = [loop for loop in found if loop.joint == joint]
        if not found:
            raise ConfigError(f"{controller} does not servo it", field="--joint", value=joint)
    if len(found) > 1:
        raise ConfigError(f"servos {', '.join(loop.joint for loop in found)}: give --joint", field="--controller",
                          value=controller)
    if found[0].chained:
        raise ConfigError("is chained: another controller gives its reference", field="--controller",
                          value=controller)
    return found[0]


__all__ = ["FORWARD_TYPES", "GAIN_NAMES", "PID_TYPE", "Ros2Loop", "ServedRos2Hardware", "connect", "node_name",
           "served_description", "served_loops", "update_period"]

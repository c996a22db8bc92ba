"""ros2_control's controller manager services on jointctl's :class:`~jointctl.control.manager.ControllerManager`.

Under ``/controller_manager`` (controller_manager_msgs/srv), what ``ros2 control`` and the spawner call:

- ``list_controllers``: every loaded controller, its YAML type, ``active`` or ``inactive``, its claimed and
  required interfaces as ``<joint>/<interface>``;
- ``list_controller_types``: the types jointctl loads (base class ``controller_interface::ControllerInterface``);
- ``list_hardware_interfaces``: each joint's command interfaces (``<joint>/effort``: jointctl's robots take
  efforts) with whether a running controller claims it, and its ``position``, ``velocity``, ``effort`` states;
- ``list_hardware_components``: the one hardware component (the simulated robot, or the hardware jointctl runs);
- ``load_controller``, ``configure_controller``: a controller defined in the controller file is built (loading
  configures it, as jointctl's manager does); one that is not defined is refused (``ok: false``);
- ``switch_controller``: deactivates then activates, at the start of the loop's next cycle, all or nothing
  (STRICT) or as much as can be (BEST_EFFORT), as ros2_control does; answered once the loop has done it;
- ``unload_controller``: refused for an active controller (as ros2_control refuses it), else ok.

Its parameter ``update_rate`` [Hz] (an integer, as ros2_control declares it) is the loop's rate, which a ROS 2
client reads as a ros2_control robot's (jointctl's tools with ``--hardware ros2`` do); read-only: jointctl's loop
keeps the rate it started with.

A refusal is logged with its reason. The loop's state is touched only in the loop thread: requests wait for it.
"""

from __future__ import annotations

import queue
import threading

from controller_manager_msgs.msg import ControllerState, HardwareComponentState, HardwareInterface
from controller_manager_msgs.srv import (ConfigureController, ListControllers, ListControllerTypes,
                                         ListHardwareComponents, ListHardwareInterfaces, LoadController,
                                         SwitchController, UnloadController)
from lifecycle_msgs.msg import State
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node

from jointctl.errors import JointCtlError

BASE_CLASS = "controller_interface::ControllerInterface"
SWITCH_WAIT_S = 10.0  # how long a switch request waits for the loop to take it [s]


class ControllerManagerServices:
    """The services of ``/controller_manager`` for ``session`` (see the module's docstring)."""

    def __init__(self, node: Node, session) -> None:
        self.node, self.session = node, session
        self.manager = session.manager
        self._requests: queue.SimpleQueue = queue.SimpleQueue()
        session.loop.add_input(self._apply_requests)
        node.declare_parameter("update_rate", int(round(1.0 / session.loop.period_s)),
                               ParameterDescriptor(read_only=True, description="the control loop's rate [Hz]"))
        group = ReentrantCallbackGroup()
        for kind, name, callback in (
                (ListControllers, "list_controllers", self._list_controllers),
                (ListControllerTypes, "list_controller_types", self._list_types),
                (ListHardwareInterfaces, "list_hardware_interfaces", self._list_interfaces),
                (ListHardwareComponents, "list_hardware_components", self._list_components),
                (LoadController, "load_controller", self._load),
                (ConfigureController, "configure_controller", self._load),
                (UnloadController, "unload_controller", self._unload),
                (SwitchController, "switch_controller", self._switch)):
            node.create_service(kind, f"~/{name}", callback, callback_group=group)

    # -- the loop thread ----------------------------------------------------------------------
    def _apply_requests(self, time_s: float) -> None:
        while True:
            try:
                run = self._requests.get_nowait()
            except queue.Empty:
                return
            run(time_s)

    def _in_loop(self, work):
        """Run ``work(time_s)`` in the loop thread at the start of its next cycle; its return value (raises
        what it raised)."""
        answer: list = []
        done = threading.Event()

        def run(time_s: float) -> None:
            try:
                answer.append(work(time_s))
            except Exception as exc:  # noqa: BLE001 - handed back to the service thread, raised there
                answer.append(exc)
            finally:
                done.set()

        self._requests.put(run)
        if not done.wait(SWITCH_WAIT_S):
            raise JointCtlError("the control loop did not take the request", field="controller_manager")
        if isinstance(answer[0], Exception):
            raise answer[0]
        return answer[0]

    # -- services (executor threads) ------------------------------------------------------------
    def _state(self, controller) -> ControllerState:
        active = controller in self.manager.active
        claimed = [f"{target}/{interface}" for target, interface in controller.claimed_interfaces()]
        state = ControllerState(name=controller.name, state="active" if active else "inactive",
                                type=self.manager.type_of(controller.name))
        state.claimed_interfaces = claimed if active else []
        state.required_command_interfaces = claimed
        state.required_state_interfaces = [f"{j}/{i}" for j in getattr(controller, "joints", ())
                                           for i in ("position", "velocity")]
        return state

    def _list_controllers(self, _request, response):
        response.controller = [self._state(c) for c in self.manager.loaded()]
        return response

    def _list_types(self, _request, response):
        response.types = sorted(self.manager.types)
        response.base_classes = [BASE_CLASS] * len(response.types)
        return response

    def _interfaces(self):
        hardware = self.session.hardware
        claimed = {claim for c in self.manager.active for claim in c.claimed_interfaces()}
        commands = [HardwareInterface(name=f"{joint}/{interface}", is_available=True,
                                      is_claimed=(joint, interface) in claimed)
                    for joint in hardware.joint_names for interface in hardware.command_interfaces(joint)]
        states = [HardwareInterface(name=f"{joint}/{interface}", is_available=True, is_claimed=False)
                  for joint in hardware.joint_names for interface in ("position", "velocity", "effort")]
        return commands, states

    def _list_interfaces(self, _request, response):
        response.command_interfaces, response.state_interfaces = self._interfaces()
        return response

    def _list_components(self, _request, response):
        commands, states = self._interfaces()
        hardware = type(self.session.hardware)
        component = HardwareComponentState(name=self.session.robot.name, type="system",
                                           plugin_name=f"jointctl/{hardware.__name__}",
                                           command_interfaces=commands, state_interfaces=states)
        component.state = State(id=State.PRIMARY_STATE_ACTIVE, label="active")
        response.component = [component]
        return response

    def _load(self, request, response):
        try:
            self._in_loop(lambda _t: self.manager.load(request.name))
            response.ok = True
        except JointCtlError as exc:
            self.node.get_logger().error(f"could not load controller {request.name!r}: {exc}")
            response.ok = False
        return response

    def _unload(self, request, response):
        active = {c.name for c in self.manager.active}
        response.ok = request.name not in active and request.name in {c.name for c in self.manager.loaded()}
        if not response.ok:
            self.node.get_logger().error(f"could not unload controller {request.name!r}: "
                                         + ("it is active" if request.name in active else "it is not loaded"))
        return response

    def _switch(self, request, response):
        strict = request.strictness != SwitchController.Request.BEST_EFFORT
        stop, start = list(request.deactivate_controllers), list(request.activate_controllers)

        def switch(time_s: float) -> bool:
            manager = self.manager
            active = {c.name for c in manager.active}
            if strict:
                manager.stop([n for n in stop if n in active], time_s)
                try:
                    manager.start(start, time_s)
                except JointCtlError:
                    manager.start([n for n in stop if n in active], time_s)  # all or nothing: put them back
                    raise
                return True
            manager.stop([n for n in stop if n in active], time_s)
            for name in start:
                try:
                    manager.start([name], time_s)
                except JointCtlError as exc:
                    self.node.get_logger().warn(f"could not activate {name!r}: {exc}")
            return True

        try:
            response.ok = self._in_loop(switch)
        except JointCtlError as exc:
            self.node.get_logger().error(f"switch_controller refused: {exc}")
            response.ok = False
        return response


__all__ = ["ControllerManagerServices"]

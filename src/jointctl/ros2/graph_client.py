"""A small rclpy node for jointctl's tools: its own context, spun in a background thread, with blocking
service calls, parameters read and written on other nodes, and a latched topic's message.

The context is initialised without rclpy's signal handlers: Ctrl-C stays Python's ``KeyboardInterrupt``,
and the node lives on while the tool puts a robot back as it found it (its gains, its reference).
"""

from __future__ import annotations

import atexit
import os
import threading
import time

import rclpy
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from jointctl.errors import JointCtlError

#: How long a service may take to appear and to answer [s].
SERVICE_TIMEOUT_S = 5.0


class GraphClient:
    """An rclpy node named ``name`` (made unique with the process id) in a context of its own, spun by
    a daemon thread; :meth:`close` ends both."""

    def __init__(self, name: str = "jointctl_tools") -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(f"{name}_{os.getpid()}", context=self.context)
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._clients: dict[tuple[type, str], object] = {}
        self._thread = threading.Thread(target=self._spin, name="ros2-graph", daemon=True)
        self._thread.start()
        self._closed = False
        atexit.register(self.close)  # an executor thread alive at exit aborts the interpreter

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception:  # the context shut down under the executor: the client is closing
            pass

    # -- services ----------------------------------------------------------------------------------
    def call(self, service_type, service: str, request, timeout_s: float = SERVICE_TIMEOUT_S):
        """The response of ``service`` (of ``service_type``) to ``request``; a JointCtlError naming the
        service when it does not exist or does not answer within ``timeout_s``."""
        key = (service_type, service)
        client = self._clients.get(key)
        if client is None:
            client = self._clients[key] = self.node.create_client(service_type, service)
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise JointCtlError(f"no such service on the ROS 2 graph within {timeout_s:g} s (ROS_DOMAIN_ID and "
                                "discovery as the robot's?)", field="service", value=service)
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout_s):
            future.cancel()
            raise JointCtlError(f"the service did not answer within {timeout_s:g} s", field="service", value=service)
        return future.result()

    def get_parameters(self, node: str, names: list[str]) -> dict:
        """``{name: value}`` of ``node``'s parameters ``names`` (Python values; a name the node does not
        have is left out)."""
        response = self.call(GetParameters, f"{node}/get_parameters", GetParameters.Request(names=list(names)))
        found = {}
        for name, value in zip(names, response.values):
            python = parameter_value(value)
            if value.type != ParameterType.PARAMETER_NOT_SET:
                found[name] = python
        return found

    def set_parameters(self, node: str, values: dict) -> None:
        """Set ``node``'s parameters ``{name: value}`` (floats, bools, ints, strings); a JointCtlError
        with the node's reason when it refuses one."""
        request = SetParameters.Request(parameters=[Parameter(name=k, value=to_parameter_value(v))
                                                    for k, v in values.items()])
        response = self.call(SetParameters, f"{node}/set_parameters", request)
        refused = {name: result.reason for name, result in zip(values, response.results) if not result.successful}
        if refused:
            name, reason = next(iter(refused.items()))
            raise JointCtlError(f"the node refused the parameter ({reason or 'no reason given'})",
                                field=f"{node} {name}", value=values[name])

    # -- topics --------------------------------------------------------------------------------------
    def latched(self, message_type, topic: str, timeout_s: float = SERVICE_TIMEOUT_S):
        """The message a transient-local publisher keeps on ``topic`` (e.g. ``/robot_description``),
        or None when none arrives within ``timeout_s``."""
        got: list = []
        done = threading.Event()

        def take(msg) -> None:
            got.append(msg)
            done.set()

        qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)
        subscription = self.node.create_subscription(message_type, topic, take, qos)
        try:
            done.wait(timeout_s)
        finally:
            self.node.destroy_subscription(subscription)
        return got[0] if got else None

    def wait(self, condition, timeout_s: float, step_s: float = 0.01) -> bool:
        """Whether ``condition()`` became true within ``timeout_s`` [s] (checked every ``step_s``)."""
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                return False
            time.sleep(step_s)
        return True

    def close(self) -> None:
        """Stop spinning and leave the graph (once)."""
        if self._closed:
            return
        self._closed = True
        atexit.unregister(self.close)
        self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        self.context.try_shutdown()
        self._thread.join(2.0)


def parameter_value(value: ParameterValue):
    """A rcl_interfaces ParameterValue as a Python value (None when not set)."""
    kinds = {ParameterType.PARAMETER_BOOL: "bool_value", ParameterType.PARAMETER_INTEGER: "integer_value",
             ParameterType.PARAMETER_DOUBLE: "double_value", ParameterType.PARAMETER_STRING: "string_value",
             ParameterType.PARAMETER_BYTE_ARRAY: "byte_array_value",
             ParameterType.PARAMETER_BOOL_ARRAY: "bool_array_value",
             ParameterType.PARAMETER_INTEGER_ARRAY: "integer_array_value",
             ParameterType.PARAMETER_DOUBLE_ARRAY: "double_array_value",
             ParameterType.PARAMETER_STRING_ARRAY: "string_array_value"}
    field = kinds.get(value.type)
    if field is None:
        return None
    found = getattr(value, field)
    return list(found) if field.endswith("_array_value") else found


def to_parameter_value(value) -> ParameterValue:
    """A Python bool, int, float or string as a rcl_interfaces ParameterValue."""
    if isinstance(value, bool):
        return ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
    if isinstance(value, int):
        return ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    if isinstance(value, float):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    return ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=str(value))


__all__ = ["GraphClient", "SERVICE_TIMEOUT_S", "parameter_value", "to_parameter_value"]

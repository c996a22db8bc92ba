"""Controllers in the ros_control mould, and the manager that loads them from YAML."""

from jointctl.control.admittance_controller import AdmittanceController
from jointctl.control.cartesian_admittance_controller import CartesianAdmittanceController
from jointctl.control.controller import Controller
from jointctl.control.joint_controllers import JointPositionController, JointVelocityController
from jointctl.control.joint_state_controller import JointStateController, JointStateSample
from jointctl.control.manager import ControllerManager
from jointctl.control.pid import Pid, PidGains
from jointctl.control.registry import controller_types, register_controller

__all__ = [
    "AdmittanceController",
    "CartesianAdmittanceController",
    "Controller",
    "ControllerManager",
    "JointPositionController",
    "JointStateController",
    "JointStateSample",
    "JointVelocityController",
    "Pid",
    "PidGains",
    "controller_types",
    "register_controller",
]

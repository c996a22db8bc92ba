"""The hardware contract (joint state, command and sensor handles) and its implementations."""

from jointctl.hardware.interface import EFFORT, POSITION, VELOCITY, HardwareInterface
from jointctl.hardware.mujoco_hardware import MujocoHardware

__all__ = ["EFFORT", "POSITION", "VELOCITY", "HardwareInterface", "MujocoHardware"]

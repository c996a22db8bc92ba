"""Physics: a :class:`~jointctl.model.RobotModel` plus world settings become a MuJoCo world."""

from jointctl.sim.mjcf_builder import WorldSettings, build_spec
from jointctl.sim.world import MujocoWorld

__all__ = ["MujocoWorld", "WorldSettings", "build_spec"]

"""Scenarios: a robot, its controllers, a world and command sources, from one YAML file."""

from jointctl.scenario.spec import Scenario, builtin_scenarios, load_scenario
from jointctl.scenario.session import Session

__all__ = ["Scenario", "Session", "builtin_scenarios", "load_scenario"]

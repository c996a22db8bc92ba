"""Shared fixtures: the built-in 1-DOF robot and helpers to write small scenario files."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

from jointctl.paths import robots_dir

ONE_DOF_XACRO = robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro"
POSITION_YAML = robots_dir() / "one_dof" / "config" / "one_dof_pos_ctl_params.yaml"
VELOCITY_YAML = robots_dir() / "one_dof" / "config" / "one_dof_vel_ctl_params.yaml"


def step_scenario(**changes) -> dict:
    """A short position-step scenario as a dict; keyword arguments replace fields."""
    scenario = {
        "name": "test_step",
        "robot": "one_dof",
        "controller_file": "position",
        "start_controllers": ["joint_state_controller", "joint1_position_controller"],
        "gravity": -9.81,
        "initial_positions": {"joint1": -0.2},
        "duration_s": 0.5,
        "commands": {"joint1_position_controller": {"type": "step", "from": -0.2, "to": -0.5, "at": 0.1}},
    }
    scenario.update(changes)
    return scenario


@pytest.fixture
def write_scenario(tmp_path: Path):
    """Write a scenario dict to a YAML file in tmp_path and return its path."""

    def write(data: dict, name: str = "scenario.yaml") -> Path:
        path = tmp_path / name
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        return path

    return write


# -- running in parallel (pytest-xdist) -------------------------------------------------------------------
#: Tests that run on the wall clock (ROS graphs, sockets to a controller, the page in a browser, the
#: viewer's window, pacing): with ``-n 2 --dist loadgroup`` they all run on one worker, one after the
#: other, while the other worker runs the simulated-time tests, whose results do not depend on how
#: fast they run. A wall-clock test therefore never shares the machine with another wall-clock test.
#: A single test elsewhere says so with ``@pytest.mark.wall_clock``.
WALL_CLOCK_TESTS = (
    "tests/ros/",
    "tests/ros2/",
    "tests/hardware/test_industrial.py",
    "tests/hardware/test_industrial_peers.py",
    "tests/industrial_controller/test_controller.py",
    "tests/industrial_controller/test_bode_over_bridge.py",
    "tests/tuning/test_page.py",
    "tests/tuning/test_server.py",
    "tests/tuning/test_analyses.py",
    "tests/visuals/test_viewer.py",
    "tests/runtime/test_clock.py",
)
_ROOT = Path(__file__).resolve().parents[1]


def pytest_collection_modifyitems(config, items):
    for item in items:
        path = Path(str(item.fspath)).resolve().relative_to(_ROOT).as_posix()
        if path.startswith(WALL_CLOCK_TESTS) or item.get_closest_marker("wall_clock") is not None:
            item.add_marker(pytest.mark.xdist_group("wall_clock"))


#: Niceness of a worker while it runs a simulated-time test under xdist (the lowest): the wall-clock tests' processes
#: (served nodes paced at 1 kHz, controllers, the browser) then get the CPU first, and the simulated
#: ones take what is left (their results do not depend on it). 0 again for a wall-clock test, where the
#: user may lower it (root; elsewhere both kinds stay at the worker's first niceness).
SIMULATED_TIME_NICENESS = 19


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    if "PYTEST_XDIST_WORKER" not in os.environ:
        return
    wall_clock = any(m.kwargs.get("name") == "wall_clock" or "wall_clock" in m.args
                     for m in item.iter_markers("xdist_group"))
    try:
        os.setpriority(os.PRIO_PROCESS, 0, 0 if wall_clock else SIMULATED_TIME_NICENESS)
    except OSError:
        pass

"""ROS across two hosts: two network namespaces joined by a veth pair, made and removed here.

Host A (10.200.0.1) runs the master and ``jointctl serve one_dof --controllers trajectory``; host B
(10.200.0.2) runs the actionlib client. Each advertises its own address (ROS_IP), as ROS 1 needs
between machines. Only addresses inside the namespaces this test creates are used.
Skipped unless root with ``ip`` (JOINTCTL_REQUIRE_ROS set: it must run).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.netns import two_hosts
from tests.processes import stop_process
from tests.ros.conftest import ROS_BUILD

CLIENT = str(Path(__file__).with_name("action_client.py"))
ADDR_A, ADDR_B = "10.200.0.1", "10.200.0.2"
PORT = 11311
JOINT_STATES = "/one_DOF_robot/joint_states"
SERVER = "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory"


@pytest.fixture
def hosts():
    """Two namespaces (A, B) joined by a veth pair (:func:`tests.netns.two_hosts`)."""
    with two_hosts("jc", ADDR_A, ADDR_B) as namespaces:
        yield namespaces


def _env(tmp_path, own_ip: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("ROS_HOSTNAME", "ROS_IP", "ROS_MASTER_URI")}
    env.update({
        "ROS_IP": own_ip, "ROS_MASTER_URI": f"http://{ADDR_A}:{PORT}",
        "ROS_HOME": str(tmp_path / f"ros_home_{own_ip}"),
        "ROS_PACKAGE_PATH": f"{ROS_BUILD / 'src'}:{env.get('ROS_PACKAGE_PATH', '')}".rstrip(":"),
        "PYTHONPATH": f"{ROS_BUILD / 'py'}:{env.get('PYTHONPATH', '')}".rstrip(":"),
    })
    return env


def _in(ns: str, *cmd: str) -> list[str]:
    return ["ip", "netns", "exec", ns, *cmd]


def test_a_goal_from_host_b_succeeds_on_host_a(hosts, tmp_path):
    ns_a, ns_b = hosts
    env_a, env_b = _env(tmp_path, ADDR_A), _env(tmp_path, ADDR_B)
    processes = []
    try:
        processes.append(subprocess.Popen(_in(ns_a, "rosmaster", "--core", "-p", str(PORT)), env=env_a,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        processes.append(subprocess.Popen(
            _in(ns_a, sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--controllers", "trajectory"),
            env=env_a, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        # From B: the joint states published on A (master and publisher both reached across the link).
        deadline = time.monotonic() + 40
        while True:
            echo = subprocess.run(_in(ns_b, "rostopic", "echo", "-n", "1", JOINT_STATES), env=env_b,
                                  capture_output=True, text=True, timeout=15)
            if echo.returncode == 0 and "joint1" in echo.stdout:
                break
            assert time.monotonic() < deadline, f"no joint states across the link: {echo.stderr[-500:]}"
            time.sleep(0.5)
        goal = {"joint_names": ["joint1"], "points": [[1.0, [-0.4]], [2.0, [-0.3]]]}
        result = subprocess.run(_in(ns_b, sys.executable, CLIENT, "follow", SERVER, json.dumps(goal)),
                                env=env_b, capture_output=True, text=True, timeout=90)
        done = json.loads(result.stdout.strip().splitlines()[-1])
        assert done["state"] == "SUCCEEDED" and done["result"]["error_code"] == 0, done
        assert done["feedback"] > 10  # feedback crossed the link too
    finally:
        for process in reversed(processes):
            stop_process(process)

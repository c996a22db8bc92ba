"""A real ROS 1 graph for the tests: a master on a free port, jointctl serving, ROS's own tools.

The tests skip when ROS 1 is missing, unless JOINTCTL_REQUIRE_ROS is set (CI sets it), in which
case they fail: nothing skips silently there.
"""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
ROS_BUILD = ROOT / "build" / "ros"


def _ros_available() -> bool:
    try:
        import rospy  # noqa: F401
        import control_msgs.msg  # noqa: F401
    except ImportError:
        return False
    return True


if not _ros_available():
    if os.environ.get("JOINTCTL_REQUIRE_ROS"):
        raise RuntimeError("JOINTCTL_REQUIRE_ROS is set but rospy or jointctl's messages do not import: run make ros")
    pytest.skip("ROS 1 is not installed (make ros)", allow_module_level=True)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def ros_env(tmp_path):
    """Environment of a fresh master on a free port; the master runs for the test."""
    port = free_port()
    env = dict(os.environ)
    env.update({
        "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_HOSTNAME": "127.0.0.1",
        "ROS_HOME": str(tmp_path / "ros_home"),
        "ROS_PACKAGE_PATH": f"{ROS_BUILD / 'src'}:{env.get('ROS_PACKAGE_PATH', '')}".rstrip(":"),
        "PYTHONPATH": f"{ROS_BUILD / 'py'}:{env.get('PYTHONPATH', '')}".rstrip(":"),
    })
    master = subprocess.Popen(["rosmaster", "--core", "-p", str(port)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 10
    while True:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                break
        except OSError:
            if time.monotonic() > deadline:
                master.terminate()
                pytest.fail("the ROS master did not come up")
            time.sleep(0.05)
    yield env
    master.terminate()
    master.wait(10)


def run(env, *args, timeout=20.0, check=True) -> subprocess.CompletedProcess:
    result = subprocess.run(list(args), env=env, capture_output=True, text=True, timeout=timeout)
    if check and result.returncode != 0:
        raise AssertionError(f"{args} failed ({result.returncode}): {result.stderr[-2000:]}")
    return result


def wait_for_topic(env, topic: str, timeout_s: float = 30.0) -> str:
    """One message of ``topic`` as rostopic prints it, waiting for the publisher to appear."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        result = run(env, "rostopic", "echo", "-n", "1", topic, timeout=10, check=False)
        if result.returncode == 0 and result.stdout.strip():
            return result.stdout
        time.sleep(0.3)
    raise AssertionError(f"no message on {topic} within {timeout_s} s")


def joint_position(env, topic: str = "/one_DOF_robot/joint_states") -> float:
    """The first joint's position in the next message of ``topic``."""
    text = wait_for_topic(env, topic)
    return float(re.search(r"position: \[([-0-9.e]+)", text).group(1))


def joint_positions(env, topic: str, count: int, column: str = "field.position0") -> list[float]:
    """``column`` of the next ``count`` messages of a JointState ``topic``."""
    text = run(env, "rostopic", "echo", "-p", "-n", str(count), topic, timeout=30).stdout
    lines = [line for line in text.splitlines() if line.strip()]
    header = lines[0].lstrip("%").split(",")
    index = header.index(column)
    return [float(line.split(",")[index]) for line in lines[1:]]


def settle_to(env, target: float, timeout_s: float = 10.0, tol: float = 0.002) -> float:
    """Poll the joint position until it is within ``tol`` of ``target``; the last position seen."""
    deadline = time.monotonic() + timeout_s
    while True:
        q = joint_position(env)
        if abs(q - target) < tol or time.monotonic() > deadline:
            return q
        time.sleep(0.2)


@pytest.fixture
def serve(ros_env):
    """Start ``jointctl serve ARGS`` against the test's master; stopped (SIGTERM) afterwards."""
    processes = []

    def start(*args: str, wait_topic: str | None = None):
        process = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "serve", *args], env=ros_env,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        processes.append(process)
        if wait_topic:
            wait_for_topic(ros_env, wait_topic)
        return process

    yield start
    for process in processes:
        process.terminate()
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()

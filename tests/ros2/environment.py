"""A real ROS 2 for the tests: the environment its ``setup.bash`` makes, a DDS domain of a test module's
own, kept on loopback, and the ``ros2`` command line.

ROS 2's Python packages (``std_msgs``, ``sensor_msgs``, ``control_msgs``...) have the names of ROS 1's, and
rclpy's C extensions find their libraries only through the ``LD_LIBRARY_PATH`` that ``setup.bash`` sets
before a process starts: so the test process stays a ROS 1 process, and everything ROS 2 (jointctl with
``--ros2``, the ``ros2`` CLI, ``ros2_control_node``, a small rclpy probe) runs in child processes started
with :func:`ros2_environment`.

Which ROS 2: ``JOINTCTL_ROS2_SETUP`` (a ``setup.bash``), else the first ``/opt/ros/<distro>/setup.bash`` with
rclpy inside (``make ros2`` installs Jazzy there). Without one the tests skip, or fail when
``JOINTCTL_REQUIRE_ROS2`` is set (CI sets it).
"""

from __future__ import annotations

import glob
import os
import subprocess
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
LOOPBACK_DDS = HERE / "cyclonedds-loopback.xml"
DOMAIN_LOCKS = Path(os.environ.get("TMPDIR", "/tmp")) / "jointctl-ros2-domains"
#: ROS_DOMAIN_IDs the tests take (Cyclone DDS maps 0..232 to ports; the ``ros2`` daemon has one per domain).
DOMAINS = range(120, 200)


def ros2_setup() -> Path | None:
    """The ``setup.bash`` of the ROS 2 the tests use, or None."""
    candidates = [os.environ["JOINTCTL_ROS2_SETUP"]] if os.environ.get("JOINTCTL_ROS2_SETUP") else \
        sorted(glob.glob("/opt/ros/*/setup.bash"))
    for setup in candidates:
        prefix = Path(setup).parent
        if Path(setup).is_file() and glob.glob(str(prefix / "lib" / "python3*" / "site-packages" / "rclpy")):
            return Path(setup)
    return None


def require_ros2() -> Path:
    """The ROS 2 setup file; skips the calling module without one (fails under JOINTCTL_REQUIRE_ROS2)."""
    setup = ros2_setup()
    if setup is None:
        reason = "no ROS 2 with rclpy (/opt/ros/<distro>/setup.bash or JOINTCTL_ROS2_SETUP): make ros2 installs one"
        if os.environ.get("JOINTCTL_REQUIRE_ROS2"):
            pytest.fail(f"JOINTCTL_REQUIRE_ROS2 is set but {reason}", pytrace=False)
        pytest.skip(reason, allow_module_level=True)
    return setup


_sourced: dict[Path, dict[str, str]] = {}


def sourced_variables(setup: Path) -> dict[str, str]:
    """The variables ``source setup.bash`` sets or changes, on top of this process's environment."""
    if setup not in _sourced:
        out = subprocess.run(["bash", "-c", f'source "{setup}" >/dev/null 2>&1; env -0'], check=True,
                             capture_output=True, env=dict(os.environ)).stdout
        after = dict(item.split("=", 1) for item in out.decode().split("\0") if "=" in item)
        _sourced[setup] = {k: v for k, v in after.items() if os.environ.get(k) != v and k not in ("_", "SHLVL")}
    return _sourced[setup]


def take_domain(besides=()) -> int:
    """A ROS_DOMAIN_ID no other live test process holds (a lock file per id, with the holder's pid), and none of
    ``besides`` (domains this process holds still: a second graph in one test module)."""
    DOMAIN_LOCKS.mkdir(parents=True, exist_ok=True)
    for domain in DOMAINS:
        if domain in besides:
            continue
        lock = DOMAIN_LOCKS / str(domain)
        try:
            holder = int(lock.read_text() or 0)
        except (FileNotFoundError, ValueError):
            holder = 0
        if holder and holder != os.getpid() and _alive(holder):
            continue
        lock.unlink(missing_ok=True)
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            continue
        with os.fdopen(fd, "w") as f:
            f.write(str(os.getpid()))
        return domain
    raise RuntimeError(f"every ROS_DOMAIN_ID in {DOMAINS} is held by a live test process")


def release_domain(domain: int) -> None:
    (DOMAIN_LOCKS / str(domain)).unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def ros2_environment(setup: Path, domain: int, log_dir: Path) -> dict[str, str]:
    """This process's environment with ROS 2 sourced, on DDS domain ``domain``, loopback only, logs in
    ``log_dir``."""
    env = dict(os.environ)
    env.update(sourced_variables(setup))
    env.update({"ROS_DOMAIN_ID": str(domain), "CYCLONEDDS_URI": LOOPBACK_DDS.as_uri(),
                "ROS_LOG_DIR": str(log_dir), "RCUTILS_COLORIZED_OUTPUT": "0", "PYTHONUNBUFFERED": "1"})
    env.pop("ROS_MASTER_URI", None)
    return env


def ros2(env: dict[str, str], *args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess:
    """Run ``ros2 ARGS...`` in ``env``; its output as text (never raises on a non-zero exit)."""
    return subprocess.run(["ros2", *args], env=env, capture_output=True, text=True, timeout=timeout_s)


def stop_daemon(env: dict[str, str]) -> None:
    """Stop the ``ros2`` CLI's daemon of ``env``'s domain (the first CLI call started it)."""
    try:
        subprocess.run(["ros2", "daemon", "stop"], env=env, capture_output=True, timeout=20)
    except subprocess.TimeoutExpired:
        pass


__all__ = ["LOOPBACK_DDS", "release_domain", "require_ros2", "ros2", "ros2_environment", "ros2_setup",
           "sourced_variables", "stop_daemon", "take_domain"]

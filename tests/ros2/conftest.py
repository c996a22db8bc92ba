"""ROS 2 test fixtures: one DDS domain per test module, the environment of the ROS 2 in use, and the ``ros2``
CLI daemon of that domain stopped at the end (see :mod:`tests.ros2.environment`)."""

from __future__ import annotations

import pytest

from tests.ros2.environment import release_domain, require_ros2, ros2_environment, stop_daemon, take_domain

SETUP = require_ros2()


@pytest.fixture(scope="module")
def ros2_env(tmp_path_factory):
    """The environment for a module's ROS 2 processes: ROS 2 sourced, its own ROS_DOMAIN_ID, loopback DDS."""
    domain = take_domain()
    env = ros2_environment(SETUP, domain, tmp_path_factory.mktemp("ros_log"))
    try:
        yield env
    finally:
        stop_daemon(env)
        release_domain(domain)

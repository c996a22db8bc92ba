"""ROS 2 across two hosts: two network namespaces joined by a veth pair (:func:`tests.netns.two_hosts`).

Host A (10.201.0.1) runs ``jointctl serve one_dof --controllers trajectory --ros2``; host B (10.201.0.2) runs ROS 2's
command line. Each host's Cyclone DDS uses its own interface and knows the other as its unicast peer (no multicast),
as two machines on a network without multicast are set up. Skipped unless root with ``ip`` (CI: it must run).
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.netns import two_hosts
from tests.processes import stop_process
from tests.waiting import wait_until

pytestmark = pytest.mark.slow

ADDR_A, ADDR_B = "10.201.0.1", "10.201.0.2"
ACTION = "/joint1_trajectory_controller/follow_joint_trajectory"
DDS = """<?xml version="1.0" encoding="UTF-8" ?>
<CycloneDDS xmlns="https://cdds.io/config">
  <Domain Id="any">
    <General>
      <Interfaces><NetworkInterface address="{own}"/></Interfaces>
      <AllowMulticast>false</AllowMulticast>
    </General>
    <Discovery>
      <ParticipantIndex>auto</ParticipantIndex>
      <MaxAutoParticipantIndex>40</MaxAutoParticipantIndex>
      <Peers><Peer address="{own}"/><Peer address="{other}"/></Peers>
    </Discovery>
  </Domain>
</CycloneDDS>
"""


def _host_env(ros2_env: dict, tmp_path, own: str, other: str) -> dict:
    config = tmp_path / f"cyclonedds-{own}.xml"
    config.write_text(DDS.format(own=own, other=other))
    return dict(ros2_env, CYCLONEDDS_URI=config.as_uri())


def _in(ns: str, *cmd: str) -> list[str]:
    return ["ip", "netns", "exec", ns, *cmd]


def test_a_goal_and_the_joint_states_cross_from_host_a_to_host_b(ros2_env, tmp_path):
    with two_hosts("jr", ADDR_A, ADDR_B) as (ns_a, ns_b):
        env_a = _host_env(ros2_env, tmp_path, ADDR_A, ADDR_B)
        env_b = _host_env(ros2_env, tmp_path, ADDR_B, ADDR_A)
        log = tmp_path / "serve.log"
        with open(log, "w") as out:
            serve = subprocess.Popen(_in(ns_a, sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--ros2",
                                         "--controllers", "trajectory"), env=env_a, stdout=out,
                                     stderr=subprocess.STDOUT)
        try:
            def cli(*args: str) -> subprocess.CompletedProcess:
                return subprocess.run(_in(ns_b, "ros2", *args), env=env_b, capture_output=True, text=True,
                                      timeout=90)

            def joint_states():
                assert serve.poll() is None, log.read_text()
                return "- joint1" in cli("topic", "echo", "--once", "--no-daemon", "/joint_states",
                                         "sensor_msgs/msg/JointState").stdout
            wait_until(joint_states, "host B's ros2 topic echo of host A's /joint_states", timeout_s=120,
                       every_s=0.5)
            goal = ("{trajectory: {joint_names: [joint1], points: [{positions: [-0.3], "
                    "time_from_start: {sec: 1}}]}}")
            done = cli("action", "send_goal", ACTION, "control_msgs/action/FollowJointTrajectory", goal)
            assert "SUCCEEDED" in done.stdout, done.stdout + done.stderr + log.read_text()
        finally:
            stop_process(serve)

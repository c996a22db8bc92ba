"""Two test hosts on one machine: network namespaces joined by a veth pair (iproute2's ``ip``, as root).

The ROS graph across hosts and the Dask cluster across hosts both run on them. Under ``JOINTCTL_REQUIRE_ROS``
(CI sets it) a machine that cannot make them fails the test instead of skipping it.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import uuid

import pytest


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10, check=check)


def _why_not() -> str | None:
    if os.geteuid() != 0:
        return "needs root for network namespaces"
    if shutil.which("ip") is None:
        return "needs iproute2's ip"
    return None


@contextlib.contextmanager
def two_hosts(prefix: str, addr_a: str, addr_b: str):
    """(namespace A, namespace B), with ``addr_a``/``addr_b`` on a /30 between them and loopback up in each;
    deleted afterwards, whatever happened. ``prefix``: two letters naming them (``jc``, ``js``...)."""
    reason = _why_not()
    if reason:
        if os.environ.get("JOINTCTL_REQUIRE_ROS"):
            pytest.fail(f"JOINTCTL_REQUIRE_ROS is set but {reason}")
        pytest.skip(reason)
    tag = uuid.uuid4().hex[:6]
    ns_a, ns_b = f"{prefix}_a_{tag}", f"{prefix}_b_{tag}"
    veth_a, veth_b = f"{prefix}va{tag}", f"{prefix}vb{tag}"  # at most 15 characters
    try:
        _ip("netns", "add", ns_a)
        _ip("netns", "add", ns_b)
        _ip("link", "add", veth_a, "type", "veth", "peer", "name", veth_b)
        _ip("link", "set", veth_a, "netns", ns_a)
        _ip("link", "set", veth_b, "netns", ns_b)
        for ns, dev, addr in ((ns_a, veth_a, addr_a), (ns_b, veth_b, addr_b)):
            _ip("-n", ns, "addr", "add", f"{addr}/30", "dev", dev)
            _ip("-n", ns, "link", "set", dev, "up")
            _ip("-n", ns, "link", "set", "lo", "up")
    except subprocess.CalledProcessError as exc:
        for ns in (ns_a, ns_b):
            _ip("netns", "del", ns, check=False)
        if os.environ.get("JOINTCTL_REQUIRE_ROS"):
            raise
        pytest.skip(f"network namespaces unavailable here: {exc.stderr.strip()}")
    try:
        yield ns_a, ns_b
    finally:
        for ns in (ns_a, ns_b):  # deleting a namespace deletes its end of the veth pair, and so the pair
            _ip("netns", "del", ns, check=False)

"""Ports for a server that a test stops and starts again on the same port (a controller killed and
restarted, as a robot cabinet reboots).

A port the OS picked (bind to port 0) lies in its ephemeral range
(``/proc/sys/net/ipv4/ip_local_port_range``), where it also picks the local port of every outgoing
connection and every other process's port 0: once the first server is gone, any of those may take it
before the restart (on a busy machine, ROS's XML-RPC alone opens connections by the hundred). Below
that range the OS hands out nothing by itself; only a process asking for that very port can take it.
So :func:`restart_safe_ports` picks there, at random, each port checked free (bound, on every
address) when picked; :func:`check_free` says plainly when one was taken anyway before a restart.
"""

from __future__ import annotations

import random
import socket
from pathlib import Path

#: Below the ephemeral range: from here up (under 10000 are many services' well-known ports).
LOWEST = 10000
#: Ports jointctl and ROS use by default (the industrial controller's, the ROS master's, Foxglove's).
AVOID = frozenset({11000, 11002, 11311, 8765, 8766})

_handed_out: set[int] = set()


def ephemeral_range() -> tuple[int, int]:
    """The OS's ephemeral port range (Linux's default when it cannot be read)."""
    try:
        low, high = map(int, Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split())
        return low, high
    except (OSError, ValueError):
        return 32768, 60999


def _bindable(port: int) -> bool:
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the servers bind (create_server)
        try:
            s.bind(("0.0.0.0", port))
        except OSError:
            return False
    return True


def restart_safe_ports(count: int) -> list[int]:
    """``count`` distinct free ports below the ephemeral range, never ones handed out before here."""
    low, _ = ephemeral_range()
    chosen: list[int] = []
    candidates = [p for p in range(LOWEST, low) if p not in AVOID and p not in _handed_out]
    for port in random.SystemRandom().sample(candidates, len(candidates)):
        if _bindable(port):
            chosen.append(port)
            _handed_out.add(port)
            if len(chosen) == count:
                return chosen
    raise AssertionError(f"no {count} free ports between {LOWEST} and {low}")


def check_free(*ports: int) -> None:
    """Fail saying which of ``ports`` another process holds now (before a server restarts on them)."""
    taken = [p for p in ports if not _bindable(p)]
    assert not taken, f"port(s) {taken} taken by another process before the restart (ss -tanp sport = :PORT)"


__all__ = ["check_free", "ephemeral_range", "restart_safe_ports"]

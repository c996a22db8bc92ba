"""The tests' own ROS graph (tests/ros/conftest.py): a master started on a port someone else took
meanwhile comes up on another, and is the process started (not whatever holds the port)."""

from __future__ import annotations

import socket
import xmlrpc.client

import tests.ros.conftest as graph


def test_free_port_never_hands_out_a_port_twice() -> None:
    ports = [graph.free_port() for _ in range(50)]
    assert len(set(ports)) == len(ports)


def test_a_master_whose_port_was_taken_comes_up_on_another(tmp_path, monkeypatch) -> None:
    with socket.socket() as squatter:  # takes the port first; accepts connections, never answers
        squatter.bind(("127.0.0.1", 0))
        squatter.listen()
        taken = squatter.getsockname()[1]
        handed = iter([taken])
        real = graph.free_port
        monkeypatch.setattr(graph, "free_port", lambda: next(handed, None) or real())
        master = graph.Master(graph.ros_environment(tmp_path, 0))
        try:
            assert master.port != taken
            assert master.env["ROS_MASTER_URI"] == f"http://127.0.0.1:{master.port}"
            assert xmlrpc.client.ServerProxy(master.uri).getPid("/test")[2] == master.process.pid
        finally:
            master.stop()

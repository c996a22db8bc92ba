"""The environment's own packages before the system's, whatever PYTHONPATH says.

A ROS 1 user's shell has a catkin workspace sourced that chains to Debian's ROS: PYTHONPATH then holds
the workspace's devel space (its messages) and Debian's ``/usr/lib/python3/dist-packages`` (rospy,
actionlib, and Debian's numpy 1.24, which ROS's tf2 pulls in). Python puts PYTHONPATH ahead of the
environment's site-packages, so Debian's numpy would shadow the one jointctl is installed with, and
every command would die importing scipy or matplotlib built against the newer one.

:func:`prefer_environment` moves each entry of ``sys.path`` that is a site directory of the base
Python (Debian's ``/usr/lib/python3/dist-packages``, ``/usr/local/lib/python3.X/dist-packages``...)
and comes before the environment's own site-packages to the end of ``sys.path``, where a virtual
environment made with ``--system-site-packages`` has it anyway: whatever the environment pins wins,
and what only the system has (rospy) still imports. Every other entry (the user's own, a devel space)
keeps its place. It runs when the ``jointctl`` package is imported, before anything of jointctl
imports numpy: the console script and ``python -m jointctl.cli`` import the package first.
Outside a virtual environment there is nothing to move.
"""

from __future__ import annotations

import os
import site
import sys


def prefer_environment(path: list[str] | None = None, *, prefix: str | None = None,
                       base_prefix: str | None = None) -> list[str]:
    """Move the base Python's site directories that come before the environment's site-packages in
    ``path`` (default ``sys.path``, changed in place) to its end; returns the entries moved. ``prefix``
    and ``base_prefix`` default to ``sys.prefix`` and ``sys.base_prefix``."""
    path = sys.path if path is None else path
    prefix = sys.prefix if prefix is None else prefix
    base_prefix = sys.base_prefix if base_prefix is None else base_prefix
    if os.path.realpath(prefix) == os.path.realpath(base_prefix):
        return []
    own = {os.path.realpath(p) for p in site.getsitepackages([prefix])}
    system = {os.path.realpath(p) for p in site.getsitepackages([base_prefix])} - own
    resolved = [os.path.realpath(p) if p else p for p in path]
    first_own = next((k for k, p in enumerate(resolved) if p in own), None)
    if first_own is None:
        return []
    moved = [path[k] for k in range(first_own) if resolved[k] in system]
    if moved:
        path[:] = [p for k, p in enumerate(path) if not (k < first_own and resolved[k] in system)] + moved
    return moved


def ros2_site_dirs(path: list[str] | None = None) -> list[str]:
    """The entries of ``path`` (default ``sys.path``) that hold a ROS 2 (an ``rclpy`` package inside)."""
    path = sys.path if path is None else path
    return [p for p in path if p and os.path.isfile(os.path.join(p, "rclpy", "__init__.py"))]


def set_aside_ros2(path: list[str] | None = None, modules: dict | None = None) -> list[str]:
    """Take a sourced ROS 2's site directories out of ``path`` (default ``sys.path``) and forget the modules
    imported from them (``modules``, default ``sys.modules``), for a ROS 1 process in a shell where ROS 2's
    ``setup.bash`` was sourced too: ROS 2's ``std_msgs``, ``rosgraph_msgs``... carry ROS 1's names and would
    shadow them. Returns the entries taken out."""
    path = sys.path if path is None else path
    modules = sys.modules if modules is None else modules
    taken = ros2_site_dirs(path)
    if not taken:
        return []
    path[:] = [p for p in path if p not in taken]
    roots = tuple(os.path.join(os.path.realpath(p), "") for p in taken)
    for name, module in list(modules.items()):
        where = getattr(module, "__file__", None) or ""
        if where and os.path.realpath(where).startswith(roots):
            del modules[name]
    return taken


__all__ = ["prefer_environment", "ros2_site_dirs", "set_aside_ros2"]

"""The environment's packages before the system's on sys.path (:mod:`jointctl.python_path`), on path lists
laid out as Debian's python3 lays them out for a virtual environment made with --system-site-packages."""

from __future__ import annotations

import site

from jointctl.python_path import prefer_environment

VENV, BASE = "/home/u/venv", "/usr"


def layout(*front: str) -> list[str]:
    """sys.path of the environment with PYTHONPATH = ``front``: PYTHONPATH, the standard library, the
    environment's site-packages, then the system's (those not on PYTHONPATH already)."""
    own = site.getsitepackages([VENV])[0]
    system = [p for p in site.getsitepackages([BASE]) if p not in front]
    return ["", *front, "/usr/lib/python311.zip", "/usr/lib/python3.11", own, *system]


def test_debians_dist_packages_on_pythonpath_goes_after_the_environments_site_packages():
    debian = "/usr/lib/python3/dist-packages"
    assert debian in site.getsitepackages([BASE])  # the base Python's own site directory
    devel = "/home/u/catkin_ws/devel/lib/python3/dist-packages"
    path = layout("/home/u/jointctl/src", devel, debian)
    moved = prefer_environment(path, prefix=VENV, base_prefix=BASE)
    assert moved == [debian]
    own = site.getsitepackages([VENV])[0]
    # The user's entries keep their place in front; Debian's comes after the environment's, still there.
    assert path[:3] == ["", "/home/u/jointctl/src", devel]
    assert path.index(own) < path.index(debian) and path.count(debian) == 1


def test_nothing_moves_without_a_system_directory_in_front_or_outside_an_environment():
    path = layout("/home/u/jointctl/src")
    assert prefer_environment(path, prefix=VENV, base_prefix=BASE) == [] and path == layout("/home/u/jointctl/src")
    system = layout("/usr/lib/python3/dist-packages")
    assert prefer_environment(system, prefix=BASE, base_prefix=BASE) == []  # the system Python's own order
    assert system == layout("/usr/lib/python3/dist-packages")

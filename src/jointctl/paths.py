"""Where jointctl's bundled data lives: robot descriptions and built-in scenarios.

In a wheel the data is packaged under ``jointctl/_data``; in a source checkout
(editable install) it is the repository's ``robots/`` and ``scenarios/``.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent


def _data_dir(name: str) -> Path:
    packaged = _PACKAGE_DIR / "_data" / name
    if packaged.is_dir():
        return packaged
    return _PACKAGE_DIR.parent.parent / name


def robots_dir() -> Path:
    """Folder of the built-in robots, one sub-folder per robot."""
    return _data_dir("robots")


def scenarios_dir() -> Path:
    """Folder of the built-in scenario files."""
    return _data_dir("scenarios")

"""The decorator of jointctl's compiled kernels: numba's ``njit``, its machine code cached on disk.

A kernel (a ``*_kernel.py`` module beside the Python it mirrors, or :mod:`jointctl.compiled`) is compiled
the first time it runs with its argument types and kept in a cache folder, so later runs (and processes)
load it in a fraction of a second. The folder is named after a digest of every kernel module's text:
numba checks only the file that defines a function, so a kernel that calls a changed kernel of another
module would otherwise load stale code. It is ``$JOINTCTL_KERNEL_CACHE`` when set, else
``$XDG_CACHE_HOME/jointctl/kernels/<digest>`` (``~/.cache`` by default).

Kernels compile with IEEE arithmetic as Python's (no fast-math, Python's error model): the same
operations in the same order give the same bits as the Python they mirror. They allocate nothing: they
work on arrays they are given, so they compile without numba's reference counting (``_nrt=False``),
whose atomic counts on every array argument of every call cost more than a controller's arithmetic.
numba is imported only when a kernel module is, so jointctl runs (on its Python loop) where numba is
missing.
"""

from __future__ import annotations

import hashlib
import os
from functools import lru_cache
from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent


def kernel_sources() -> list[Path]:
    """Every module whose functions are kernels, in a fixed order."""
    return sorted([*_PACKAGE_DIR.rglob("*_kernel.py"), *(_PACKAGE_DIR / "compiled").glob("*.py"),
                   Path(__file__).resolve()])


@lru_cache(maxsize=1)
def cache_dir() -> Path:
    """The folder the kernels' machine code is kept in (see the module docstring)."""
    given = os.environ.get("JOINTCTL_KERNEL_CACHE")
    if given:
        return Path(given)
    digest = hashlib.sha256()
    for path in kernel_sources():
        digest.update(path.relative_to(_PACKAGE_DIR).as_posix().encode())
        digest.update(path.read_bytes())
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "jointctl" / "kernels" / digest.hexdigest()[:16]


def kernel(function):
    """``function`` compiled by numba (nopython, no reference counting, cached in :func:`cache_dir`, the GIL
    released while it runs)."""
    import numba
    from numba.core import config

    saved = config.CACHE_DIR
    config.CACHE_DIR = str(cache_dir())  # read once, as the dispatcher picks its cache locator
    try:
        return numba.njit(cache=True, nogil=True, _nrt=False)(function)
    finally:
        config.CACHE_DIR = saved

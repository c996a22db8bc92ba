"""Resolve ``$(find pkg)`` and ``package://pkg/...`` without ROS.

A package is a folder holding a ``package.xml`` whose ``<name>`` is the
package's name, or, failing that, a folder named after the package. Folders
are searched in order: the user's search path first (``JOINTCTL_PACKAGE_PATH``
and explicit arguments), then ``ROS_PACKAGE_PATH``, then jointctl's own robots.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from pathlib import Path

from jointctl.errors import ModelError
from jointctl.paths import robots_dir

_NAME_RE = re.compile(r"<name>\s*([^<\s]+)\s*</name>")


class PackageResolver:
    """Finds package folders by name across an ordered list of search roots."""

    def __init__(self, search_path: Iterable[str | os.PathLike] = ()) -> None:
        roots: list[Path] = [Path(p) for p in search_path]
        for env in ("JOINTCTL_PACKAGE_PATH", "ROS_PACKAGE_PATH"):
            roots += [Path(p) for p in os.environ.get(env, "").split(os.pathsep) if p]
        roots.append(robots_dir())
        self.roots: tuple[Path, ...] = tuple(roots)
        self._cache: dict[str, Path] = {}

    def find(self, package: str) -> Path:
        """The folder of ``package``; :class:`ModelError` when no root has it."""
        if package in self._cache:
            return self._cache[package]
        for root in self.roots:
            found = _find_in_root(root, package)
            if found is not None:
                self._cache[package] = found
                return found
        searched = ", ".join(str(r) for r in self.roots)
        raise ModelError(
            f"package {package!r} not found (searched {searched}; add its parent folder "
            "with --package-path or JOINTCTL_PACKAGE_PATH)",
            field="$(find)",
            value=package,
        )

    def resolve_uri(self, uri: str, base_dir: Path | None = None) -> Path:
        """Turn ``package://pkg/rel``, ``file://abs`` or a relative path into a file path."""
        if uri.startswith("package://"):
            rest = uri[len("package://") :]
            package, _, rel = rest.partition("/")
            return self.find(package) / rel
        if uri.startswith("file://"):
            return Path(uri[len("file://") :])
        path = Path(uri)
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        return path


def _find_in_root(root: Path, package: str) -> Path | None:
    if not root.is_dir():
        return None
    candidates: Sequence[Path] = [root] + sorted(p for p in root.iterdir() if p.is_dir())
    for folder in candidates:
        manifest = folder / "package.xml"
        if manifest.is_file() and _manifest_name(manifest) == package:
            return folder
    direct = root / package
    return direct if direct.is_dir() else None


def _manifest_name(manifest: Path) -> str | None:
    try:
        return ET.parse(manifest).getroot().findtext("name", default="").strip() or None
    except ET.ParseError:
        match = _NAME_RE.search(manifest.read_text(errors="replace"))
        return match.group(1) if match else None

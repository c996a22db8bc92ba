"""Load a robot description file (``.urdf`` or ``.xacro``) into a :class:`RobotModel`.

xacro runs in-process with ``$(find pkg)`` resolved by
:class:`~jointctl.model.package_paths.PackageResolver` (no ROS needed); the
``package://`` URIs of meshes are resolved the same way.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

from jointctl.errors import ModelError
from jointctl.model.package_paths import PackageResolver
from jointctl.model.robot_model import Link, RobotModel, Shape
from jointctl.model.urdf_parser import parse_urdf


def load_robot_model(
    path: str | os.PathLike,
    *,
    search_path: Iterable[str | os.PathLike] = (),
    xacro_args: Mapping[str, str] | None = None,
) -> RobotModel:
    """Read ``path`` (URDF, or xacro when it ends in ``.xacro``) into a RobotModel."""
    path = Path(path)
    if not path.is_file():
        raise ModelError("robot description file not found", source=str(path))
    resolver = PackageResolver(search_path)
    if path.suffix == ".xacro":
        text = expand_xacro(path, resolver, xacro_args or {})
    else:
        try:
            text = path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise ModelError(f"cannot read: {exc}", source=str(path)) from None
    model = parse_urdf(text, source=str(path))
    return _resolve_meshes(model, resolver, path.parent)


def expand_xacro(path: Path, resolver: PackageResolver, args: Mapping[str, str]) -> str:
    """Run xacro on ``path`` and return the URDF text."""
    import xacro
    from xacro import substitution_args

    with _find_resolver(substitution_args, resolver):
        try:
            doc = xacro.process_file(str(path), mappings=dict(args))
        except Exception as exc:  # xacro raises XacroException, XML and name errors
            inner = _wrapped_model_error(exc)
            if inner is not None:  # our $(find) resolver's error, wrapped by xacro
                inner.source = inner.source or str(path)
                raise inner from None
            detail = " ".join(str(exc).split())  # xacro's messages span lines
            raise ModelError(f"xacro failed: {detail}", source=str(path)) from None
    return doc.toxml()


def description_text(robot: RobotModel, search_path: Iterable[str | os.PathLike] = ()) -> str:
    """The URDF text of ``robot`` as jointctl loaded it: its ``source`` file, xacro expanded with the same
    ``$(find)`` resolution (``search_path``, then JOINTCTL_PACKAGE_PATH, ROS_PACKAGE_PATH and jointctl's
    robots), or read as it is when it is plain URDF."""
    if not robot.source:
        raise ModelError("the robot model has no description file", field="robot_description", value=robot.name)
    path = Path(robot.source)
    if path.suffix == ".xacro":
        return expand_xacro(path, PackageResolver(search_path), {})
    try:
        return path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"cannot read: {exc}", source=str(path), field="robot_description") from None


def _wrapped_model_error(exc: BaseException) -> ModelError | None:
    """The ModelError inside xacro's exception wrapping (``.exc``, cause or context), if any."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, ModelError):
            return exc
        seen.add(id(exc))
        exc = getattr(exc, "exc", None) or exc.__cause__ or exc.__context__
    return None


@contextlib.contextmanager
def _find_resolver(substitution_args, resolver: PackageResolver):
    """Point xacro's ``$(find pkg)`` (which wants ament_index) at ``resolver``."""
    original = substitution_args._eval_find

    def find(pkg: str) -> str:
        return str(resolver.find(pkg))

    substitution_args._eval_find = find
    substitution_args._eval_dict["find"] = find
    try:
        yield
    finally:
        substitution_args._eval_find = original
        substitution_args._eval_dict["find"] = original


def _resolve_meshes(model: RobotModel, resolver: PackageResolver, base_dir: Path) -> RobotModel:
    def fix(shape: Shape, where: str) -> Shape:
        g = shape.geometry
        if g.kind != "mesh":
            return shape
        resolved = resolver.resolve_uri(g.mesh_path, base_dir)
        if not resolved.is_file():
            raise ModelError("mesh file not found", source=model.source, field=where,
                             value=g.mesh_path)
        return dataclasses.replace(shape, geometry=dataclasses.replace(g, mesh_path=str(resolved)))

    def fix_link(link: Link) -> Link:
        return dataclasses.replace(
            link,
            visuals=tuple(fix(s, f"link[{link.name}].visual") for s in link.visuals),
            collisions=tuple(fix(s, f"link[{link.name}].collision") for s in link.collisions),
        )

    if not any(s.geometry.kind == "mesh" for lk in model.links for s in lk.visuals + lk.collisions):
        return model
    return dataclasses.replace(model, links=tuple(fix_link(lk) for lk in model.links))



"""Where the drawn shapes of a MuJoCo world are: axis-aligned bounds in the world frame [m].

:func:`drawn_bounds` is the box around every geom a picture shows (MuJoCo's default geom groups
0 to 2, colour not transparent), planes left out (a floor has no size worth framing). Each geom's
own bounding box (MuJoCo's ``geom_aabb``, in the geom's frame) is turned into the world frame, so
a box or a cylinder is bounded by its corners, not by a sphere around it. ``bodies`` keeps only
the geoms of those bodies: the robot's links, or a spawned object. A camera framing the scene
(:mod:`jointctl.visuals.framing`) and the tests that check a picture use it.
"""

from __future__ import annotations

from collections.abc import Iterable

import mujoco
import numpy as np

#: The geom groups MuJoCo draws by default (``mjvOption.geomgroup``: groups 0, 1 and 2).
DRAWN_GROUPS = (0, 1, 2)


def drawn_geoms(model: mujoco.MjModel, bodies: Iterable[str] | None = None) -> list[int]:
    """Indices of the geoms a picture shows, planes left out; only those of ``bodies`` when given."""
    wanted = None
    if bodies is not None:
        wanted = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) for name in bodies}
    return [g for g in range(model.ngeom)
            if model.geom_rgba[g][3] > 0 and int(model.geom_group[g]) in DRAWN_GROUPS
            and int(model.geom_type[g]) != int(mujoco.mjtGeom.mjGEOM_PLANE)
            and (wanted is None or int(model.geom_bodyid[g]) in wanted)]


def drawn_bounds(model: mujoco.MjModel, data: mujoco.MjData,
                 bodies: Iterable[str] | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """(lowest, highest) corner [m, world frame] of the drawn geoms (see the module docstring) at
    ``data``'s pose (after ``mj_forward`` or a step); None when nothing is drawn."""
    ids = drawn_geoms(model, bodies)
    if not ids:
        return None
    centres_local = model.geom_aabb[ids, :3]
    halves = model.geom_aabb[ids, 3:]
    rotations = data.geom_xmat[ids].reshape(-1, 3, 3)
    centres = data.geom_xpos[ids] + np.einsum("gij,gj->gi", rotations, centres_local)
    extents = np.einsum("gij,gj->gi", np.abs(rotations), halves)
    return (centres - extents).min(axis=0), (centres + extents).max(axis=0)


def robot_bodies(model: mujoco.MjModel, objects: Iterable[str] = ()) -> list[str]:
    """The names of the bodies that are not the world and not one of the spawned ``objects``."""
    skip = set(objects)
    names = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(1, model.nbody))
    return [name for name in names if name not in skip]


__all__ = ["DRAWN_GROUPS", "drawn_bounds", "drawn_geoms", "robot_bodies"]

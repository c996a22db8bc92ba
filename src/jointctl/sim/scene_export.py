"""The visible shapes of a MuJoCo world and their poses, as plain data for a 3D view elsewhere.

:func:`visual_geoms` lists the geoms a viewer draws (alpha above zero: the URDF's visuals and the
spawned objects, not the invisible collision copies): their MuJoCo type (``box``, ``sphere``,
``cylinder``, ``capsule``, ``ellipsoid``, ``plane``, ``mesh``), size (MuJoCo's: half extents, radius
and half length...) [m], colour (RGBA 0..1), the body they belong to, and for meshes the vertices
[m, the mesh frame] and triangles. :func:`geom_poses` gives each one's pose in the world frame:
position [m] and orientation as a quaternion (w, x, y, z). Z is up, as in MuJoCo.
"""

from __future__ import annotations

import mujoco
import numpy as np

_TYPES = {int(t): name for t, name in (
    (mujoco.mjtGeom.mjGEOM_PLANE, "plane"), (mujoco.mjtGeom.mjGEOM_SPHERE, "sphere"),
    (mujoco.mjtGeom.mjGEOM_CAPSULE, "capsule"), (mujoco.mjtGeom.mjGEOM_ELLIPSOID, "ellipsoid"),
    (mujoco.mjtGeom.mjGEOM_CYLINDER, "cylinder"), (mujoco.mjtGeom.mjGEOM_BOX, "box"),
    (mujoco.mjtGeom.mjGEOM_MESH, "mesh"))}


def visible_ids(model: mujoco.MjModel) -> list[int]:
    """Indices of the geoms a viewer draws: known shapes with a colour that is not transparent."""
    return [g for g in range(model.ngeom) if model.geom_rgba[g][3] > 0 and int(model.geom_type[g]) in _TYPES]


def visual_geoms(model: mujoco.MjModel) -> list[dict]:
    """Shape, size [m], colour and body of each visible geom (see the module docstring)."""
    out = []
    for g in visible_ids(model):
        body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g])) or "world"
        entry = {"type": _TYPES[int(model.geom_type[g])], "size": [round(float(v), 6) for v in model.geom_size[g]],
                 "rgba": [round(float(v), 4) for v in model.geom_rgba[g]], "body": body}
        if int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_MESH):
            mesh = int(model.geom_dataid[g])
            v0, nv = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
            f0, nf = model.mesh_faceadr[mesh], model.mesh_facenum[mesh]
            entry["vertices"] = np.round(model.mesh_vert[v0:v0 + nv], 6).ravel().tolist()
            entry["faces"] = model.mesh_face[f0:f0 + nf].ravel().tolist()
        out.append(entry)
    return out


def geom_poses(model: mujoco.MjModel, data: mujoco.MjData, ids: list[int]) -> list[list[float]]:
    """[x, y, z, qw, qx, qy, qz] of each geom of ``ids`` in the world frame [m]."""
    quat = np.empty(4)
    poses = []
    for g in ids:
        mujoco.mju_mat2Quat(quat, data.geom_xmat[g])
        poses.append([*(round(float(v), 6) for v in data.geom_xpos[g]), *(round(float(v), 6) for v in quat)])
    return poses


__all__ = ["geom_poses", "visible_ids", "visual_geoms"]

"""MuJoCo's C functions as compiled kernels call them: the library the ``mujoco`` wheel ships, loaded into
numba's symbol table, and the functions declared by address (``mjModel*``, ``mjData*`` and array pointers are
``uintp``: a model's or data's ``_address``, an array's ``ctypes.data``).

Declared: ``mj_step``, and the pose queries of :class:`~jointctl.model.dynamics.RobotDynamics`:
``mj_kinematics``, ``mj_comPos``, ``mj_crb``, ``mj_jacBody``, ``mj_rne``, ``mj_mulM``, ``mj_fullM``.
"""

from __future__ import annotations

from pathlib import Path

import llvmlite.binding
import mujoco
from numba import types


def mujoco_library() -> Path:
    """The MuJoCo library the ``mujoco`` package loaded (``libmujoco.so.X`` beside its modules)."""
    folder = Path(mujoco.__file__).resolve().parent
    found = sorted(p for p in folder.glob("libmujoco*") if p.is_file())
    if not found:
        raise ImportError(f"no MuJoCo library (libmujoco*) in {folder}")
    return found[0]


llvmlite.binding.load_library_permanently(str(mujoco_library()))

_POINTER = types.uintp
#: ``void mj_step(const mjModel* m, mjData* d)``.
mj_step = types.ExternalFunction("mj_step", types.void(_POINTER, _POINTER))
#: ``void mj_kinematics(const mjModel* m, mjData* d)``: the bodies' poses.
mj_kinematics = types.ExternalFunction("mj_kinematics", types.void(_POINTER, _POINTER))
#: ``void mj_comPos(const mjModel* m, mjData* d)``: the centre-of-mass frames.
mj_comPos = types.ExternalFunction("mj_comPos", types.void(_POINTER, _POINTER))
#: ``void mj_crb(const mjModel* m, mjData* d)``: the composite inertia M(q).
mj_crb = types.ExternalFunction("mj_crb", types.void(_POINTER, _POINTER))
#: ``void mj_jacBody(const mjModel* m, const mjData* d, mjtNum* jacp, mjtNum* jacr, int body)``.
mj_jacBody = types.ExternalFunction("mj_jacBody", types.void(_POINTER, _POINTER, _POINTER, _POINTER, types.int32))
#: ``void mj_rne(const mjModel* m, mjData* d, int flg_acc, mjtNum* result)``.
mj_rne = types.ExternalFunction("mj_rne", types.void(_POINTER, _POINTER, types.int32, _POINTER))
#: ``void mj_mulM(const mjModel* m, const mjData* d, mjtNum* res, const mjtNum* vec)``.
mj_mulM = types.ExternalFunction("mj_mulM", types.void(_POINTER, _POINTER, _POINTER, _POINTER))
#: ``void mj_fullM(const mjModel* m, const mjData* d, mjtNum* dst)``: M(q) as a dense nv x nv matrix, row by row.
mj_fullM = types.ExternalFunction("mj_fullM", types.void(_POINTER, _POINTER, _POINTER))

"""The compiled form of :class:`~jointctl.control.cartesian_admittance_controller.CartesianAdmittanceController`
(H diagonal, ``inertia_estimate``, or the model's M(q), ``use_model_inertia``): its ``update`` on arrays, operation
for operation as the Python.

- ``_measure``: the joint state gathered, the pose set and the flange's Jacobians taken through
  :mod:`~jointctl.model.dynamics_kernel` (the same C functions on the controller's own ``RobotDynamics``
  data), the sensed force rotated into the base frame by the sensor frame's rotation;
- the tare window (the mean base-frame force while holding still);
- the virtual force ``f = K·(p_att - p) - B·v + F``, ``τ - c·q̇`` with ``τ = Jvᵀ·f``;
- the diagonal-H accelerations, or with wrist joints ``_wrist_accelerations`` (the 3 x 3 push-through solve)
  and ``_wrist_command`` (the orientation error as a rotation vector, the damped least-squares rows);
- with the model's inertia, ``_model_accelerations``: M(q) from ``mj_fullM`` of the controller's own dynamics data
  (the pose set with inertia: ``mj_crb``) gathered to its joints, with wrist joints ``Tᵀ·M·T`` and ``Tᵀ·g``, and
  ``_cholesky_solve`` (factor and solve in place in the state table). A matrix that is not positive definite (the
  Python raises ``LinAlgError``) makes :func:`cartesian_update` return False, the references unwritten: the
  compiled cycle hands that cycle to Python from this update on, which raises as the Python does;
- the hand-over to the velocity controllers' reference slots.

Sums run in the Python's order (its dot products are plain loops, so both paths do the same operations).

The controller's numbers are three tables: integers (:data:`INDEX_ROWS` rows: joints, reference slots, arm
and wrist joints, the bodies' and sensor's indices), parameters (:data:`PARAMETER_ROWS`
rows: gains, joint damping, H and H⁻¹, velocity limits, scalars) and state (:data:`STATE_ROWS` rows: every
quantity the Python controller keeps; with the model's inertia, blocks of work rows after them: M(q), the
factor, M·T, P and MuJoCo's dense nv x nv M). :class:`CartesianArrays` makes them from a started controller and
:meth:`CartesianArrays.unpack` puts the state back into its attributes (``velocity_reference``, the tare's
sums, ``orientation_error``, ``virtual_force``, ``force``, ``acceleration``, ``velocity_command``...).
"""

from __future__ import annotations

import math

import numpy as np

from jointctl.control.cartesian_admittance_controller import WRIST_DLS_DAMPING, CartesianAdmittanceController
from jointctl.jit import kernel
from jointctl.model.dynamics_kernel import (DynamicsArrays, dynamics_jacobians, dynamics_mass_matrix,
                                            dynamics_set_pose)

#: Integer rows: the hardware index of each joint, each velocity controller's reference slot, the arm joints,
#: the wrist joints, and the scalars ``SCALARS_I``.
GATHER, TARGETS, ARM, WRIST, SCALARS_I = range(5)
INDEX_ROWS = 5
#: ``SCALARS_I`` columns: the flange's and the sensor frame's bodies, the sensor's row in the hardware's
#: wrenches, the number of arm joints and of wrist joints, whether H is the model's M(q) (1) or diagonal (0), the
#: first state row of the model-inertia blocks (n rows each: M(q), the Cholesky factor, M·T, P; then the rows
#: holding MuJoCo's dense nv x nv M) and the model's nv.
FLANGE_BODY, SENSOR_BODY, SENSOR_ROW, N_ARM, N_WRIST, MODEL_INERTIA, MASS_ROW, NV = range(8)

#: Parameter rows: K, B, p_att (``GAINS``: columns 0-2, 3-5, 6-8), c per joint, H and H⁻¹ per joint, the
#: velocity limit per joint, and the scalars ``SCALARS``.
GAINS, JOINT_DAMPING, INERTIA, INVERSE_INERTIA, LIMIT, SCALARS = range(6)
PARAMETER_ROWS = 6
#: ``SCALARS`` columns: the wrist gain [1/s], λ² of the damped least squares [rad²], the end of the tare [s].
WRIST_GAIN, LAMBDA2, TARE_UNTIL = range(3)

#: State rows (3-vectors in columns 0-2, joint vectors in joint order, arm vectors in arm order):
(TARE_SUM, TARE, TARGET_ROTATION, ORIENTATION_ERROR, VELOCITY_REFERENCE, VELOCITY_COMMAND, SENSED_FORCE, FORCE,
 VIRTUAL_FORCE, ACCELERATION, VELOCITY, TORQUE, GENERALIZED, QD, Q, DLS_X, DLS_Y, DLS_Z, ERROR_ROTATION, U,
 FLAGS, SOLVE) = range(22)
STATE_ROWS = 22
#: ``TARE_SUM`` column 3: the readings summed. ``FLAGS`` columns: the admittance ran (force, virtual force,
#: acceleration and velocity are set), the wrist ran (the orientation error, the rows of Jr_W⁺ are set).
TARE_COUNT = 3
RAN, WRIST_RAN = range(2)


def cartesian_reason(c: CartesianAdmittanceController) -> str | None:
    """Why ``c`` has no compiled form (None when it has one: every configuration has, ``inertia_estimate`` and
    ``use_model_inertia`` alike)."""
    return None


class CartesianArrays:
    """The tables and buffers of one started ``CartesianAdmittanceController``."""

    def __init__(self, c: CartesianAdmittanceController) -> None:
        self.controller = c
        n, arm, wrist = len(c.joint_names), c.arm_joints, c.wrist_joints
        hw = c.hardware
        self.dynamics = DynamicsArrays(c.dynamics)
        nv = self.dynamics.jacp.shape[1]
        model = c.use_model_inertia
        width = max(n, 9, nv) if model else max(n, 9)
        rows = STATE_ROWS + (4 * n + -(-nv * nv // width) if model else 0)
        self.q = np.zeros(n)
        self.jv, self.jr = c.flange.translation_jacobian, c.flange.rotation_jacobian
        index = self.index = np.zeros((INDEX_ROWS, width), dtype=np.int64)
        index[GATHER, :n] = c.indices
        index[TARGETS, :n] = c._target_indices
        index[ARM, :len(arm)] = arm
        index[WRIST, :len(wrist)] = wrist
        index[SCALARS_I, :8] = (c.flange._body, c.sensor_frame._body, hw.sensor_names.index(c.sensor), len(arm),
                                len(wrist), int(model), STATE_ROWS, nv)
        p = self.parameters = np.zeros((PARAMETER_ROWS, width))
        p[GAINS, :9] = c._gains
        p[JOINT_DAMPING, :n] = c.joint_damping
        if not model:
            p[INERTIA, :n] = c._inertia
            p[INVERSE_INERTIA, :n] = c._inverse_inertia
        p[LIMIT, :n] = c.max_velocity
        p[SCALARS, :3] = (c.wrist_gain, WRIST_DLS_DAMPING**2, c._tare_until_s)
        s = self.state = np.zeros((rows, width))
        s[TARE_SUM, :3] = c._tare_sum
        s[TARE_SUM, TARE_COUNT] = c._tare_count
        s[TARE, :3] = c._tare
        s[TARGET_ROTATION, :9] = np.asarray(c.target_rotation).ravel()
        s[ORIENTATION_ERROR, :3] = c.orientation_error
        s[VELOCITY_REFERENCE, :len(arm)] = c.velocity_reference
        s[VELOCITY_COMMAND, :n] = c.velocity_command
        s[SENSED_FORCE, :3] = c.sensed_force
        for row, name, width_ in ((FORCE, "force", 3), (VIRTUAL_FORCE, "virtual_force", 3),
                                  (ACCELERATION, "acceleration", len(arm))):
            if hasattr(c, name):
                s[row, :width_] = getattr(c, name)
        s[VELOCITY, :3] = c.velocity
        s[TORQUE, :n] = c.torque
        s[GENERALIZED, :n] = c._generalized
        s[QD, :n] = c._qd
        for w, row in enumerate(getattr(c, "_dls_rows", [])):
            s[DLS_X:DLS_Z + 1, w] = row

    def unpack(self) -> None:
        """Put the state back into the controller's attributes, as its Python update leaves them."""
        c, s = self.controller, self.state
        n, n_arm, n_wrist = len(c.joint_names), len(c.arm_joints), len(c.wrist_joints)
        c._tare_sum = s[TARE_SUM, :3].copy()
        c._tare_count = int(s[TARE_SUM, TARE_COUNT])
        c.tare_force = s[TARE, :3].copy()
        c._tare = tuple(c.tare_force.tolist())
        c.velocity_reference = s[VELOCITY_REFERENCE, :n_arm].tolist()
        c.velocity_command = s[VELOCITY_COMMAND, :n].tolist()
        c.sensed_force = tuple(s[SENSED_FORCE, :3].tolist())
        c._qd[:] = s[QD, :n]
        c.jv, c.jr = self.jv, self.jr
        c.position, c.rotation = c.flange.position, c.flange.rotation
        if s[FLAGS, RAN]:
            c.force = tuple(s[FORCE, :3].tolist())
            c.virtual_force = s[VIRTUAL_FORCE, :3].tolist()
            c.acceleration = s[ACCELERATION, :n_arm].tolist()
            c.velocity[:] = s[VELOCITY, :3]
            c.torque[:] = s[TORQUE, :n]
            c._generalized[:] = s[GENERALIZED, :n]
        if s[FLAGS, WRIST_RAN]:
            c.orientation_error = tuple(s[ORIENTATION_ERROR, :3].tolist())
            c._dls_rows = [tuple(s[DLS_X:DLS_Z + 1, w].tolist()) for w in range(n_wrist)]
            c.jr_columns = self.jr.T.tolist()
        s[FLAGS, RAN] = s[FLAGS, WRIST_RAN] = 0.0


# -- 3 x 3 arithmetic on floats, as the Python's -----------------------------------------------------------------
@kernel
def symmetric_inverse(a00, a01, a02, a11, a12, a22):
    """``_symmetric_inverse``: the inverse of a symmetric positive definite 3 x 3 matrix (upper triangle)."""
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    d = 1.0 / (a00 * c00 + a01 * c01 + a02 * c02)
    return c00 * d, c01 * d, c02 * d, c11 * d, c12 * d, c22 * d


@kernel
def symmetric_times(a00, a01, a02, a11, a12, a22, x0, x1, x2):
    """``_symmetric_times``: ``A·x`` for a symmetric A."""
    return (a00 * x0 + a01 * x1 + a02 * x2, a01 * x0 + a11 * x1 + a12 * x2, a02 * x0 + a12 * x1 + a22 * x2)


@kernel
def solve3(m00, m01, m02, m10, m11, m12, m20, m21, m22, b0, b1, b2):
    """``_solve3``: ``M⁻¹·b`` for an invertible 3 x 3 matrix M (Cramer's rule)."""
    c00, c10, c20 = m11 * m22 - m12 * m21, m12 * m20 - m10 * m22, m10 * m21 - m11 * m20
    d = 1.0 / (m00 * c00 + m01 * c10 + m02 * c20)
    return ((c00 * b0 + (m02 * m21 - m01 * m22) * b1 + (m01 * m12 - m02 * m11) * b2) * d,
            (c10 * b0 + (m00 * m22 - m02 * m20) * b1 + (m02 * m10 - m00 * m12) * b2) * d,
            (c20 * b0 + (m01 * m20 - m00 * m21) * b1 + (m00 * m11 - m01 * m10) * b2) * d)


@kernel
def quaternion(m0, m1, m2, m3, m4, m5, m6, m7, m8):
    """``_quaternion``: the unit quaternion (w, x, y, z) of a rotation matrix given row by row."""
    if m0 + m4 + m8 > 0:
        w = 0.5 * math.sqrt(1 + m0 + m4 + m8)
        x, y, z = 0.25 * (m7 - m5) / w, 0.25 * (m2 - m6) / w, 0.25 * (m3 - m1) / w
    elif m0 > m4 and m0 > m8:
        x = 0.5 * math.sqrt(1 + m0 - m4 - m8)
        w, y, z = 0.25 * (m7 - m5) / x, 0.25 * (m1 + m3) / x, 0.25 * (m2 + m6) / x
    elif m4 > m8:
        y = 0.5 * math.sqrt(1 - m0 + m4 - m8)
        w, x, z = 0.25 * (m2 - m6) / y, 0.25 * (m1 + m3) / y, 0.25 * (m5 + m7) / y
    else:
        z = 0.5 * math.sqrt(1 - m0 - m4 + m8)
        w, x, y = 0.25 * (m3 - m1) / z, 0.25 * (m2 + m6) / z, 0.25 * (m5 + m7) / z
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if abs(norm - 1.0) > 1e-15:
        inverse = 1.0 / norm
        w, x, y, z = w * inverse, x * inverse, y * inverse, z * inverse
    return w, x, y, z


@kernel
def rotation_vector(m0, m1, m2, m3, m4, m5, m6, m7, m8):
    """``_rotation_vector``: axis times angle [rad] (angle in [0, π]) of a rotation matrix given row by row."""
    w, x, y, z = quaternion(m0, m1, m2, m3, m4, m5, m6, m7, m8)
    if w < 0:
        w, x, y, z = -w, -x, -y, -z
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        return 2.0 * x, 2.0 * y, 2.0 * z  # small-angle limit
    k = 2.0 * math.atan2(s, w) / s
    return k * x, k * y, k * z


# -- the cycle ---------------------------------------------------------------------------------------------------
@kernel
def cartesian_measure(index, state, addresses, dyn_qpos, qpos_adr, dof_adr, jacp, jacr, xpos, xmat, q, jv, jr,
                      position, velocity, wrench):
    """``_measure``: the joint state, the pose and the flange's Jacobians at it, the sensed force in the base
    frame (``state[SENSED_FORCE]``, before the tare)."""
    n = jv.shape[1]
    for j in range(n):
        i = index[GATHER, j]
        q[j] = position[i]
        state[QD, j] = velocity[i]
    dynamics_set_pose(addresses, dyn_qpos, qpos_adr, q, index[SCALARS_I, MODEL_INERTIA] != 0)
    dynamics_jacobians(addresses, jacp, jacr, index[SCALARS_I, FLANGE_BODY], dof_adr, jv, jr)
    b = index[SCALARS_I, SENSOR_BODY]
    s = index[SCALARS_I, SENSOR_ROW]
    w0, w1, w2 = wrench[s, 0], wrench[s, 1], wrench[s, 2]
    state[SENSED_FORCE, 0] = xmat[b, 0] * w0 + xmat[b, 1] * w1 + xmat[b, 2] * w2
    state[SENSED_FORCE, 1] = xmat[b, 3] * w0 + xmat[b, 4] * w1 + xmat[b, 5] * w2
    state[SENSED_FORCE, 2] = xmat[b, 6] * w0 + xmat[b, 7] * w1 + xmat[b, 8] * w2


@kernel
def wrist_rows(index, parameters, state, jr):
    """``_wrist_rows``: the rows of Jr_W⁺ = Jr_Wᵀ·(Jr_W·Jr_Wᵀ + λ²·I)⁻¹, one per wrist joint, into
    ``state[DLS_X:DLS_Z + 1]``."""
    n_wrist = index[SCALARS_I, N_WRIST]
    g00 = g01 = g02 = g11 = g12 = g22 = 0.0  # Jr_W·Jr_Wᵀ
    for w in range(n_wrist):
        j = index[WRIST, w]
        x, y, z = jr[0, j], jr[1, j], jr[2, j]
        g00 += x * x
        g01 += x * y
        g02 += x * z
        g11 += y * y
        g12 += y * z
        g22 += z * z
    lam2 = parameters[SCALARS, LAMBDA2]
    i00, i01, i02, i11, i12, i22 = symmetric_inverse(g00 + lam2, g01, g02, g11 + lam2, g12, g22 + lam2)
    for w in range(n_wrist):
        j = index[WRIST, w]
        x, y, z = symmetric_times(i00, i01, i02, i11, i12, i22, jr[0, j], jr[1, j], jr[2, j])
        state[DLS_X, w], state[DLS_Y, w], state[DLS_Z, w] = x, y, z


@kernel
def wrist_accelerations(index, parameters, state, jr):
    """``_wrist_accelerations``: q̈_A (``state[ACCELERATION]``, arm order) with the wrist holding the flange
    orientation, H diagonal; the rows of Jr_W⁺ into ``state[DLS_X:DLS_Z + 1]``."""
    n_arm, n_wrist = index[SCALARS_I, N_ARM], index[SCALARS_I, N_WRIST]
    wrist_rows(index, parameters, state, jr)
    q00 = q01 = q02 = q11 = q12 = q22 = 0.0  # Q
    t0 = t1 = t2 = 0.0                       # t
    for w in range(n_wrist):
        j = index[WRIST, w]
        x, y, z = state[DLS_X, w], state[DLS_Y, w], state[DLS_Z, w]  # p_w
        h = parameters[INERTIA, j]
        gj, hx, hy, hz = state[GENERALIZED, j], h * x, h * y, h * z
        q00 += hx * x
        q01 += hx * y
        q02 += hx * z
        q11 += hy * y
        q12 += hy * z
        q22 += hz * z
        t0 += gj * x
        t1 += gj * y
        t2 += gj * z
    k00 = k01 = k02 = k11 = k12 = k22 = 0.0  # K
    y0 = y1 = y2 = 0.0                       # Jr_A·u
    for a in range(n_arm):
        j = index[ARM, a]
        x, y, z = jr[0, j], jr[1, j], jr[2, j]
        hi = parameters[INVERSE_INERTIA, j]
        uj = (state[GENERALIZED, j] - (x * t0 + y * t1 + z * t2)) * hi
        state[U, a] = uj
        y0 += x * uj
        y1 += y * uj
        y2 += z * uj
        hx, hy, hz = hi * x, hi * y, hi * z
        k00 += hx * x
        k01 += hx * y
        k02 += hx * z
        k11 += hy * y
        k12 += hy * z
        k22 += hz * z
    w0, w1, w2 = solve3(  # (I + K·Q)·w = Jr_A·u
        1.0 + k00 * q00 + k01 * q01 + k02 * q02, k00 * q01 + k01 * q11 + k02 * q12,
        k00 * q02 + k01 * q12 + k02 * q22,
        k01 * q00 + k11 * q01 + k12 * q02, 1.0 + k01 * q01 + k11 * q11 + k12 * q12,
        k01 * q02 + k11 * q12 + k12 * q22,
        k02 * q00 + k12 * q01 + k22 * q02, k02 * q01 + k12 * q11 + k22 * q12,
        1.0 + k02 * q02 + k12 * q12 + k22 * q22, y0, y1, y2)
    z0, z1, z2 = symmetric_times(q00, q01, q02, q11, q12, q22, w0, w1, w2)
    for a in range(n_arm):
        j = index[ARM, a]
        x, y, z = jr[0, j], jr[1, j], jr[2, j]
        state[ACCELERATION, a] = state[U, a] - (x * z0 + y * z1 + z * z2) * parameters[INVERSE_INERTIA, j]


@kernel
def cholesky_solve(table, a_row, x_row, n):
    """``_cholesky_solve``: ``A⁻¹·b`` for the symmetric positive definite n x n ``A`` in ``table[a_row:a_row + n,
    :n]`` (its lower triangle read, then overwritten by the factor L) and ``b`` in ``table[x_row, :n]``
    (overwritten by the solution); the same operations in the same order. False (and nothing solved) when a pivot
    is not above zero: ``A`` is not positive definite."""
    for j in range(n):
        pivot = table[a_row + j, j]
        for k in range(j):
            pivot -= table[a_row + j, k] * table[a_row + j, k]
        if not pivot > 0.0:  # (also NaN)
            return False
        d = math.sqrt(pivot)
        table[a_row + j, j] = d
        for i in range(j + 1, n):
            value = table[a_row + i, j]
            for k in range(j):
                value -= table[a_row + i, k] * table[a_row + j, k]
            table[a_row + i, j] = value / d
    for i in range(n):  # L·y = b
        value = table[x_row, i]
        for k in range(i):
            value -= table[a_row + i, k] * table[x_row, k]
        table[x_row, i] = value / table[a_row + i, i]
    for i in range(n - 1, -1, -1):  # Lᵀ·x = y
        value = table[x_row, i]
        for k in range(i + 1, n):
            value -= table[a_row + k, i] * table[x_row, k]
        table[x_row, i] = value / table[a_row + i, i]
    return True


@kernel
def model_accelerations(index, parameters, state, addresses, dof_adr, jr):
    """``_model_accelerations``: q̈_A (``state[ACCELERATION]``, arm order) with H = M(q), the model's inertia:
    ``(Tᵀ·M·T)·q̈_A = Tᵀ·g``, T = [I; -P], P = Jr_W⁺·Jr_A (the rows of Jr_W⁺ into ``state[DLS_X:DLS_Z + 1]``).
    False when the matrix is not positive definite (``state[ACCELERATION]`` unchanged)."""
    n = dof_adr.shape[0]
    n_arm, n_wrist = index[SCALARS_I, N_ARM], index[SCALARS_I, N_WRIST]
    mass = index[SCALARS_I, MASS_ROW]
    lower, mt, pr, full = mass + n, mass + 2 * n, mass + 3 * n, mass + 4 * n
    dynamics_mass_matrix(addresses, index[SCALARS_I, NV], dof_adr, state, full, state, mass)
    if n_wrist == 0:
        for j in range(n):
            state[SOLVE, j] = state[GENERALIZED, j]
        if not cholesky_solve(state, mass, SOLVE, n):
            return False
        for j in range(n):
            state[ACCELERATION, j] = state[SOLVE, j]
        return True
    wrist_rows(index, parameters, state, jr)
    for w in range(n_wrist):  # P = Jr_W⁺·Jr_A
        x, y, z = state[DLS_X, w], state[DLS_Y, w], state[DLS_Z, w]
        for b in range(n_arm):
            a = index[ARM, b]
            state[pr + w, b] = x * jr[0, a] + y * jr[1, a] + z * jr[2, a]
    for i in range(n):  # M·T, row by row
        for b in range(n_arm):
            value = state[mass + i, index[ARM, b]]
            for w in range(n_wrist):
                value -= state[mass + i, index[WRIST, w]] * state[pr + w, b]
            state[mt + i, b] = value
    for b in range(n_arm):  # Tᵀ·M·T and Tᵀ·g
        a = index[ARM, b]
        for c in range(n_arm):
            value = state[mt + a, c]
            for w in range(n_wrist):
                value -= state[pr + w, b] * state[mt + index[WRIST, w], c]
            state[lower + b, c] = value
        value = state[GENERALIZED, a]
        for w in range(n_wrist):
            value -= state[pr + w, b] * state[GENERALIZED, index[WRIST, w]]
        state[SOLVE, b] = value
    if not cholesky_solve(state, lower, SOLVE, n_arm):
        return False
    for b in range(n_arm):
        state[ACCELERATION, b] = state[SOLVE, b]
    return True


@kernel
def wrist_command(index, parameters, state, xmat, jr):
    """``_wrist_command``: the wrist joints' velocities ``Jr_W⁺·(k·e - Jr_A·q̇_A)`` within their limits, into
    ``state[VELOCITY_COMMAND]`` at the wrist joints; the orientation error into ``state[ORIENTATION_ERROR]``."""
    b = index[SCALARS_I, FLANGE_BODY]
    for r in range(3):  # R_0·Rᵀ
        for k in range(3):
            state[ERROR_ROTATION, 3 * r + k] = (state[TARGET_ROTATION, 3 * r] * xmat[b, 3 * k]
                                                + state[TARGET_ROTATION, 3 * r + 1] * xmat[b, 3 * k + 1]
                                                + state[TARGET_ROTATION, 3 * r + 2] * xmat[b, 3 * k + 2])
    e0, e1, e2 = rotation_vector(state[ERROR_ROTATION, 0], state[ERROR_ROTATION, 1], state[ERROR_ROTATION, 2],
                                 state[ERROR_ROTATION, 3], state[ERROR_ROTATION, 4], state[ERROR_ROTATION, 5],
                                 state[ERROR_ROTATION, 6], state[ERROR_ROTATION, 7], state[ERROR_ROTATION, 8])
    state[ORIENTATION_ERROR, 0], state[ORIENTATION_ERROR, 1], state[ORIENTATION_ERROR, 2] = e0, e1, e2
    gain = parameters[SCALARS, WRIST_GAIN]
    b0, b1, b2 = gain * e0, gain * e1, gain * e2
    for a in range(index[SCALARS_I, N_ARM]):
        j = index[ARM, a]
        r = state[VELOCITY_REFERENCE, a]
        b0 -= jr[0, j] * r
        b1 -= jr[1, j] * r
        b2 -= jr[2, j] * r
    for w in range(index[SCALARS_I, N_WRIST]):  # Jr_W⁺·b, row by row
        j = index[WRIST, w]
        c = state[DLS_X, w] * b0 + state[DLS_Y, w] * b1 + state[DLS_Z, w] * b2
        limit = parameters[LIMIT, j]
        state[VELOCITY_COMMAND, j] = -limit if c < -limit else limit if c > limit else c


@kernel
def cartesian_update(index, parameters, state, addresses, dyn_qpos, qpos_adr, dof_adr, jacp, jacr, xpos, xmat, q,
                     jv, jr, time_s, period_s, position, velocity, wrench, velocities):
    """``CartesianAdmittanceController.update``: the velocity controllers' references written into ``velocities``
    (their reference slots). False (nothing written) when the model's inertia is not positive definite, where the
    Python update raises: the cycle then goes on in Python from this update."""
    n = jv.shape[1]
    cartesian_measure(index, state, addresses, dyn_qpos, qpos_adr, dof_adr, jacp, jacr, xpos, xmat, q, jv, jr,
                      position, velocity, wrench)
    if time_s < parameters[SCALARS, TARE_UNTIL] - 1e-9:  # taring: hold still, average the reading
        count = state[TARE_SUM, TARE_COUNT] + 1.0
        state[TARE_SUM, TARE_COUNT] = count
        for a in range(3):
            state[TARE_SUM, a] += state[SENSED_FORCE, a]
            state[TARE, a] = state[TARE_SUM, a] / count
        for j in range(n):
            state[VELOCITY_COMMAND, j] = 0.0
            velocities[index[TARGETS, j]] = 0.0
        return True
    for a in range(3):  # v = Jv·q̇
        v = jv[a, 0] * state[QD, 0]
        for j in range(1, n):
            v += jv[a, j] * state[QD, j]
        state[VELOCITY, a] = v
    b = index[SCALARS_I, FLANGE_BODY]
    for a in range(3):
        sensed = state[SENSED_FORCE, a] - state[TARE, a]
        state[FORCE, a] = sensed
        state[VIRTUAL_FORCE, a] = (parameters[GAINS, a] * (parameters[GAINS, 6 + a] - xpos[b, a])
                                   - parameters[GAINS, 3 + a] * state[VELOCITY, a] + sensed)
    f0, f1, f2 = state[VIRTUAL_FORCE, 0], state[VIRTUAL_FORCE, 1], state[VIRTUAL_FORCE, 2]
    for j in range(n):  # τ = Jvᵀ·f, then τ - c·q̇
        t = f0 * jv[0, j] + f1 * jv[1, j] + f2 * jv[2, j]
        state[TORQUE, j] = t
        state[GENERALIZED, j] = t - parameters[JOINT_DAMPING, j] * state[QD, j]
    n_arm, n_wrist = index[SCALARS_I, N_ARM], index[SCALARS_I, N_WRIST]
    if index[SCALARS_I, MODEL_INERTIA] != 0:
        if not model_accelerations(index, parameters, state, addresses, dof_adr, jr):
            return False  # (the flags as they were: the update made again in Python sets what it sets)
    elif n_wrist > 0:
        wrist_accelerations(index, parameters, state, jr)
    else:
        for j in range(n):
            state[ACCELERATION, j] = state[GENERALIZED, j] / parameters[INERTIA, j]
    state[FLAGS, RAN] = 1.0
    for a in range(n_arm):  # q̇_cmd += q̈·dt once per cycle, within the limits
        j = index[ARM, a]
        r = state[VELOCITY_REFERENCE, a] + state[ACCELERATION, a] * period_s
        limit = parameters[LIMIT, j]
        r = -limit if r < -limit else limit if r > limit else r
        state[VELOCITY_REFERENCE, a] = r
        state[VELOCITY_COMMAND, j] = r
    if n_wrist > 0:
        wrist_command(index, parameters, state, xmat, jr)
        state[FLAGS, WRIST_RAN] = 1.0
    for j in range(n):
        velocities[index[TARGETS, j]] = state[VELOCITY_COMMAND, j]
    return True

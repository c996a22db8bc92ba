"""Fit one joint's rigid-body model to recorded motion: inertia, viscous damping, Coulomb friction, gravity.

The model, per joint with the others held (SI units; rad or m, per s, N or N·m)::

    effort = inertia · qdd + damping · qd + friction · sign(qd) + gravity(q)

``gravity(q)`` is a constant load on a prismatic joint, and ``a·sin(q) + c·cos(q)`` on a revolute
one (the gravity torque on a joint turning about a fixed axis with the others held). The fit is
linear least squares over the samples where the joint moves (``|qd|`` above a fraction of its peak,
where Coulomb friction has a defined sign), with 95 % confidence intervals from the residual
variance (``σ²·(AᵀA)⁻¹``, normal quantile).

Samples: with ``acceleration="forward"`` (a trace of every control cycle), ``qdd`` is the
velocity's forward difference, ``(qd[k+1] - qd[k]) / dt``, the acceleration the effort produced
over that period. A recorder may log the effort a cycle before or after the motion it produced, so
the fit tries effort shifts of 0 to ``max_shift_cycles`` cycles and keeps the one with the smallest
residual (``effort_shift_cycles`` in the result). Samples sparser than the control loop (joint
states at 50 Hz, a bag) take ``acceleration="central"``: ``(qd[k+1] - qd[k-1]) / 2dt``, centred on
the sample whose position, speed and effort it is matched with (a forward difference there would
sit half a sample late); :func:`resample_uniform` first puts such samples on a uniform grid.

A simulated joint integrated with implicit damping (MuJoCo's Euler) shows an inertia larger by
``dt·damping`` (0.01 kg for the 1-DOF robot at 1 kHz: 1 %); the fit reports what the joint does.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike

from jointctl.errors import JointCtlError

#: Samples slower than this fraction of the peak speed are left out (friction's sign undefined there).
MOVING_FRACTION = 0.1
#: 95 % two-sided normal quantile.
Z95 = 1.959963984540054


class IdentificationError(JointCtlError):
    """The data cannot identify the joint (no excitation, too few samples, unknown joint type...)."""

    code = "identification"


@dataclass(frozen=True)
class PlantFit:
    """One joint's identified model. ``inertia`` [kg or kg·m²], ``damping`` [N·s/m or N·m·s/rad],
    ``friction`` (Coulomb) [N or N·m]; ``gravity_load`` [N] (prismatic, the constant load) or
    ``gravity_sin``/``gravity_cos`` [N·m] (revolute: the load is ``sin·sin(q) + cos·cos(q)``);
    ``*_ci95`` their 95 % half-widths; ``residual_rms`` [N or N·m]; ``r_squared`` of the fit;
    ``samples`` used; ``effort_shift_cycles`` the effort's alignment kept; ``acceleration`` the
    differences used ("forward" or "central")."""

    joint_type: str
    inertia: float
    inertia_ci95: float
    damping: float
    damping_ci95: float
    friction: float
    friction_ci95: float
    gravity_load: float
    gravity_load_ci95: float
    gravity_sin: float
    gravity_cos: float
    residual_rms: float
    r_squared: float
    samples: int
    effort_shift_cycles: int
    acceleration: str = "forward"

    def gravity(self, q: ArrayLike) -> np.ndarray:
        """The identified gravity load at positions ``q``."""
        q = np.asarray(q, dtype=float)
        if self.joint_type == "prismatic":
            return np.full_like(q, self.gravity_load)
        return self.gravity_sin * np.sin(q) + self.gravity_cos * np.cos(q)

    def effort(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike) -> np.ndarray:
        """The effort the model predicts for a motion."""
        qd = np.asarray(qd, dtype=float)
        return (self.inertia * np.asarray(qdd, dtype=float) + self.damping * qd
                + self.friction * np.sign(qd) + self.gravity(q))

    def as_dict(self) -> dict:
        return asdict(self)


def resample_uniform(time_s: ArrayLike, *columns: ArrayLike) -> tuple[np.ndarray, ...]:
    """``(t, *columns)`` linearly interpolated onto a uniform grid at the median step of ``time_s``
    (for samples that arrived over a network, where one may be late or lost). Refused when a gap
    exceeds five steps: interpolation there would invent motion."""
    t = np.asarray(time_s, dtype=float)
    if t.size < 2:
        raise IdentificationError("too few samples to fit (at least 50)", field="samples", value=int(t.size))
    order = np.argsort(t, kind="stable")
    t = t[order]
    keep = np.concatenate([[True], np.diff(t) > 0])
    t = t[keep]
    steps = np.diff(t)
    dt = float(np.median(steps)) if steps.size else 0.0
    if not dt > 0:
        raise IdentificationError("the samples' time stamps do not advance", field="time_s", value=dt)
    if steps.max() > 5 * dt:
        at = float(t[int(np.argmax(steps))])
        raise IdentificationError(f"a gap of {steps.max():.3g} s in the samples at t = {at:.3f} s (median step "
                                  f"{dt:.3g} s): samples were lost", field="time_s", value=float(steps.max()))
    grid = t[0] + dt * np.arange(int(math.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    return (grid, *(np.interp(grid, t, np.asarray(c, dtype=float)[order][keep]) for c in columns))


def fit_plant(time_s: ArrayLike, position: ArrayLike, velocity: ArrayLike, effort: ArrayLike, *,
              joint_type: str, max_shift_cycles: int = 2, fit_friction: bool = True,
              acceleration: str = "forward") -> PlantFit:
    """Fit the joint model of the module docstring to uniformly sampled ``time_s`` [s], ``position``,
    ``velocity`` and ``effort``. ``joint_type``: ``"prismatic"``, ``"revolute"`` or
    ``"continuous"``; ``acceleration``: ``"forward"`` or ``"central"`` differences (see the module
    docstring). Raises :class:`IdentificationError` when the data cannot identify it."""
    if joint_type not in ("prismatic", "revolute", "continuous"):
        raise IdentificationError("must be prismatic, revolute or continuous", field="joint_type", value=joint_type)
    if acceleration not in ("forward", "central"):
        raise IdentificationError("must be forward or central", field="acceleration", value=acceleration)
    t, q, qd, u = (np.asarray(x, dtype=float) for x in (time_s, position, velocity, effort))
    if not (t.ndim == q.ndim == qd.ndim == u.ndim == 1 and t.size == q.size == qd.size == u.size):
        raise IdentificationError("time, position, velocity and effort must be 1-D and of one length",
                                  field="samples", value=[x.size for x in (t, q, qd, u)])
    if t.size < 50:
        raise IdentificationError("too few samples to fit (at least 50)", field="samples", value=int(t.size))
    if not all(np.isfinite(x).all() for x in (t, q, qd, u)):
        raise IdentificationError("the trace holds non-finite values", field="samples", value="nan/inf")
    steps = np.diff(t)
    dt = float(np.median(steps))
    if not dt > 0 or np.max(np.abs(steps - dt)) > 1e-6 * max(dt, 1e-9) + 1e-9:
        raise IdentificationError("samples must be uniformly spaced in time (record every cycle)",
                                  field="time_s", value=f"steps from {steps.min():g} to {steps.max():g} s")
    peak = float(np.max(np.abs(qd)))
    travel = float(np.ptp(q))
    if peak < 1e-6 or travel < 1e-6:
        raise IdentificationError(f"the joint does not move (peak speed {peak:.3g}, travel {travel:.3g}): "
                                  "nothing to identify; excite it (jointctl identify ROBOT) or record a motion",
                                  field="velocity", value=peak)
    best = None
    for shift in range(max_shift_cycles + 1):
        fit = _fit_with_shift(t, q, qd, u, dt, shift, joint_type, peak, fit_friction, acceleration)
        if best is None or fit.residual_rms < best.residual_rms:
            best = fit
    return best


def accelerations(qd: np.ndarray, dt: float, shift: int, acceleration: str) -> tuple[slice, np.ndarray]:
    """(the samples the differences belong to, the accelerations there) for an effort shift of ``shift``."""
    n = qd.size - 1 - shift
    if acceleration == "forward":
        return slice(0, n), (qd[1:n + 1] - qd[:n]) / dt
    return slice(1, n), (qd[2:n + 1] - qd[:n - 1]) / (2 * dt)


def _fit_with_shift(t, q, qd, u, dt, shift, joint_type, peak, fit_friction, acceleration) -> PlantFit:
    at, qdd = accelerations(qd, dt, shift, acceleration)
    q0, qd0 = q[at], qd[at]
    u0 = u[at.start + shift:at.stop + shift]
    moving = np.abs(qd0) > MOVING_FRACTION * peak
    if moving.sum() < 20:
        raise IdentificationError("too few samples where the joint moves", field="velocity",
                                  value=int(moving.sum()))
    columns = [qdd, qd0]
    names = ["inertia", "damping"]
    if fit_friction:
        columns.append(np.sign(qd0))
        names.append("friction")
    if joint_type == "prismatic":
        columns.append(np.ones_like(q0))
        names.append("gravity_load")
    else:
        columns += [np.sin(q0), np.cos(q0)]
        names += ["gravity_sin", "gravity_cos"]
    a = np.column_stack(columns)[moving]
    b = u0[moving]
    scale = np.linalg.norm(a, axis=0)
    if np.any(scale == 0) or np.linalg.cond(a / scale) > 1e8:
        raise IdentificationError("the motion does not separate inertia, damping, friction and gravity "
                                  "(excite the joint with changing speed, in both directions)", field="samples",
                                  value=f"condition number {np.linalg.cond(a / np.where(scale == 0, 1, scale)):.3g}")
    x, *_ = np.linalg.lstsq(a, b, rcond=None)
    residual = b - a @ x
    dof = max(len(b) - len(x), 1)
    sigma2 = float(residual @ residual) / dof
    cov = sigma2 * np.linalg.inv(a.T @ a)
    ci = Z95 * np.sqrt(np.maximum(np.diag(cov), 0.0))
    values = dict(zip(names, x.tolist()))
    cis = dict(zip(names, ci.tolist()))
    total = float(((b - b.mean()) ** 2).sum())
    return PlantFit(
        joint_type=joint_type,
        inertia=values["inertia"], inertia_ci95=cis["inertia"],
        damping=values["damping"], damping_ci95=cis["damping"],
        friction=values.get("friction", 0.0), friction_ci95=cis.get("friction", 0.0),
        gravity_load=values.get("gravity_load", 0.0), gravity_load_ci95=cis.get("gravity_load", 0.0),
        gravity_sin=values.get("gravity_sin", 0.0), gravity_cos=values.get("gravity_cos", 0.0),
        residual_rms=math.sqrt(float(residual @ residual) / len(b)),
        r_squared=1.0 - float(residual @ residual) / total if total > 0 else 1.0,
        samples=int(len(b)), effort_shift_cycles=shift, acceleration=acceleration,
    )


__all__ = ["IdentificationError", "PlantFit", "accelerations", "fit_plant", "resample_uniform"]

"""The step response of joints under linear position loops, coupled through their mass matrix.

About a rest pose, n joints each under its own loop move as ::

    M·ẍ + D·ẋ + K·x = f·u

``x`` the joints' deviations from the pose [m or rad], ``M`` the joint-space inertia at the pose,
``D`` the loops' damping (joint damping plus derivative gains), ``K`` their stiffness (position
gains plus the change of the holding efforts with the pose), ``f`` the column through which a step
``u`` of one joint's reference enters (that joint's position gain), SI units throughout. A
derivative on the error adds, in the step's first cycle, an impulse ``d·u`` on that joint (its
"kick"): a velocity ``M⁻¹·d·u`` at the start.

:func:`linear_step` solves it by its modes (the eigenvalues of the first-order form): the final
deviation ``K⁻¹·f·u``, every mode's share of one joint's transient, the mode that dominates it (its
ωn and ζ are what a fit of one damped sinusoid to that joint's response recovers) and the
overshoot of that joint's step. With one joint it is the textbook loop, ``ωn = √(k/m)``,
``ζ = c/(2·√(k·m))``, overshoot ``exp(-πζ/√(1-ζ²))``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import minimize_scalar

__all__ = ["LinearStep", "Mode", "linear_step"]

#: Samples of the transient searched for its peak before the peak is refined.
_SAMPLES = 20_001
#: The transient is followed until its slowest mode has decayed by exp(-this).
_ENVELOPE_TIME_CONSTANTS = 8.0


@dataclass(frozen=True)
class Mode:
    """One mode of the coupled loops: ``natural_frequency_rad_s`` = |λ| [rad/s], ``damping_ratio``
    = -Re λ/|λ| (1 for a real mode), and ``share``, the RMS of its part of the analysed joint's
    transient over the dominant mode's (1 for the dominant one)."""

    natural_frequency_rad_s: float
    damping_ratio: float
    oscillating: bool
    share: float


@dataclass(frozen=True)
class LinearStep:
    """The analysed joint's response to a unit step of its reference.

    ``final`` is its final deviation per unit of step [-]; ``natural_frequency_rad_s`` and
    ``damping_ratio`` those of the dominant mode of its transient; ``overshoot_pct`` its peak
    beyond the final value in percent of the final value [%] (0 if none); ``modes`` every mode,
    dominant first; ``second_share`` the largest share of another mode (0 with one mode);
    ``poles`` [1/s] and ``residues`` [-] the transient's terms, one per mode (an oscillating pair
    once, its residue doubled): :meth:`position` sums them.
    """

    final: float
    natural_frequency_rad_s: float
    damping_ratio: float
    oscillating: bool
    overshoot_pct: float
    modes: tuple[Mode, ...]
    second_share: float
    poles: tuple[complex, ...] = field(default=(), repr=False)
    residues: tuple[complex, ...] = field(default=(), repr=False)

    def position(self, tau_s: ArrayLike) -> np.ndarray:
        """The joint's position change per unit step of its reference [-] at ``tau_s`` [s] after the
        step: 0 at and before it, ``final`` once the transient has died out."""
        tau = np.asarray(tau_s, dtype=float)
        after = np.clip(tau, 0.0, None).ravel()
        poles, residues = np.asarray(self.poles, dtype=complex), np.asarray(self.residues, dtype=complex)
        transient = (residues[:, None] * np.exp(poles[:, None] * after[None, :])).real.sum(axis=0)
        return np.where(tau > 0, self.final + transient.reshape(tau.shape), 0.0)


def linear_step(mass_matrix: ArrayLike, stiffness: ArrayLike, damping: ArrayLike, joint: int, gain: float,
                kick: float = 0.0) -> LinearStep:
    """The response of joint ``joint`` (an index) to a unit step of its reference entering through
    its position gain ``gain`` [N/m or N·m/rad], with a derivative kick impulse ``kick`` per unit of
    step [N·s/m or N·m·s/rad] (its derivative gain under a derivative on the error; 0 otherwise).

    ``mass_matrix``, ``stiffness`` and ``damping`` are n x n (see the module docstring). Raises
    ValueError when the loops have no rest (``K`` singular), are not stable (a mode with Re λ ≥ 0)
    or the step does not move the joint."""
    m = np.atleast_2d(np.asarray(mass_matrix, dtype=float))
    k = np.atleast_2d(np.asarray(stiffness, dtype=float))
    c = np.atleast_2d(np.asarray(damping, dtype=float))
    n = m.shape[0]
    if not (m.shape == k.shape == c.shape == (n, n)) or not 0 <= joint < n:
        raise ValueError("mass, stiffness and damping must be n x n and joint one of the n")
    force = np.zeros(n)
    force[joint] = gain
    try:
        final = np.linalg.solve(k, force)
        m_inv = np.linalg.inv(m)
    except np.linalg.LinAlgError:
        raise ValueError("the loops' stiffness is singular: no rest pose") from None
    step = float(final[joint])
    if not abs(step) > 1e-12 * abs(final).max(initial=1.0):
        raise ValueError("the step does not move the joint")
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-m_inv @ k, -m_inv @ c]])
    lam, vectors = np.linalg.eig(a)
    if np.any(lam.real >= 0):
        worst = lam[np.argmax(lam.real)]
        raise ValueError(f"the loops are not stable about the pose (a mode at {worst:.4g} 1/s)")
    start = np.concatenate([-final, m_inv[:, joint] * kick])
    coeff = np.linalg.solve(vectors, start.astype(complex)) * vectors[joint]
    # One entry per mode: an oscillating pair counted once (its λ with Im > 0, twice its real part).
    keep = [i for i in range(2 * n) if lam[i].imag >= 0]
    lam_m = lam[keep]
    coeff_m = np.where(lam_m.imag > 0, 2.0, 1.0) * coeff[keep]
    sigma = -lam_m.real
    span = _ENVELOPE_TIME_CONSTANTS / sigma.min()
    t = np.linspace(0.0, span, _SAMPLES)
    parts = (coeff_m[:, None] * np.exp(lam_m[:, None] * t[None, :])).real
    rms = np.sqrt(np.mean(parts**2, axis=1))
    order = np.argsort(-rms)
    top = rms[order[0]]
    modes = tuple(Mode(float(abs(lam_m[i])), float(sigma[i] / abs(lam_m[i])), bool(lam_m[i].imag > 0),
                       float(rms[i] / top) if top > 0 else 0.0) for i in order)

    def excursion(time: float) -> float:  # beyond the final value, in the step's direction, per unit of step
        return float(np.sum((coeff_m * np.exp(lam_m * time)).real)) / step

    transient = parts.sum(axis=0) / step
    peak = int(np.argmax(transient))
    overshoot = 0.0
    if transient[peak] > 0:
        lo, hi = t[max(peak - 1, 0)], t[min(peak + 1, t.size - 1)]
        best = minimize_scalar(lambda x: -excursion(x), bounds=(lo, hi), method="bounded",
                               options={"xatol": 1e-12 * span})
        overshoot = 100.0 * max(transient[peak], -best.fun)
    dominant = modes[0]
    return LinearStep(final=step, natural_frequency_rad_s=dominant.natural_frequency_rad_s,
                      damping_ratio=dominant.damping_ratio, oscillating=dominant.oscillating,
                      overshoot_pct=overshoot, modes=modes,
                      second_share=modes[1].share if len(modes) > 1 else 0.0,
                      poles=tuple(complex(x) for x in lam_m), residues=tuple(complex(x) for x in coeff_m))

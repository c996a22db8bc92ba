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
median residual (``effort_shift_cycles`` in the result). Samples sparser than the control loop (joint
states at 50 Hz, a bag) take ``acceleration="central"``: ``(qd[k+1] - qd[k-1]) / 2dt``, centred on
the sample whose position, speed and effort it is matched with (a forward difference there would
sit half a sample late); their callers try no shift (one sample is many cycles).
:func:`resample_uniform` first puts samples that arrived over a network on a uniform grid, at the
period of their stamps (:func:`stamp_period`).

Outliers: a row far off the fit (a residual beyond ``OUTLIER_SIGMAS`` robust standard deviations
and ``OUTLIER_FLOOR`` of the effort's spread) is left out and the fit made again, until nothing
changes (``outliers`` in the result). Such rows hold what one sample cannot show: at 50 Hz a
sample's effort is one cycle's, and a derivative kick in that cycle (a position command that
arrived a cycle late, two steps at once) is not in the motion between samples; with sparse samples
the rows whose central difference takes such a sample's velocity (that cycle's too) are left out
with it (``left_out`` counts all). Every cycle recorded, the kicks are in the motion and fit; a row
left out there spans a cycle that was lost unseen (its acceleration read twice over).

Gaps: samples lost on the way (a dropped message, a 10 ms hiccup of a busy machine) are cut out, not
invented. A step between samples longer than ``GAP_STEPS`` sampling periods (one lost sample is
enough: interpolating across it would make up the motion there, (ω·h)²/8 of a swing at frequency ω
over a gap h) splits the samples into stretches; differences are taken inside a stretch only (no
difference spans a gap, nor does an effort shift), and the rows of every stretch go into one fit.
The fit reports what it used (``samples_given``, ``samples``, ``gaps`` with their times and lengths,
``usable_s`` of ``span_s``) and refuses only when fewer than ``MIN_SAMPLES`` rows are left, saying
how much time was usable.

A joint of a chain: the other joints' motion loads the joint through the inertia matrix (their
accelerations, the Coriolis and centrifugal products of their speeds) and shifts its gravity. A
caller that knows that load (:mod:`jointctl.identification.coupling`, from the robot's model) gives it
as ``coupling_torque``, subtracted from the effort before the fit, and gives
``inertia_scale = M_ii(q) / M_ii(q̄)`` when the joint's own inertia changes with the others' pose:
the inertia column becomes ``inertia_scale · qdd`` and ``inertia`` is the joint's inertia at the pose
``q̄``, ``gravity(q)`` the joint's gravity load with the others at ``q̄`` (``coupling`` in the result
says "model"; ``coupling_rms`` the load's RMS over the fitted rows).

A simulated joint integrated with implicit damping (MuJoCo's Euler) shows an inertia larger by
``dt·damping`` (0.01 kg for the 1-DOF robot at 1 kHz: 1 %); the fit reports what the joint does.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.ndimage import median_filter
from scipy.optimize import minimize_scalar

from jointctl.errors import JointCtlError

#: Samples slower than this fraction of the peak speed are left out (friction's sign undefined there).
MOVING_FRACTION = 0.1
#: A step between samples longer than this many sampling periods is a gap: samples were lost there.
#: One lost sample makes a step of two periods; jitter of a stamp up to half a period is not a gap.
GAP_STEPS = 1.5
#: Samples around a stamp (it in the middle) whose median offset says how many loop cycles were lost before it.
CYCLE_WINDOW = 15
#: Most cycles a recorder may log the effort off the motion it produced (the shifts the fit tries).
MAX_SHIFT_CYCLES = 2
#: Fewest rows (samples whose differences lie inside one stretch) a fit takes.
MIN_SAMPLES = 50
#: Fewest of them where the joint moves.
MIN_MOVING = 20
#: A row whose residual is more than this many standard deviations (the residuals' robust one,
#: 1.4826 times their median absolute deviation) off the fit is an outlier: left out, and the fit made again.
OUTLIER_SIGMAS = 5.0
#: ... and more than this share of the effort's standard deviation (a residual below it is the model's).
OUTLIER_FLOOR = 0.01
#: At most this many fits, each without the outliers of the one before.
OUTLIER_PASSES = 5
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
    ``*_ci95`` their 95 % half-widths; ``residual_rms`` [N or N·m] and ``r_squared`` of the fit (over
    the rows it kept), ``residual_median`` [N or N·m] the median absolute residual over every row;
    ``samples`` used (the rows of the least squares: where the joint moves, differences inside one
    stretch, not left out), ``outliers`` the rows left out as off the fit and ``left_out`` all rows left
    out (with their neighbours, see the module docstring); ``effort_shift_cycles`` the effort's alignment
    kept; ``acceleration`` the differences used ("forward" or "central"). The data: ``samples_given``
    samples in the fit's input, ``sample_period_s`` [s] their period, ``span_s`` [s] the time they span,
    ``usable_s`` [s] the time of the stretches left after cutting ``gaps`` (each ``(at_s, length_s)``:
    the time of the last sample before it and the step across it [s]). The chain:
    ``coupling`` "model" when the other joints' load was subtracted (see the module docstring), "none"
    when not; ``coupling_rms`` [N or N·m] that load's RMS over the fitted rows."""

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
    samples_given: int = 0
    span_s: float = 0.0
    usable_s: float = 0.0
    gaps: tuple[tuple[float, float], ...] = ()
    coupling: str = "none"
    coupling_rms: float = 0.0
    sample_period_s: float = 0.0
    outliers: int = 0
    left_out: int = 0
    residual_median: float = 0.0

    @property
    def share_used(self) -> float:
        """The share of the recording's time left in the fit's stretches (1 without gaps)."""
        return self.usable_s / self.span_s if self.span_s > 0 else 0.0

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


def resample_uniform(time_s: ArrayLike, *columns: ArrayLike, cycles: bool = False,
                     period_s: float | None = None) -> tuple[np.ndarray, ...]:
    """``(t, *columns)`` on a uniform grid at the period of the stamps ``time_s`` [s] (``period_s``, else
    :func:`stamp_period`'s): samples that arrived over a network, stamped off their period. A step longer
    than ``GAP_STEPS`` periods (samples lost) is never bridged: ``t`` jumps across it and
    :func:`fit_plant` cuts the samples there.

    ``cycles``: each sample is one cycle of the control loop (joint states published every cycle),
    stamped when the cycle ran (ros_control's ``ros::Time::now()`` at the top of the cycle: late by the
    loop's jitter) while its values are the cycle's. Such samples are not interpolated (at a jitter of a
    third of a period, interpolating at the stamps makes a noise of half the acceleration, which the fit
    reads as 20-40 % less inertia): each takes the grid point of its cycle (:func:`_cycle_numbers`), and
    a cycle lost makes a gap. Otherwise (sparser samples, each many cycles apart) the columns are linearly interpolated
    onto a grid of their own in each stretch between gaps (at its stamps' median phase): interpolation
    only puts jittered stamps on the grid, it never invents motion."""
    t = np.asarray(time_s, dtype=float)
    if t.size < 2:
        raise IdentificationError(f"too few samples to fit (at least {MIN_SAMPLES})", field="samples",
                                  value=int(t.size))
    order = np.argsort(t, kind="stable")
    t = t[order]
    keep = np.concatenate([[True], np.diff(t) > 0])
    t = t[keep]
    steps = np.diff(t)
    dt = (stamp_period(t) if period_s is None else float(period_s)) if steps.size else 0.0
    if not dt > 0:
        raise IdentificationError("the samples' time stamps do not advance", field="time_s", value=dt)
    values = [np.asarray(c, dtype=float)[order][keep] for c in columns]
    if cycles:
        return (t[0] + dt * _cycle_numbers(t, dt), *values)
    cuts = np.concatenate([[0], np.nonzero(steps > GAP_STEPS * dt)[0] + 1, [t.size]])
    grids, parts = [], [[] for _ in values]
    for a, b in zip(cuts[:-1], cuts[1:]):
        # The stretch's grid: its stamps' typical phase (the median offset from whole periods after its
        # first), from the grid point nearest its first stamp to the one nearest its last, and still a
        # gap (more than GAP_STEPS periods) after the grid before it.
        since = t[a:b] - t[a]
        start = t[a] + float(np.median(since - dt * np.round(since / dt)))
        grid = start + dt * np.arange(round((t[a] - start) / dt), round((t[b - 1] - start) / dt) + 1)
        if grids:
            grid = grid[grid - grids[-1][-1] > GAP_STEPS * dt * (1 + 1e-9)]
        if not grid.size:
            continue
        grids.append(grid)
        for part, column in zip(parts, values):
            part.append(np.interp(grid, t[a:b], column[a:b]))
    return (np.concatenate(grids), *(np.concatenate(part) for part in parts))


def _cycle_numbers(t: np.ndarray, dt: float) -> np.ndarray:
    """The loop cycle of each of the increasing stamps ``t`` [s] (the first's is 0), a cycle ``dt`` [s]
    long, each stamp late by up to a cycle (see :func:`resample_uniform`). A stamp's own lateness makes
    its cycle ambiguous (one late by two thirds of a period is nearer the next cycle's time), but the
    cycles lost before it are the same for its neighbours: the stamps' offset from ``dt`` per sample,
    ``(t - t[0])/dt - index``, is that count plus the lateness, and its running median over
    ``CYCLE_WINDOW`` samples is the count plus the typical lateness (its common fraction of a period,
    taken off). The count never falls; a jump of it is a gap."""
    offset = (t - t[0]) / dt - np.arange(t.size)
    level = median_filter(offset, size=CYCLE_WINDOW, mode="nearest")
    lateness = float(np.angle(np.mean(np.exp(2j * np.pi * level)))) / (2 * np.pi)
    lost = np.maximum.accumulate(np.round(level - lateness)).astype(int)
    return np.arange(t.size) + lost - lost[0]


def stamp_period(time_s: ArrayLike) -> float:
    """The period [s] of samples stamped ``time_s`` (increasing): the period whose whole multiples the
    stamps sit on. Exactly spaced stamps (a simulation's, with gaps or not) give their median step. Stamps
    late by a loop's jitter give the period at which their phases ``2π·t/T`` are most coherent
    (:func:`_coherent_period`): each stamp is a whole number of periods after the first plus its
    lateness, whichever cycles were lost. (Steps do not give it: a stamp late by a third of a period
    makes the next step short, which is just when a publisher skips that cycle, so the steps left are
    longer than the period: 3 % at the jitter of a real ros_control robot.)"""
    t = np.asarray(time_s, dtype=float)
    steps = np.diff(t)
    dt = float(np.median(steps))
    exact = (np.abs(steps - dt) <= 1e-9 * dt) | (steps > GAP_STEPS * dt)
    if exact.all():
        return dt
    near = steps[np.abs(steps - dt) <= 0.5 * dt]  # a first guess: the steps near the median, averaged
    return _coherent_period(t - t[0], float(np.mean(near)) if near.size else dt)


def _coherent_period(t: np.ndarray, guess: float) -> float:
    """The period within 10 % of ``guess`` [s] at which the phases of the stamps ``t`` [s] (from 0) are
    most coherent (``|Σ exp(2πi·t/T)|`` largest), or ``guess`` when no period stands out of the
    incoherent ``√N``. The peak is ``T²/span`` wide over stamps spanning ``span``: searched over the
    first thousand periods on a grid a quarter of that fine, then on eight times as many stamps each
    time around the best so far, ending with all of them and a bounded scalar search."""
    def power(periods, stamps):
        return np.abs(np.exp(2j * np.pi * stamps[:, None] / np.asarray(periods)[None, :]).sum(axis=0))

    period, width, span = guess, 0.1 * guess, 1000 * guess
    while True:
        stamps = t[t <= span]
        peak = period**2 / max(stamps[-1], period)
        candidates = period + np.linspace(-width, width, 2 * math.ceil(4 * width / peak) + 1)
        coherence = power(candidates, stamps)
        best = int(np.argmax(coherence))
        if coherence[best] < 4 * math.sqrt(stamps.size):
            return guess
        period = float(candidates[best])
        if stamps.size == t.size:
            break
        width, span = 2 * peak, 8 * span
    step = float(candidates[1] - candidates[0])
    found = minimize_scalar(lambda p: -power([p], t)[0], bounds=(period - step, period + step), method="bounded",
                            options={"xatol": 1e-12 * period})
    return float(found.x)


def sampling_period(steps: np.ndarray) -> float:
    """The period [s] of samples ``steps`` apart: their median step, or, when most steps are gaps
    (longer than ``GAP_STEPS`` times the shortest), the median of the others."""
    dt = float(np.median(steps))
    shortest = float(steps.min())
    if dt > GAP_STEPS * shortest:
        dt = float(np.median(steps[steps <= GAP_STEPS * shortest]))
    return dt


@dataclass(frozen=True)
class Stretches:
    """Samples split at their gaps: ``dt`` [s] the sampling period, ``index`` the stretch of every
    sample (0, 1, ...), ``gaps`` ``(at_s, length_s)`` of each cut, ``span_s`` and ``usable_s`` [s]
    (the time the samples span, ``dt`` more than last minus first, and that less the time lost in
    the gaps: each gap's step less one period)."""

    dt: float
    index: np.ndarray
    gaps: tuple[tuple[float, float], ...]
    span_s: float
    usable_s: float

    def describe(self) -> str:
        """How much is left, e.g. ``0.8 s of 10 s usable after cutting 3 gaps``."""
        n = len(self.gaps)
        return f"{self.usable_s:.3g} s of {self.span_s:.3g} s usable after cutting {n} gap{'s' * (n != 1)}"


def stretches(time_s: ArrayLike) -> Stretches:
    """Split ``time_s`` [s] (increasing) at its gaps (steps longer than ``GAP_STEPS`` periods, the
    period from :func:`sampling_period`); every other step must be the period (within 1e-6 of it,
    relative): IdentificationError otherwise."""
    t = np.asarray(time_s, dtype=float)
    steps = np.diff(t)
    if steps.size == 0 or not steps.min() > 0:
        raise IdentificationError("samples must be uniformly spaced in time (record every cycle)", field="time_s",
                                  value=f"steps from {steps.min() if steps.size else math.nan:g} s")
    dt = sampling_period(steps)
    gap = steps > GAP_STEPS * dt
    uneven = ~gap & (np.abs(steps - dt) > 1e-6 * dt + 1e-9)
    if uneven.any():
        raise IdentificationError("samples must be uniformly spaced in time (record every cycle)",
                                  field="time_s", value=f"steps from {steps.min():g} to {steps.max():g} s")
    at = np.nonzero(gap)[0]
    index = np.concatenate([[0], np.cumsum(gap)])
    span = float(t[-1] - t[0] + dt)
    return Stretches(dt, index, tuple((float(t[k]), float(steps[k])) for k in at), span,
                     span - float(np.sum(steps[at] - dt)))


def difference_rows(index: np.ndarray, qd: np.ndarray, dt: float, shift: int,
                    acceleration: str) -> tuple[np.ndarray, np.ndarray]:
    """(rows, accelerations there): the samples whose velocity difference (``acceleration``:
    "forward" ``(qd[k+1] - qd[k]) / dt``, "central" ``(qd[k+1] - qd[k-1]) / 2dt``) and effort ``shift``
    cycles later lie inside one stretch (``index``: the stretch of every sample, :func:`stretches`).
    ``qd`` may hold one column per joint (N x n)."""
    first = 0 if acceleration == "forward" else 1
    reach = max(1, shift)
    k = np.arange(first, index.size - reach)
    rows = k[index[k - first] == index[k + reach]]
    if acceleration == "forward":
        return rows, (qd[rows + 1] - qd[rows]) / dt
    return rows, (qd[rows + 1] - qd[rows - 1]) / (2 * dt)


def accelerations(qd: np.ndarray, dt: float, shift: int, acceleration: str) -> tuple[slice, np.ndarray]:
    """(the samples the differences belong to, the accelerations there) for an effort shift of
    ``shift``, on samples without gaps (see :func:`difference_rows` for samples with gaps)."""
    n = qd.size - 1 - shift
    if acceleration == "forward":
        return slice(0, n), (qd[1:n + 1] - qd[:n]) / dt
    return slice(1, n), (qd[2:n + 1] - qd[:n - 1]) / (2 * dt)


def fit_plant(time_s: ArrayLike, position: ArrayLike, velocity: ArrayLike, effort: ArrayLike, *,
              joint_type: str, max_shift_cycles: int = MAX_SHIFT_CYCLES, fit_friction: bool = True,
              acceleration: str = "forward", coupling_torque: ArrayLike | None = None,
              inertia_scale: ArrayLike | None = None) -> PlantFit:
    """Fit the joint model of the module docstring to ``time_s`` [s], ``position``, ``velocity`` and
    ``effort`` sampled at a uniform period, with gaps cut out (see the module docstring).
    ``joint_type``: ``"prismatic"``, ``"revolute"`` or ``"continuous"``; ``acceleration``:
    ``"forward"`` or ``"central"`` differences; effort shifts of 0 to ``max_shift_cycles`` samples are
    tried. ``coupling_torque`` [N or N·m] (the other joints' load
    on this one, per sample, computed with the same differences; NaN where undefined) and
    ``inertia_scale`` (``M_ii(q) / M_ii(q̄)`` per sample) come from
    :mod:`jointctl.identification.coupling`. Raises :class:`IdentificationError` when the data cannot
    identify it."""
    if joint_type not in ("prismatic", "revolute", "continuous"):
        raise IdentificationError("must be prismatic, revolute or continuous", field="joint_type", value=joint_type)
    if acceleration not in ("forward", "central"):
        raise IdentificationError("must be forward or central", field="acceleration", value=acceleration)
    t, q, qd, u = (np.asarray(x, dtype=float) for x in (time_s, position, velocity, effort))
    if not (t.ndim == q.ndim == qd.ndim == u.ndim == 1 and t.size == q.size == qd.size == u.size):
        raise IdentificationError("time, position, velocity and effort must be 1-D and of one length",
                                  field="samples", value=[x.size for x in (t, q, qd, u)])
    if t.size < 2:
        raise IdentificationError(f"too few samples to fit (at least {MIN_SAMPLES})", field="samples",
                                  value=int(t.size))
    if not all(np.isfinite(x).all() for x in (t, q, qd, u)):
        raise IdentificationError("the trace holds non-finite values", field="samples", value="nan/inf")
    coupling = _per_sample(coupling_torque, t.size, "coupling_torque")
    scale = _per_sample(inertia_scale, t.size, "inertia_scale")
    split = stretches(t)
    rows, _ = difference_rows(split.index, qd, split.dt, 0, acceleration)
    if rows.size < MIN_SAMPLES:
        if split.gaps:
            raise IdentificationError(f"only {split.describe()}: need at least {MIN_SAMPLES} samples inside "
                                      f"unbroken stretches, {rows.size} left", field="samples", value=int(rows.size))
        raise IdentificationError(f"too few samples to fit (at least {MIN_SAMPLES})", field="samples",
                                  value=int(t.size))
    peak = float(np.max(np.abs(qd)))
    travel = float(np.ptp(q))
    if peak < 1e-6 or travel < 1e-6:
        raise IdentificationError(f"the joint does not move (peak speed {peak:.3g}, travel {travel:.3g}): "
                                  "nothing to identify; excite it (jointctl identify ROBOT) or record a motion",
                                  field="velocity", value=peak)
    best = None
    for shift in range(max_shift_cycles + 1):
        fit = _fit_with_shift(q, qd, u, split, shift, joint_type, peak, fit_friction, acceleration, coupling,
                              scale)
        if best is None or fit.residual_median < best.residual_median:
            best = fit
    return best


def _per_sample(values, n: int, name: str) -> np.ndarray | None:
    if values is None:
        return None
    a = np.asarray(values, dtype=float)
    if a.shape != (n,):
        raise IdentificationError(f"must hold one value per sample ({n})", field=name, value=list(a.shape))
    return a


def _fit_with_shift(q, qd, u, split: Stretches, shift, joint_type, peak, fit_friction, acceleration,
                    coupling, scale) -> PlantFit:
    rows, qdd = difference_rows(split.index, qd, split.dt, shift, acceleration)
    q0, qd0, u0 = q[rows], qd[rows], u[rows + shift]
    load = np.zeros(rows.size) if coupling is None else coupling[rows]
    inertia_column = qdd if scale is None else scale[rows] * qdd
    moving = (np.abs(qd0) > MOVING_FRACTION * peak) & np.isfinite(load) & np.isfinite(inertia_column)
    if moving.sum() < MIN_MOVING:
        left = f" ({split.describe()})" if split.gaps else ""
        raise IdentificationError(f"too few samples where the joint moves{left}", field="velocity",
                                  value=int(moving.sum()))
    columns = [inertia_column, qd0]
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
    b = (u0 - load)[moving]
    norm = np.linalg.norm(a, axis=0)
    if np.any(norm == 0) or np.linalg.cond(a / norm) > 1e8:
        raise IdentificationError("the motion does not separate inertia, damping, friction and gravity "
                                  "(excite the joint with changing speed, in both directions)", field="samples",
                                  value=f"condition number {np.linalg.cond(a / np.where(norm == 0, 1, norm)):.3g}")
    kept = _inliers(a, b)
    outliers = int((~kept).sum())
    if acceleration == "central":
        # A sample whose effort is off the motion at 50 Hz holds one cycle's event (a derivative kick), and
        # its velocity that cycle's too: the rows whose difference takes it are left out as well.
        odd = np.zeros(q.size + 1, dtype=bool)
        odd[rows[moving][~kept]] = True
        kept &= ~(odd[rows[moving] - 1] | odd[rows[moving] + 1])
    x, *_ = np.linalg.lstsq(a[kept], b[kept], rcond=None)
    everywhere = b - a @ x
    a, b = a[kept], b[kept]
    residual = everywhere[kept]
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
        outliers=outliers, left_out=int((~kept).sum()), residual_median=float(np.median(np.abs(everywhere))),
        samples_given=int(q.size), span_s=split.span_s, usable_s=split.usable_s, gaps=split.gaps,
        sample_period_s=split.dt,
        coupling="none" if coupling is None else "model",
        coupling_rms=0.0 if coupling is None else float(np.sqrt(np.mean(load[moving][kept] ** 2))),
    )


def _inliers(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rows of ``a·x = b`` that are not outliers (see ``OUTLIER_SIGMAS``): fitted by least squares,
    the rows far off the fit left out, fitted again without them, until nothing changes."""
    kept = np.ones(len(b), dtype=bool)
    floor = OUTLIER_FLOOR * float(np.std(b))
    for _ in range(OUTLIER_PASSES):
        x, *_ = np.linalg.lstsq(a[kept], b[kept], rcond=None)
        residual = b - a @ x
        spread = 1.4826 * float(np.median(np.abs(residual[kept] - np.median(residual[kept]))))
        inliers = np.abs(residual) <= max(OUTLIER_SIGMAS * spread, floor)
        if np.array_equal(inliers, kept) or inliers.sum() < MIN_MOVING:
            break
        kept = inliers
    return kept


__all__ = ["GAP_STEPS", "IdentificationError", "MAX_SHIFT_CYCLES", "MIN_SAMPLES", "PlantFit", "Stretches",
           "accelerations", "difference_rows", "fit_plant", "resample_uniform", "sampling_period", "stamp_period",
           "stretches"]

"""Trajectory goals of the chapter's example clients, generated in-process.

:func:`coarse_sine` is the chapter's ``example_trajectory_action_client``: a
sine sampled coarsely and irregularly (figure 11.8), with velocities filled in.
"""

from __future__ import annotations

import math

import numpy as np

from jointctl.trajectory.messages import JointTrajectory


def coarse_sine(*, joint: str = "joint1", seed: int = 0, offset: float = 0.5, amplitude: float = 0.5,
                omega_rad_s: float = 1.0, periods: float = 2.0, first_time_s: float = 0.1,
                min_step_s: float = 0.01, max_step_s: float = 1.0) -> JointTrajectory:
    """q = offset + amplitude·sin(ω t) sampled at irregular times.

    The first point is at ``first_time_s``; each next one after a step drawn
    uniformly from {min_step_s, min_step_s + 0.01, ..., max_step_s} (seeded), until
    ``periods`` periods have passed; the last point is exactly at the end.
    Velocities are the sine's derivative (the chapter's client fills them; its
    server ignores them).
    """
    rng = np.random.default_rng(seed)
    steps = np.round(np.arange(min_step_s, max_step_s + 1e-9, 0.01), 2)
    end = periods * 2 * math.pi / omega_rad_s
    times = [first_time_s]
    while times[-1] < end:
        times.append(min(end, times[-1] + float(rng.choice(steps))))
    t = np.array(times)
    q = offset + amplitude * np.sin(omega_rad_s * t)
    v = amplitude * omega_rad_s * np.cos(omega_rad_s * t)
    return JointTrajectory.from_arrays([joint], t, q[:, None], v[:, None])

"""The compiled form of :class:`~jointctl.control.pid.Pid`: :func:`pid_compute` is ``Pid.compute``, term for term.

A PID's gains are a row of floats (:func:`pid_gains`, indexed by the names below); its integral state is the
caller's, passed in and returned.
"""

from __future__ import annotations

from jointctl.control.pid import Pid
from jointctl.jit import kernel

#: The gains row: p, i, d (effort per error unit, per error unit·s, per error unit/s), the integral clamp
#: [effort], antiwindup (1.0 or 0.0) and the output limit [effort].
P, I, D, I_MIN, I_MAX, ANTIWINDUP, OUTPUT_LIMIT = range(7)
GAINS = 7


def pid_gains(pid: Pid) -> list[float]:
    """``pid``'s gains as the kernel's row."""
    p, i, d, i_min, i_max, antiwindup = pid._g
    return [p, i, d, i_min, i_max, 1.0 if antiwindup else 0.0, pid.output_limit]


@kernel
def pid_compute(gains, i_state, error, error_rate, dt):
    """(effort, the integral state after this call) for ``error``, its rate [error/s] over ``dt`` [s]."""
    i_state = i_state + gains[I] * dt * error
    i_min, i_max = gains[I_MIN], gains[I_MAX]
    if gains[ANTIWINDUP] != 0.0:
        i_state = i_min if i_state < i_min else i_max if i_state > i_max else i_state
    i_term = i_min if i_state < i_min else i_max if i_state > i_max else i_state
    u = gains[P] * error + i_term + gains[D] * error_rate
    limit = gains[OUTPUT_LIMIT]
    return (limit if u > limit else -limit if u < -limit else u), i_state

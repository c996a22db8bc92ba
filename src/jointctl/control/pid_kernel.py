"""The compiled form of :class:`~jointctl.control.pid.Pid`: :func:`pid_compute` is ``Pid.compute``, term for term.

A PID's gains are part of a row of floats (:func:`pid_gains`, indexed from the row's ``first`` column by the names
below); its integral state is the caller's, passed in and returned. Like every kernel it takes the compiled
cycle's table and a row number (every controller's parameters in one array).
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
def pid_compute(table, row, first, i_state, error, error_rate, dt):
    """(effort, the integral state after this call) for ``error``, its rate [error/s] over ``dt`` [s], with the
    gains at ``table[row, first:]``."""
    i_state = i_state + table[row, first + I] * dt * error
    i_min, i_max = table[row, first + I_MIN], table[row, first + I_MAX]
    if table[row, first + ANTIWINDUP] != 0.0:
        i_state = i_min if i_state < i_min else i_max if i_state > i_max else i_state
    i_term = i_min if i_state < i_min else i_max if i_state > i_max else i_state
    u = table[row, first + P] * error + i_term + table[row, first + D] * error_rate
    limit = table[row, first + OUTPUT_LIMIT]
    return (limit if u > limit else -limit if u < -limit else u), i_state

"""The compiled form of :meth:`~jointctl.metrics.step_loop.JointLoop.run`: the same loop, statement for statement,
on arrays (a design search runs it thousands of times; a sweep's analysis once a run).

Its loads are :class:`~jointctl.metrics.step_loop.HoldingEffort` tables (or none), read by :func:`table_hold` as
``HoldingEffort.__call__`` reads them; a loop whose load is another callable runs in Python. :func:`loop_run`
fills the position [m or rad], velocity and effort [N or N·m] of each cycle and returns how many it ran.
"""

from __future__ import annotations

from jointctl.jit import kernel


@kernel
def table_hold(left, spacing, values, slopes, position):
    """``HoldingEffort.__call__``: the effort [N or N·m] at ``position`` [m or rad]."""
    last = slopes.shape[0] - 1
    cell = int((position - left) // spacing)
    cell = 0 if cell < 0 else last if cell > last else cell
    return values[cell] + slopes[cell] * (position - left - cell * spacing)


@kernel
def loop_run(plant, gains, flags, reference, rates, hold_grid, hold_values, hold_slopes, model_grid, model_values,
             model_slopes, start, pending, arrived, qs, vs, us):
    """``JointLoop.run``'s cycles. ``plant``: a00, a01, a10, a11, b0, b1; ``gains``: h, p, i, d, the effort
    limit, the integral's low and high clamps; ``flags``: antiwindup, the derivative on the error, rates given,
    feed-forward, the feed-forward's own model (the load), a load, until the peak; ``start``: q, v, the
    integral, the last error; ``pending``: the commands on their way (a ring, ``delay_cycles`` long);
    ``hold_grid``/``model_grid``: (left, spacing) of the load's and the feed-forward's tables. Returns the
    cycles run."""
    a00, a01, a10, a11, b0, b1 = plant[0], plant[1], plant[2], plant[3], plant[4], plant[5]
    h, p, i, d, limit, low, clamp = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5], gains[6]
    antiwindup, on_error, has_rates = flags[0] != 0.0, flags[1] != 0.0, flags[2] != 0.0
    feedforward, own_model, has_hold, until_peak = flags[3] != 0.0, flags[4] != 0.0, flags[5] != 0.0, flags[6] != 0.0
    q, v, i_state, e_last = start[0], start[1], start[2], start[3]
    n = reference.shape[0]
    direction = 1.0 if reference[n - 1] >= reference[0] else -1.0
    delay = pending.shape[0]
    slot = 0
    count = 0
    for k in range(n):
        if until_peak and k > arrived and v * direction <= 0.0:
            break
        e = reference[k] - q
        if has_rates:
            rate = rates[k] - v
        else:
            rate = (e - e_last) / h if on_error else -v
            e_last = e
        if i != 0.0:
            i_state += i * h * e
            if antiwindup:
                i_state = clamp if i_state > clamp else low if i_state < low else i_state
            i_term = clamp if i_state > clamp else low if i_state < low else i_state
        else:
            i_term = 0.0
        u = p * e + i_term + d * rate
        u = limit if u > limit else -limit if u < -limit else u
        load = table_hold(hold_grid[0], hold_grid[1], hold_values, hold_slopes, q) if has_hold else 0.0
        if feedforward:
            u += load if own_model else table_hold(model_grid[0], model_grid[1], model_values, model_slopes, q)
            u = limit if u > limit else -limit if u < -limit else u
        qs[count] = q
        vs[count] = v
        us[count] = u
        count += 1
        if delay > 0:
            pending[slot], u = u, pending[slot]
            slot = slot + 1 if slot + 1 < delay else 0
        force = u - load
        q, v = a00 * q + a01 * v + b0 * force, a10 * q + a11 * v + b1 * force
    return count

"""The compiled PID computes what :class:`~jointctl.control.pid.Pid` computes, bit for bit: the same terms in the
same order, for any gains, clamps and inputs."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings, strategies as st

from jointctl.control.pid import Pid, PidGains
from jointctl.control.pid_kernel import pid_compute, pid_gains

finite = st.floats(-1e6, 1e6, allow_nan=False)
gain = st.floats(0.0, 1e4, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(p=gain, i=gain, d=gain, clamp=st.floats(0.0, 50.0), antiwindup=st.booleans(),
       limit=st.sampled_from([math.inf, 100.0, 1.0]), steps=st.lists(st.tuples(finite, finite), min_size=1,
                                                                        max_size=20))
def test_the_kernel_is_pid_compute(p, i, d, clamp, antiwindup, limit, steps):
    pid = Pid(PidGains(p, i, d, -clamp, clamp, antiwindup), limit)
    table = np.array([[0.0, *pid_gains(pid)]])  # the gains from column 1 of row 0
    i_state = 0.0
    for error, rate in steps:
        expected = pid.compute(error, rate, 0.001)
        effort, i_state = pid_compute(table, 0, 1, i_state, error, rate, 0.001)
        assert effort == expected and i_state == pid.i_state

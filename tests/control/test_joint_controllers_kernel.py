"""The compiled position controller's pieces: the angle wrap and the counted clamp are the Python ones."""

from __future__ import annotations

import math

import numpy as np

from jointctl.control.joint_controllers import wrap_angle
from jointctl.control.joint_controllers_kernel import CLAMPED, FURTHEST, HAS_FURTHEST, STATE, clamp_counted
from jointctl.control.joint_controllers_kernel import wrap_angle as wrap_kernel


def test_the_wrap_is_the_python_wrap():
    angles = [*np.linspace(-40.0, 40.0, 20001), math.pi, -math.pi, 3 * math.pi, -3 * math.pi,
              math.nextafter(math.pi, 4.0), math.nextafter(-math.pi, -4.0), 1e9, -1e9]
    assert [wrap_kernel(a) for a in angles] == [wrap_angle(a) for a in angles]


def test_the_clamp_counts_and_keeps_the_reference_furthest_outside():
    state = np.zeros((2, STATE))
    assert clamp_counted(state, 1, 1.5, -1.0, 1.0) == 1.0
    assert clamp_counted(state, 1, -3.0, -1.0, 1.0) == -1.0
    assert clamp_counted(state, 1, 1.2, -1.0, 1.0) == 1.0
    assert state[1, CLAMPED] == 3 and state[1, HAS_FURTHEST] == 1.0 and state[1, FURTHEST] == -3.0
    assert not state[0].any()

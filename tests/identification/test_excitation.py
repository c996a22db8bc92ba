"""The safe chirp: inside the range and the speed limit, starting and ending at rest where the joint is."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jointctl.identification.excitation import safe_chirp
from jointctl.identification.plant_fit import IdentificationError


def test_it_starts_and_ends_at_rest_at_the_start_and_sweeps_its_band() -> None:
    chirp = safe_chirp(-0.5, -1.0, 0.0, 100.0, duration_s=10.0)
    t = np.linspace(0.0, 10.0, 100_001)
    q = np.array([chirp(x) for x in t])
    assert q[0] == q[-1] == -0.5
    v = np.gradient(q, t)
    assert abs(v[0]) < 1e-6 and abs(v[-1]) < 1e-6
    assert chirp.amplitude == pytest.approx(0.3 * 0.5)  # 30 % of the room to the nearer limit
    assert q.min() >= -0.5 - chirp.amplitude and q.max() <= -0.5 + chirp.amplitude
    assert np.abs(v).max() <= chirp.peak_speed


def test_a_slow_joint_gets_an_amplitude_within_half_its_speed_limit() -> None:
    chirp = safe_chirp(1.0, -3.0, 3.0, 0.2, f_start_hz=0.2, f_end_hz=1.0, duration_s=10.0)
    t = np.linspace(0.0, 10.0, 100_001)
    v = np.gradient([chirp(x) for x in t], t)
    assert np.abs(v).max() <= 0.1 + 1e-9
    assert chirp.peak_speed == pytest.approx(0.1)


def test_a_joint_without_a_range_swings_one_radian_at_most() -> None:
    assert safe_chirp(5.0, -math.inf, math.inf, math.inf).amplitude == pytest.approx(0.3)


@pytest.mark.parametrize("kwargs, field", [
    (dict(amplitude=0.2), "amplitude"),
    (dict(amplitude=-0.1), "amplitude"),
    (dict(duration_s=0.0), "duration_s"),
    (dict(f_end_hz=math.nan), "f_end_hz"),
])
def test_unsafe_or_bad_settings_are_refused_naming_the_field(kwargs, field) -> None:
    with pytest.raises(IdentificationError) as info:
        safe_chirp(-0.5, -1.0, 0.0, 100.0, **kwargs)
    assert info.value.field == field


def test_a_joint_resting_at_or_beyond_a_limit_cannot_be_excited() -> None:
    with pytest.raises(IdentificationError, match="no room"):
        safe_chirp(0.0, -1.0, 0.0, 100.0)
    with pytest.raises(IdentificationError, match="outside its range"):
        safe_chirp(0.5, -1.0, 0.0, 100.0)


def test_without_a_loop_model_the_planned_chirp_keeps_the_reference_inside() -> None:
    """No model: the reference alone. Its speed peaks at half the 0.2 rad/s limit, measured on a fine grid;
    the bound A·(2π·f_end + π/T) that safe_chirp uses is loose (the window is small where the frequency
    is highest), so the planned chirp is larger than safe_chirp's."""
    from jointctl.identification.excitation import planned_chirp
    from jointctl.identification.safety import Envelope

    envelope = Envelope("joint", 1.0, -3.0, 3.0, 0.2, math.inf)
    chirp, allowance = planned_chirp(envelope, None, period_s=0.001, f_start_hz=0.2, f_end_hz=1.0, duration_s=10.0)
    t = np.linspace(0.0, 10.0, 1_000_001)
    speed = np.abs(np.gradient([chirp(x) for x in t], t)).max()
    assert allowance.binds == "velocity" and speed == pytest.approx(0.1, rel=1e-3)
    assert chirp.amplitude > safe_chirp(1.0, -3.0, 3.0, 0.2, f_start_hz=0.2, f_end_hz=1.0, duration_s=10.0).amplitude

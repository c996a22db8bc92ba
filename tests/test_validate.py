"""The one numeric check: real, not bool, finite, within bounds; the same messages everywhere."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from jointctl.validate import checked_number, finite_number, real_number


@pytest.mark.parametrize(("value", "real", "finite"), [
    (1, 1.0, 1.0), (2.5, 2.5, 2.5), (np.float32(0.5), 0.5, 0.5), (Fraction(1, 4), 0.25, 0.25),
    (math.inf, math.inf, None), (True, None, None), ("1.0", None, None), (None, None, None), ([1.0], None, None),
])
def test_real_and_finite_numbers(value, real, finite):
    assert real_number(value) == real
    assert finite_number(value) == finite


def test_nan_is_real_but_not_finite():
    assert math.isnan(real_number(math.nan)) and finite_number(math.nan) is None


@pytest.mark.parametrize(("value", "kwargs", "message"), [
    ("x", {}, "must be a number"), (False, {}, "must be a number"), (math.nan, {}, "must be finite"),
    (-math.inf, {}, "must be finite"), (0.0, {"positive": True}, "must be positive"),
    (-1.0, {"minimum": 0}, "must not be negative"), (0.5, {"minimum": 1.0}, "must be at least 1.0"),
])
def test_checked_number_refuses_with_the_shared_messages(value, kwargs, message):
    with pytest.raises(ValueError, match=message):
        checked_number(value, ValueError, **kwargs)


def test_checked_number_passes_good_values_as_floats():
    assert checked_number(3, ValueError, positive=True, minimum=1) == 3.0
    assert type(checked_number(3, ValueError)) is float

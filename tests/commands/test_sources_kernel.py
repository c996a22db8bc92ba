"""The compiled sources give the values their ``sample`` gives, bit for bit, message for message."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.commands.sources import ConstantSource, ExpressionSource, SineSource, StepSource
from jointctl.commands.sources_kernel import pack_source, source_sample, unpack_source


@pytest.mark.parametrize("source", [
    ConstantSource(-0.3),
    StepSource(-0.2, -0.5, 0.5),
    StepSource(-0.2, -0.5, 0.5, 0.05),
    SineSource(0.1, 3.183098861837907, -0.5, 100.0),
    SineSource(0.25, 7.0, 0.0, 1000.0, derivative=True),
    SineSource(0.1, 2.0, 0.3, 333.0),
], ids=["constant", "step", "ramp", "sine", "velocity sine", "sine at 333 Hz"])
def test_the_kernel_samples_as_the_source_does(source):
    times = np.arange(3000) * 0.001  # the loop's times: k * period
    expected = [source.sample(t) for t in times]
    source.reset()
    parameters, state = (np.array([row]) for row in pack_source(source))
    assert [source_sample(parameters, state, 0, t) for t in times] == expected
    unpack_source(source, state[0])
    if isinstance(source, SineSource):  # the held message goes back: the next sample needs no new one
        assert source._hold.k == int(np.floor(times[-1] * source.rate_hz + 1e-9))


def test_an_expression_has_no_compiled_form():
    with pytest.raises(TypeError, match="ExpressionSource has no compiled form"):
        pack_source(ExpressionSource("0.1*sin(i/5)"))

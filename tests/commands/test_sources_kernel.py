"""The compiled sources give the values their ``sample`` gives, bit for bit, message for message."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.commands.sources import ChirpSource, ConstantSource, ExpressionSource, SineSource, StepSource
from jointctl.commands.sources_kernel import fill_table, pack_source, source_sample, unpack_source


@pytest.mark.parametrize("source", [
    ConstantSource(-0.3),
    StepSource(-0.2, -0.5, 0.5),
    StepSource(-0.2, -0.5, 0.5, 0.05),
    SineSource(0.1, 3.183098861837907, -0.5, 100.0),
    SineSource(0.25, 7.0, 0.0, 1000.0, derivative=True),
    SineSource(0.1, 2.0, 0.3, 333.0),
    ChirpSource(0.05, 0.5, 9.0, 2.0, -0.4, 0.5),
], ids=["constant", "step", "ramp", "sine", "velocity sine", "sine at 333 Hz", "chirp"])
def test_the_kernel_samples_as_the_source_does(source):
    times = np.arange(3000) * 0.001  # the loop's times: k * period
    expected = [source.sample(t) for t in times]
    source.reset()
    parameters, state = (np.array([row]) for row in pack_source(source))
    tables = np.zeros((1, 1))
    assert [source_sample(parameters, state, tables, 0, t, 0) for t in times] == expected
    unpack_source(source, state[0])
    if isinstance(source, SineSource):  # the held message goes back: the next sample needs no new one
        assert source._hold.k == int(np.floor(times[-1] * source.rate_hz + 1e-9))


@pytest.mark.parametrize("rate_hz", [100.0, 333.0, 2500.0])
def test_an_expression_sampled_a_stretch_ahead_holds_what_the_loop_would(rate_hz):
    """Its messages evaluated in Python where each is due, in stretches of any length: the values the loop's
    own ``sample`` gives at every cycle, each message evaluated once, the same hold left behind."""
    loop, ahead = ExpressionSource("0.1*sin(i/5)-0.5+0.01*t", rate_hz), ExpressionSource("0.1*sin(i/5)-0.5+0.01*t",
                                                                                          rate_hz)
    times = np.arange(3000) * 0.001
    expected = [loop.sample(t) for t in times]
    evaluated, expression = [], ahead.expression

    class Counted:
        def evaluate(self, i, t):
            evaluated.append(i)
            return expression.evaluate(i, t)

    ahead.expression = Counted()
    parameters, state = (np.array([row]) for row in pack_source(ahead))
    tables = np.zeros((1, 1000))
    got = []
    for k0, n in ((0, 7), (7, 1000), (1007, 993), (2000, 1000)):
        fill_table(ahead, tables[0], k0, n, 0.001)
        got += [source_sample(parameters, state, tables, 0, times[k0 + j], j) for j in range(n)]
    assert got == expected
    assert evaluated == sorted(set(np.floor(times * rate_hz + 1e-9).astype(int).tolist()))  # once each
    assert (ahead._hold.k, ahead._hold.value) == (loop._hold.k, loop._hold.value)
    assert ahead._hold.k == int(np.floor(2.999 * rate_hz + 1e-9))


def test_a_source_of_another_kind_has_no_compiled_form():
    class Ramp(ConstantSource):
        pass

    with pytest.raises(TypeError, match="Ramp has no compiled form"):
        pack_source(Ramp(1.0))

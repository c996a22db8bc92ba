"""Late commands and noisy sensors: ImperfectHardware, alone and in a run."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jointctl.errors import ConfigError
from jointctl.hardware.imperfect import NOISE_BLOCK_CYCLES, ImperfectHardware
from jointctl.hardware.interface import EFFORT, HardwareInterface
from jointctl.sweep.runner import RunTask, evaluate

M_KG, B, KP, DT = 1.01, 10.0, 400.0, 0.001


class Recording(HardwareInterface):
    """Two joints that remember every effort written to them and read back a fixed state."""

    def __init__(self):
        super().__init__(("a", "b"))
        self.written = []
        self.position[:] = [0.5, -0.25]
        self.velocity[:] = [1.0, 2.0]
        self.command_buffer(EFFORT)[:] = [7.0, 8.0]  # what the hardware holds before any write

    def command_interfaces(self, joint):
        return frozenset({EFFORT})

    def read(self):
        pass

    def write(self):
        self.written.append(list(self._commands[EFFORT]))

    def advance(self, period_s):
        pass


@pytest.mark.parametrize("latency", [0, 1, 3])
def test_commands_reach_the_hardware_exactly_latency_cycles_late(latency):
    inner = Recording()
    hw = ImperfectHardware(inner, latency_cycles=latency)
    commands = hw.command_buffer(EFFORT)
    assert commands == [7.0, 8.0]
    for k in range(6):
        commands[:] = [float(k), -float(k)]
        hw.write()
    expected = [[7.0, 8.0]] * latency + [[float(k), -float(k)] for k in range(6 - latency)]
    assert inner.written == expected


def test_without_noise_the_state_is_the_hardwares_and_the_wrenches_are_shared():
    inner = Recording()
    hw = ImperfectHardware(inner, latency_cycles=2)
    hw.read()
    assert hw.position == [0.5, -0.25] and hw.velocity == [1.0, 2.0] and hw.wrenches is inner.wrenches
    assert hw.command_interfaces("a") == frozenset({EFFORT}) and hw.simulation is None and hw.fault is None


def test_noise_has_its_standard_deviation_and_the_seed_decides_it():
    def samples(seed, cycles=3 * NOISE_BLOCK_CYCLES):
        hw = ImperfectHardware(Recording(), position_noise=1e-3, velocity_noise=0.05, seed=seed)
        out = []
        for _ in range(cycles):
            hw.read()
            out.append(hw.position + hw.velocity)
        return np.array(out)

    first = samples(1)
    n = len(first)
    errors = first - np.array([0.5, -0.25, 1.0, 2.0])
    # n independent draws: the mean within 4 σ/√n of 0, the sample deviation within 4 σ/√(2n) of σ.
    for column, sigma in zip(errors.T, (1e-3, 1e-3, 0.05, 0.05)):
        assert abs(column.mean()) < 4 * sigma / math.sqrt(n)
        assert abs(column.std() - sigma) < 4 * sigma / math.sqrt(2 * n)
    assert abs(np.corrcoef(errors[:, 0], errors[:, 1])[0, 1]) < 4 / math.sqrt(n)  # joints independent
    assert np.array_equal(samples(1), first)
    assert not np.array_equal(samples(2), first)


@pytest.mark.parametrize("kwargs, field", [({"latency_cycles": -1}, "latency_cycles"),
                                           ({"latency_cycles": 1.5}, "latency_cycles"),
                                           ({"position_noise": -1e-3}, "noise.position"),
                                           ({"velocity_noise": math.nan}, "noise.velocity")])
def test_bad_settings_are_refused(kwargs, field):
    with pytest.raises(ConfigError) as caught:
        ImperfectHardware(Recording(), **kwargs)
    assert caught.value.field == field


def test_latency_takes_damping_away_as_a_delay_in_the_loop_does():
    # A delay τ = N·dt in the P loop: m s² + b s + Kp e^(-sτ) ≈ m s² + (b - Kp τ) s + Kp (first order in sτ), so
    # ζ drops by Kp τ / (2√(Kp m)) while ωn stays. The next term adds Kp τ²/2 to the mass (3.2 g, 0.3 %, at 4
    # cycles); the 1 kHz loop's own discretisation is common to both runs: 2 % of the drop covers both.
    rows = {n: evaluate(RunTask(0, "one_dof_step", {"latency_cycles": n}, overrides=("duration_s=2",)))
            for n in (0, 4)}
    assert all(r.error is None for r in rows.values()), [r.error for r in rows.values()]
    drop = KP * 4 * DT / (2 * math.sqrt(KP * M_KG))
    measured = rows[0].metrics["damping_ratio"] - rows[4].metrics["damping_ratio"]
    assert measured == pytest.approx(drop, rel=0.02)
    assert rows[4].metrics["natural_frequency_rad_s"] == pytest.approx(rows[0].metrics["natural_frequency_rad_s"],
                                                                         rel=0.005)


def test_a_noisy_run_is_repeatable_and_its_seed_comes_from_the_sweep_and_the_run():
    def run(index, seed=0):
        return evaluate(RunTask(index, "one_dof_step", {"noise.position": 2e-4}, seed=seed,
                                overrides=("duration_s=1.5",)))

    first = run(0)
    assert first.error is None
    assert run(0).metrics == first.metrics and np.array_equal(run(0).trace["position"], first.trace["position"])
    assert run(1).metrics != first.metrics and run(0, seed=1).metrics != first.metrics
    quiet = evaluate(RunTask(0, "one_dof_step", {}, overrides=("duration_s=1.5",)))
    # 0.2 mm of noise on a 0.3 m step moves the fitted ωn by far less than 1 %.
    assert first.metrics["natural_frequency_rad_s"] == pytest.approx(quiet.metrics["natural_frequency_rad_s"], rel=0.01)

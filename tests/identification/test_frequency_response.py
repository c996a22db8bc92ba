"""Stepped-sine frequency responses of the 1-DOF robot's loops against theory and the sampled-loop model.

The chapter's position loop (p = 400 N/m, m = 1.01 kg, b = 10 N·s/m) is a mass-spring-damper:
ωn = sqrt(p/m) = 19.90 rad/s (3.167 Hz), where the phase is -90°, less the 1 kHz hold's ω·h/2
(0.57°)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jointctl.errors import ConfigError
from jointctl.identification.frequency_response import LoopModel, analyse, bode, measure, write_bode
from jointctl.identification.plant_fit import IdentificationError
from jointctl.scenario.spec import scenario_for_robot

M, B, KP, H = 1.01, 10.0, 400.0, 0.001
WN = math.sqrt(KP / M)
FN = WN / (2 * math.pi)


@pytest.fixture(scope="module")
def position_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("bode")
    frequencies = np.logspace(math.log10(0.5), math.log10(20.0), 20)
    return bode(scenario_for_robot("one_dof", "position"), "joint1_position_controller", frequencies,
                out_dir=out), out


def test_the_phase_is_minus_90_at_the_natural_frequency_less_the_hold() -> None:
    (point,), _ = measure(scenario_for_robot("one_dof", "position"), "joint1_position_controller", [FN])
    assert point.phase_deg == pytest.approx(-90.0 - math.degrees(WN * H / 2), abs=2.0)
    # And the gain there is 1/(2ζ) = sqrt(p·m)/b: 20.1, i.e. 26 dB... for the undamped-by-d loop:
    zeta = B / (2 * math.sqrt(KP * M))
    assert point.gain_db == pytest.approx(20 * math.log10(1 / (2 * zeta)), abs=0.3)


def test_the_sweep_finds_the_natural_frequency_and_matches_its_model(position_sweep) -> None:
    result, out = position_sweep
    assert result["phase_minus_90_hz"] == pytest.approx(FN, rel=0.01)
    assert result["plant_source"] == "robot model" and result["model"]["mass"] == pytest.approx(M, rel=1e-6)
    measured, modelled = np.array(result["gain_db"]), np.array(result["model"]["gain_db"])
    f = np.array(result["frequencies_hz"])
    assert np.abs(measured - modelled)[f < 10].max() < 0.3  # dB
    phase_gap = np.abs(np.array(result["phase_deg"]) - np.array(result["model"]["phase_deg"]))
    assert phase_gap[f < 5].max() < 2.0  # deg (above, MuJoCo's semi-implicit step leads the ZOH model)
    # The magnitude peak of a mass-spring-damper: ωn·sqrt(1 - 2ζ²), 1/(2ζ·sqrt(1 - ζ²)); on this grid
    # the nearest point is within one grid step.
    zeta = B / (2 * math.sqrt(KP * M))
    assert result["resonance_peak_db"] == pytest.approx(20 * math.log10(1 / (2 * zeta * math.sqrt(1 - zeta ** 2))),
                                                        abs=0.6)
    assert (out / "bode.png").stat().st_size > 10_000 and (out / "metrics.json").is_file()


def test_the_models_margins_are_the_textbook_ones() -> None:
    model = LoopModel(M, B, KP, 0.0, 0.0, H)
    margins = model.margins()
    # Loop gain p/(m s² + b s): |L| = 1 where m²ω⁴ + b²ω² = p², phase margin atan(b/(mω)) there.
    wc = math.sqrt((-B**2 + math.sqrt(B**4 + 4 * M**2 * KP**2)) / (2 * M**2))
    assert margins["gain_crossover_hz"] == pytest.approx(wc / (2 * math.pi), rel=0.01)
    assert margins["phase_margin_deg"] == pytest.approx(math.degrees(math.atan2(B, M * wc)) - math.degrees(wc * H / 2),
                                                        abs=0.5)


def test_the_velocity_loop_is_a_first_order_lag() -> None:
    frequencies = [1.0, 5.0, 20.0]
    points, context = measure(scenario_for_robot("one_dof", "velocity"), "joint1_velocity_controller", frequencies)
    kv = context["gains"]["p"]
    for point in points[:2]:  # Kv / (m s + Kv + b), while ω·m/Kv is small against the 1 kHz loop
        w = 2 * math.pi * point.frequency_hz
        assert point.gain_db == pytest.approx(20 * math.log10(kv / math.hypot(kv + B, M * w)), abs=0.1)
        assert point.phase_deg == pytest.approx(-math.degrees(math.atan2(M * w, kv + B)) - math.degrees(w * H / 2),
                                                abs=1.5)
    # At 20 Hz (Kv·h/m = 0.2) the sampled loop departs from the continuous lag; the sampled model holds.
    gain, phase = LoopModel(M, B, kv, 0.0, 0.0, H, "velocity").response([20.0])
    assert points[2].gain_db == pytest.approx(gain[0], abs=0.05)
    assert points[2].phase_deg == pytest.approx(phase[0], abs=1.5)


@pytest.mark.parametrize("kwargs, error, field", [
    (dict(controller_name="joint9_position_controller"), ConfigError, "--controller"),
    (dict(frequencies_hz=[600.0]), IdentificationError, "frequencies_hz"),
    (dict(amplitude=0.4), IdentificationError, "amplitude"),
    (dict(plant={"mass_kg": -1}), IdentificationError, "plant"),
])
def test_bad_requests_are_refused_naming_the_field(kwargs, error, field) -> None:
    args = dict(controller_name="joint1_position_controller", frequencies_hz=[1.0]) | kwargs
    with pytest.raises(error) as info:
        bode(scenario_for_robot("one_dof", "position"), args.pop("controller_name"), args.pop("frequencies_hz"),
             **args)
    assert info.value.field == field


def test_bode_writes_strict_json_with_null_for_what_it_did_not_measure(tmp_path) -> None:
    """A sweep that never falls through -3 dB has no bandwidth (NaN): metrics.json says null, not NaN."""
    import json

    from jointctl.identification.frequency_response import Point

    points = [Point(f, 0.0, -10.0 * k) for k, f in enumerate((0.5, 1.0, 2.0))]
    result = analyse(points, None)
    assert math.isnan(result["bandwidth_hz"])
    write_bode(tmp_path, {**result, "gain_margin_db": math.inf}, "flat")

    def refuse(constant):
        raise ValueError(constant)

    written = json.loads((tmp_path / "metrics.json").read_text(), parse_constant=refuse)
    assert written["bandwidth_hz"] is None and written["gain_margin_db"] is None
    assert written["gain_db"] == [0.0, 0.0, 0.0]


GRID_HZ = np.logspace(math.log10(0.5), math.log10(20.0), 20)  # bode's default sweep


def second_order_points(fn_hz: float, zeta: float, frequencies=GRID_HZ):
    """Synthetic measurements of ``ωn² / (s² + 2ζωn s + ωn²)``: gain [dB], phase [deg]."""
    from jointctl.identification.frequency_response import Point

    r = np.asarray(frequencies) / fn_hz
    h = 1.0 / (1.0 - r ** 2 + 2j * zeta * r)
    return [Point(float(f), float(20 * np.log10(abs(x))), float(np.degrees(np.angle(x))))
            for f, x in zip(frequencies, h)]


def test_a_peak_inside_the_sweep_is_the_resonance() -> None:
    zeta, fn = 0.2, 3.0
    result = analyse(second_order_points(fn, zeta), None)
    expected_hz = fn * math.sqrt(1 - 2 * zeta ** 2)
    nearest = GRID_HZ[np.argmin(np.abs(GRID_HZ - expected_hz))]
    assert result["resonance_hz"] == pytest.approx(nearest)
    assert result["resonance_peak_db"] == pytest.approx(max(p.gain_db for p in second_order_points(fn, zeta)))
    assert result["resonance_peak_db"] > 6.0


@pytest.mark.parametrize(("fn_hz", "zeta", "why"), [
    (3.0, 1.2, "overdamped: the gain falls from the first test frequency on"),
    (3.0, 0.7071, "maximally flat: no peak above the low-frequency gain"),
    (60.0, 0.2, "the peak lies above the swept range: the gain still rises at 20 Hz"),
])
def test_no_peak_inside_the_sweep_is_no_resonance(fn_hz, zeta, why, tmp_path) -> None:
    import json

    points = second_order_points(fn_hz, zeta)
    gains = [p.gain_db for p in points]
    assert int(np.argmax(gains)) in (0, len(gains) - 1), why
    result = analyse(points, None)
    assert result["resonance_hz"] is None and result["resonance_peak_db"] is None, why
    write_bode(tmp_path, result, why)
    written = json.loads((tmp_path / "metrics.json").read_text())
    assert written["resonance_hz"] is None and written["resonance_peak_db"] is None


@pytest.mark.parametrize(("gains", "peak"), [
    ([0.0, 3.0, 1.0], 1), ([0.0, 0.0, -1.0], None), ([-1.0, 0.0, 0.0], None), ([1.0, 1.0, 1.0], None),
    ([0.0, 2.0, 2.0, 0.0], 1), ([5.0, 1.0, 4.0], None), ([1.0, 2.0], None), ([], None),
])
def test_resonance_peak_only_inside_the_range(gains, peak) -> None:
    from jointctl.identification.frequency_response import resonance_peak

    assert resonance_peak(gains) == peak


def test_the_bode_figure_names_what_it_plots_and_marks_the_bandwidth_and_margins_in_its_svg(tmp_path) -> None:
    """The SVG beside bode.png, read back: the axis labels, the bandwidth line at the measured -3 dB crossing,
    the margins' text from the model, and a log frequency axis that spans the sweep (not 100 Hz)."""
    import re

    model = LoopModel(1.01, 0.0, 400.0, 0.0, 40.0, 0.001, "position", "error")
    result = analyse(second_order_points(3.0, 0.5), model)
    write_bode(tmp_path, {**result, "period_s": 0.001, "loop": "position", "derivative": "error"}, "joint1")
    svg = (tmp_path / "bode.svg").read_text()
    assert "gain |position / reference| [dB]" in svg and "phase [°]" in svg and "frequency [Hz]" in svg
    assert 'id="bode-bandwidth"' in svg and 'id="bode-measured-gain"' in svg and 'id="bode-model-gain"' in svg
    margins = model.margins()
    assert f"{margins['phase_margin_deg']:.1f}°" in svg and "gain margin" in svg
    assert f"bandwidth {result['bandwidth_hz']:.3g} Hz" in svg
    ticks = re.findall(r">(\d+(?:\.\d+)?)</text>", svg)
    assert {"0.5", "1", "2", "5", "10", "20"} <= set(ticks) and "100" not in ticks  # 1-2-5 over the sweep only

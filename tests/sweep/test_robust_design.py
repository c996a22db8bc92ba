"""Robust autotune on the 1-DOF robot against its theory: with PD on the measurement, ωn = sqrt(p/m) and
ζ = (b + d)/(2 sqrt(p m)) per payload, so the nominal design for 1.01 kg (10 % overshoot in 0.3 s) rings
with a 5 kg payload, and the robust design meets the spec on every plant, within the effort limit."""

from __future__ import annotations

import json
import math

import pytest

from jointctl.cli import main
from jointctl.errors import ConfigError
from jointctl.identification.autotune import spec_from_step
from jointctl.scenario.targets import resolve_target
from jointctl.sweep.robust_design import family, parse_range, robust_autotune

MEASUREMENT = ["controllers.joint1_position_controller.derivative=measurement"]
MASS_KG, DAMPING = 1.01, 10.0


def scenario_for(extra=()):
    return lambda overrides: resolve_target("one_dof", overrides=[*extra, *overrides]).scenario


def continuous_overshoot_pct(p: float, d: float, m: float, b: float = DAMPING) -> float:
    zeta = (b + d) / (2 * math.sqrt(p * m))
    return 100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)) if zeta < 1 else 0.0


def test_the_family_is_the_corners_the_centre_and_the_draws() -> None:
    scenario = scenario_for()(())
    plants = family(scenario, "joint1", [parse_range("payload_kg=0:5"), parse_range("model.joint1.damping=7:13")],
                    samples=4, seed=3)
    assert len(plants) == 4 + 1 + 4
    corners = {(p.values["payload_kg"], p.values["model.joint1.damping"]): p for p in plants[:4]}
    assert set(corners) == {(0.0, 7.0), (0.0, 13.0), (5.0, 7.0), (5.0, 13.0)}
    # A payload on the piston adds its mass to the joint's inertia; the joint's damping is the varied one.
    assert corners[(5.0, 13.0)].inertia == pytest.approx(MASS_KG + 5.0, rel=1e-9)
    assert corners[(0.0, 7.0)].inertia == pytest.approx(MASS_KG, rel=1e-9) and corners[(0.0, 7.0)].damping == 7.0
    assert corners[(5.0, 7.0)].gravity_load == pytest.approx((MASS_KG + 5.0) * 9.81, rel=1e-6)
    again = family(scenario, "joint1", [parse_range("payload_kg=0:5"), parse_range("model.joint1.damping=7:13")],
                   samples=4, seed=3)
    assert [p.values for p in again] == [p.values for p in plants]  # the seed decides the draws


def test_the_nominal_design_rings_with_a_payload_and_the_robust_one_meets_the_spec_everywhere() -> None:
    zeta, bandwidth = spec_from_step(10, 0.3)
    result = robust_autotune(scenario_for(MEASUREMENT), "joint1_position_controller", ["payload_kg=0:5"],
                             overshoot_pct=10, settling_s=0.3, zeta=zeta, bandwidth_hz=bandwidth, step=0.1,
                             target="one_dof", overrides=MEASUREMENT)
    nominal, robust = result["nominal"], result["robust"]
    p, d = nominal["gains"]["p"], nominal["gains"]["d"]
    heavy = continuous_overshoot_pct(p, d, MASS_KG + 5.0)
    assert heavy > 40  # "about 45 %"
    # The sampled model and the simulated robot agree with the continuous theory at the heaviest plant.
    assert nominal["model_worst"]["overshoot_pct"] == pytest.approx(heavy, abs=2.0)
    assert nominal["model_worst"]["overshoot_pct_at"] == {"payload_kg": 5.0}
    assert nominal["robot_worst"]["overshoot_pct"] == pytest.approx(nominal["model_worst"]["overshoot_pct"], abs=2.0)
    assert nominal["robot_worst"]["failed"] >= 1
    # The robust gains: every plant meets the spec, on the model and on the robot, within the effort limit.
    assert result["meets_spec_on_model"]
    worst = robust["robot_worst"]
    assert worst["runs"] == 3 and worst["passed"] == 3 and not worst["errors"]
    assert worst["overshoot_pct"] <= 10 and worst["settling_time_s"] <= 0.3
    assert robust["effort_at_step"] <= robust["effort_limit"]
    # Phase margins on the sampled loops: the robust loop is the better damped one at the heaviest plant.
    assert robust["model_worst"]["phase_margin_deg"] > nominal["model_worst"]["phase_margin_deg"]
    # ... as the theory says of the two ends: ζ at the heaviest plant high enough for 10 %.
    assert continuous_overshoot_pct(robust["gains"]["p"], robust["gains"]["d"], MASS_KG + 5.0) <= 10


@pytest.mark.parametrize("item, fragment", [("payload_kg=5:0", "LOW below HIGH"), ("payload_kg=1", "FIELD=LOW:HIGH"),
                                            ("latency_cycles=0:3", "varies the plant"),
                                            ("payload_kg=a:b", "numbers")])
def test_bad_ranges_are_refused(item, fragment) -> None:
    with pytest.raises(ConfigError) as caught:
        parse_range(item)
    assert caught.value.field == "--robust" and fragment in str(caught.value)


def test_the_command_writes_the_robust_yaml_with_the_law_it_was_designed_for(tmp_path, capsys) -> None:
    out = tmp_path / "robust"
    assert main(["autotune", "one_dof", "--controller", "joint1_position_controller", "--overshoot-pct", "10",
                 "--settling-s", "0.3", "--robust", "payload_kg=0:5", "--robust-samples", "2",
                 "--set", MEASUREMENT[0], "--out", str(out)]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert json.loads((out / "metrics.json").read_text())["robust"]["gains"] == printed["robust"]["gains"]
    written = (out / "one_dof_pos_ctl_params.yaml").read_text()
    assert "derivative: measurement" in written and f"p: {round(printed['robust']['gains']['p'], 6)}" in written
    assert main(["autotune", "one_dof", "--controller", "joint1_position_controller", "--overshoot-pct", "10",
                 "--settling-s", "0.3", "--robust", "model.nothing.mass=1:2", "--out", str(tmp_path / "x")]) == 2
    assert "nothing" in capsys.readouterr().err and not (tmp_path / "x").exists()

"""The loop models of ``bode`` and ``autotune`` follow the derivative law the controller runs
(/work/shared/reference/ros-control-facts.md): ``derivative: error`` (ros_controllers', a plain position
command) is ``u = p·e + d·(e - e_last)/h`` with e_last 0 before the step, a zero ``p + d·s`` acting on
``r - y`` in the closed loop; ``derivative: measurement`` is ``u = p·e - d·q̇``, ``d`` on ``y`` only. The
sampled model is checked against a simulation written here from those formulas (the exact zero-order
hold of ``m q̈ = u - b q̇``), and autotune's design against the simulated 1-DOF robot running the law."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import linalg, signal

from jointctl.identification.autotune import _model_overshoot, autotune, spec_from_step
from jointctl.identification.frequency_response import LoopModel, bode
from jointctl.scenario.spec import scenario_for_robot

M, B, H = 1.01, 10.0, 0.001
P_FACTS, D_FACTS = 391.0, 13.6  # the facts' autotune design (10 % in 0.3 s, derivative on measurement)
LAWS = ("error", "measurement")


def simulated_step(law: str, p: float, i: float, d: float, n: int = 800) -> np.ndarray:
    """Unit step response of the sampled loop, written from the facts' formulas."""
    a_c = np.array([[0.0, 1.0], [0.0, -B / M]])
    b_c = np.array([0.0, 1.0 / M])
    big = linalg.expm(np.block([[a_c, b_c[:, None]], [np.zeros((1, 3))]]) * H)  # exact ZOH
    a_d, b_d = big[:2, :2], big[:2, 2]
    x = np.zeros(2)
    e_last, i_state, y = 0.0, 0.0, []
    for _ in range(n):
        y.append(x[0])
        e = 1.0 - x[0]
        i_state += i * H * e
        rate = (e - e_last) / H if law == "error" else -x[1]
        e_last = e
        x = a_d @ x + b_d * (p * e + i_state + d * rate)
    return np.array(y)


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("i", [0.0, 50.0])
def test_the_sampled_model_is_the_laws_loop(law, i) -> None:
    model = LoopModel(M, B, P_FACTS, i, D_FACTS, H, "position", law)
    import control

    n = 800
    _, y = control.step_response(model.closed_loop(), T=np.arange(n) * H)
    expected = simulated_step(law, P_FACTS, i, D_FACTS, n)
    assert np.abs(np.asarray(y).ravel() - expected).max() < 1e-9
    other = simulated_step(LAWS[1 - LAWS.index(law)], P_FACTS, i, D_FACTS, n)
    assert np.abs(other - expected).max() > 0.01  # the two laws are told apart


def test_derivative_on_error_puts_the_zero_in_the_loop() -> None:
    # Continuous loops: (d s + p)/(m s² + (b + d)s + p) on the error, p/(m s² + (b + d)s + p) on measurement.
    t = np.linspace(0.0, 2.0, 20001)
    over = {}
    for law, num in (("error", [D_FACTS, P_FACTS]), ("measurement", [P_FACTS])):
        _, y = signal.step(signal.lti(num, [M, B + D_FACTS, P_FACTS]), T=t)
        over[law] = 100 * (y.max() - 1.0)
        # The 1 kHz hold moves the overshoot by less than half a point.
        assert 100 * _model_overshoot(LoopModel(M, B, P_FACTS, 0.0, D_FACTS, H, "position", law)) == \
            pytest.approx(over[law], abs=0.5)
    assert over["measurement"] == pytest.approx(10.0, abs=0.2)  # what the design promised
    assert over["error"] == pytest.approx(13.8, abs=0.5)  # what the real ros_control robot measured


@pytest.mark.parametrize("law", LAWS)
def test_the_models_loop_gain_follows_the_law(law) -> None:
    # Broken at the plant input: L(z) = C(z)·P(z), C = p + d(1 - 1/z)/h on the error; p + d·[q̇] on measurement.
    model = LoopModel(M, B, P_FACTS, 0.0, D_FACTS, H, "position", law)
    import control

    plant = control.c2d(control.ss([[0, 1], [0, -B / M]], [[0], [1 / M]], np.eye(2), np.zeros((2, 1))), H, "zoh")
    for f in (1.0, 5.0, 30.0):
        z = np.exp(2j * math.pi * f * H)
        q, qd = (np.asarray(plant.C) @ np.linalg.solve(z * np.eye(2) - np.asarray(plant.A), np.asarray(plant.B))).ravel()
        expected = (P_FACTS + D_FACTS * (1 - 1 / z) / H) * q if law == "error" else P_FACTS * q + D_FACTS * qd
        assert model.loop_response([f])[0] == pytest.approx(expected, rel=1e-9)


def test_bode_models_the_law_the_controller_runs(tmp_path) -> None:
    frequencies = [1.0, 3.0, 5.0, 8.0]
    gains = ["controllers.joint1_position_controller.pid.p=391.0", "controllers.joint1_position_controller.pid.d=13.6"]
    result = bode(scenario_for_robot("one_dof", "position", gains), "joint1_position_controller", frequencies)
    assert result["derivative"] == "error"
    measured, modelled = np.array(result["gain_db"]), np.array(result["model"]["gain_db"])
    assert np.abs(measured - modelled).max() < 0.3  # dB
    wrong, _ = LoopModel(result["model"]["mass"], B, P_FACTS, 0.0, D_FACTS, H, "position", "measurement").response(
        frequencies)
    assert np.abs(measured - wrong).max() > 1.0  # the other law's model would not match


@pytest.fixture(scope="module")
def tuned_with_ros_controls_law():
    zeta, bandwidth_hz = spec_from_step(10.0, 0.3)  # the facts' spec
    result = autotune(lambda o: scenario_for_robot("one_dof", "position", list(o)), "joint1_position_controller",
                      bandwidth_hz=bandwidth_hz, zeta=zeta, step=0.1, settling_s=0.3)  # the CLI's default step
    return result, bandwidth_hz


def test_autotune_on_ros_controls_law_measures_what_it_promised(tuned_with_ros_controls_law) -> None:
    result, _ = tuned_with_ros_controls_law
    assert result["derivative"] == "error"
    assert result["model"]["overshoot_pct"] == pytest.approx(10.0, abs=0.05)
    # The tolerance: a quarter of what the law's zero adds to the measurement design (≈ 4 points): a
    # design blind to the law misses by the whole of it.
    blind = 100 * _model_overshoot(LoopModel(M, B, P_FACTS, 0.0, D_FACTS, H, "position", "error"))
    tolerance = (blind - 10.0) / 4
    assert 0.8 < tolerance < 1.2
    assert result["robot"]["step_overshoot_pct"] == pytest.approx(10.0, abs=tolerance)
    assert result["robot"]["step_settling_s"] == pytest.approx(0.3, rel=0.15)


def test_a_step_whose_derivative_kick_exceeds_the_effort_limit_is_designed_for_at_that_step(
        tuned_with_ros_controls_law) -> None:
    """The kick d·step/period of the 0.1 m step is clamped at 1000 N for a cycle: the design is made on that
    clamped loop and checked at that very step, not at a smaller one."""
    result, _ = tuned_with_ros_controls_law
    p, d = result["gains"]["p"], result["gains"]["d"]
    assert p * 0.1 + d * 0.1 / H + M * 9.81 > 1000.0  # a 0.1 m step would kick more than 1000 N
    assert result["check_step"] == 0.1 and "kick" in result["note"] and "designed for" in result["note"]
    assert result["robot"]["step_peak_effort"] == pytest.approx(1000.0)  # the clamped kick, measured

"""The chapter's trajectory example (figs. 11.8, 11.9) on Part 2's minimal robot, against theory.

Theory here is the inverted pendulum's, from the book's numbers typed in by hand (see
tests/model/test_minimal_robot.py): I = 0.44525 kg·m² about joint1, gravity torque
τ_g(q) = g·(0.02·cos q + 0.595·sin q) = m·g·l·sin(q + φ), the book's loop Kp = 10 N·m/rad,
Kv = 3 N·m·s/rad. About a pose q the loop is a spring-damper of stiffness k(q) = Kp - m·g·l·cos(q + φ)
(upright: Kp - m·g·l = 4.16 N·m/rad), ωn = √(k/I), ζ = Kv/(2√(kI)); at rest Kp·(command - q) = -τ_g(q).

Tolerances come from the theory's own approximations, not from the measurements:

- local ωn and ζ are fitted over a stretch of angle ΔA; over it k varies by at most
  m·g·l·(|sin(q + φ)|·ΔA + ΔA²/2), and a fit returns some average k, so ωn (∝ √k) and ζ (∝ 1/√k)
  are within half that relative variation. The fit itself is exact for the loop's sampled dynamics
  (the forward difference of the recorded velocity is the acceleration each sample produced);
- the steady error waits for the settling: 5.01 s after the goal at σ = Kv/(2I) = 3.37 /s
  (underdamped there) leaves at most e^(-σT)/√(1-ζ²) of a move below 1 rad;
- the nonlinear model run differs from MuJoCo's only by the integrator: MuJoCo's semi-implicit
  Euler advances the angle with the step's end velocity, at most one step (1 ms) of motion:
  |Δq| ≤ max|q̇|·dt; lags compared within one loop period.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from jointctl.model import load_robot_model
from jointctl.model.robot_model import Inertial, Joint, Link, Pose, RobotModel
from jointctl.paths import robots_dir
from jointctl.scenario.analyses.minimal_robot import (
    PendulumTheory,
    fit_local_dynamics,
    pendulum_theory,
    tracking_lag_s,
)
from jointctl.scenario.run import run_scenario
from jointctl.scenario.spec import load_scenario
from jointctl.trajectory.messages import JointTrajectory

MINIMAL = robots_dir() / "minimal_robot"
GOAL_FILE = MINIMAL / "goals" / "example_trajectory_client.yaml"
G = 9.81
I_AXIS = 0.1 + 1.0 * 0.5**2 + 0.001 + 0.1 * (0.2**2 + 0.95**2)
MX, MZ = 0.1 * 0.2, 1.0 * 0.5 + 0.1 * 0.95
MGL = G * math.hypot(MX, MZ)
LEAN = math.atan2(MX, MZ)
KP, KV = 10.0, 3.0
DT = 0.001


def gravity_torque(q: float) -> float:
    return G * (MX * math.cos(q) + MZ * math.sin(q))


def stiffness(q: float) -> float:
    return KP - MGL * math.cos(q + LEAN)


def rest_pose(command: float) -> float:
    from scipy.optimize import brentq

    return brentq(lambda x: KP * (command - x) + gravity_torque(x), command - 2.0, command + 2.0, xtol=1e-15)


# -- the book's client goal ---------------------------------------------------------------------

def glibc_rand(seed: int = 1):
    """glibc's rand() after srand(seed): the additive feedback generator r[i] = r[i-3] + r[i-31]
    seeded by a Park-Miller sequence, 310 outputs discarded, each output shifted right by one."""
    r = [seed]
    for i in range(1, 31):
        hi, lo = divmod(r[i - 1], 127773)
        word = 16807 * lo - 2836 * hi
        r.append(word + 2147483647 if word < 0 else word)
    r += r[:3]
    for i in range(34, 344):
        r.append((r[i - 31] + r[i - 3]) & 0xFFFFFFFF)
    while True:
        r.append((r[-31] + r[-3]) & 0xFFFFFFFF)
        yield r[-1] >> 1


def book_client_points() -> list[tuple[float, float, float]]:
    """(time_from_start, position, velocity) as the book's example_trajectory_action_client builds them."""
    rand = glibc_rand()
    points, phase, t, dt = [], 0.0, 0.0, 0.1
    while phase < 4 * 3.1415927:
        t += dt
        points.append((t, 0.5 + 0.5 * math.sin(phase), 0.5 * math.cos(phase)))
        dt = (next(rand) % 100 + 1) * 0.01
        phase += dt
    return points


def test_glibc_rand_is_the_known_sequence():
    rand = glibc_rand()
    assert [next(rand) for _ in range(5)] == [1804289383, 846930886, 1681692777, 1714636915, 1957747793]


def test_the_goal_file_is_the_book_clients_goal():
    goal = JointTrajectory.from_dict(yaml.safe_load(GOAL_FILE.read_text()))
    assert goal.joint_names == ("joint1",)
    expected = book_client_points()
    assert len(goal.points) == len(expected) == 23
    for point, (t, q, v) in zip(goal.points, expected):
        assert point.time_from_start_s == pytest.approx(t, abs=1e-9)  # ros::Duration keeps nanoseconds
        assert point.positions == (q,)
        assert point.velocities == (v,)
        assert q == pytest.approx(0.5 + 0.5 * math.sin(t - 0.1), abs=1e-9)  # sin(t - 0.1)
    assert goal.points[0].time_from_start_s == 0.1
    assert goal.points[-1].time_from_start_s == pytest.approx(12.49, abs=1e-9)


# -- the theory and the measurements, on known cases ---------------------------------------------

def test_pendulum_theory_of_the_minimal_robot_is_the_hand_computed_one():
    theory = pendulum_theory(load_robot_model(MINIMAL / "urdf" / "minimal_robot.xacro"), "joint1",
                             (0.0, 0.0, -G), kp=KP, kv=KV)
    assert theory.inertia_kg_m2 == pytest.approx(I_AXIS, rel=1e-12)
    assert theory.mass_length_kg_m == pytest.approx(math.hypot(MX, MZ), rel=1e-12)
    assert theory.mgl_n_m == pytest.approx(MGL, rel=1e-12)
    assert theory.lean_rad == pytest.approx(LEAN, rel=1e-12)
    assert theory.upright_stiffness == pytest.approx(KP - MGL)
    for q in (0.0, 0.4, 1.3, -2.0):
        assert theory.gravity_torque(q) == pytest.approx(gravity_torque(q), abs=1e-12)
    assert theory.equilibrium(0.0) == pytest.approx(rest_pose(0.0), abs=1e-12)
    assert theory.natural_frequency(KP - MGL) == pytest.approx(math.sqrt((KP - MGL) / I_AXIS))
    assert theory.damping_ratio(KP - MGL) == pytest.approx(KV / (2 * math.sqrt((KP - MGL) * I_AXIS)))


def test_pendulum_theory_of_a_tilted_point_mass():
    """A 2 kg point at 0.5 m along the link's x, the joint about z on a base rolled 90° about x
    (so the joint axis is horizontal, world -y): gravity pulls with m·g·l = 9.81 N·m, I = 0.5."""
    base = Joint("base_joint", "fixed", "world", "base", origin=Pose(rpy=(math.pi / 2, 0.0, 0.0)))
    arm = Joint("j", "continuous", "base", "arm", axis=(0.0, 0.0, 1.0))
    robot = RobotModel("tilted", (Link("world"), Link("base"),
                                  Link("arm", Inertial(2.0, Pose(xyz=(0.5, 0.0, 0.0)), (0.0,) * 6))),
                       (base, arm))
    theory = pendulum_theory(robot, "j", (0.0, 0.0, -G), kp=30.0, kv=1.0)
    assert theory.inertia_kg_m2 == pytest.approx(0.5)
    assert theory.mgl_n_m == pytest.approx(2.0 * G * 0.5)
    # At q = 0 the mass is level (along the world x): gravity's torque is largest, towards -q
    # (positive q about the base's z, i.e. world -y, lifts +x).
    assert theory.gravity_torque(0.0) == pytest.approx(-2.0 * G * 0.5)
    assert theory.gravity_torque(-math.pi / 2) == pytest.approx(0.0, abs=1e-12)


def test_a_loop_that_cannot_hold_the_pendulum_has_no_pose():
    weak = PendulumTheory(kp=5.0, kv=KV, inertia_kg_m2=I_AXIS, mass_length_kg_m=MGL / G, mgl_n_m=MGL,
                          lean_rad=LEAN)
    with pytest.raises(ValueError, match="does not exceed"):
        weak.equilibrium(0.0)


def test_the_model_run_matches_a_linear_step_response():
    """Without gravity the model is a PD loop: a unit step from rest follows the analytic
    second-order response, within the one-sample hold of the control (max|q̇|·dt)."""
    theory = PendulumTheory(kp=KP, kv=KV, inertia_kg_m2=I_AXIS, mass_length_kg_m=0.0, mgl_n_m=0.0, lean_rad=0.0)
    t = np.arange(0.0, 4.0, DT)
    q = theory.simulate(t, np.ones_like(t), 0.0, 0.0)
    wn, zeta = math.sqrt(KP / I_AXIS), KV / (2 * math.sqrt(KP * I_AXIS))
    wd = wn * math.sqrt(1 - zeta**2)
    analytic = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))
    peak_speed = float(np.max(np.abs(np.gradient(analytic, t))))
    assert np.max(np.abs(q - analytic)) <= peak_speed * DT


def test_the_local_fit_recovers_a_sampled_loop_exactly():
    a, b, c = -9.34, -6.74, 0.44  # ωn 3.056 rad/s, ζ 1.1, rest 0.0471 rad
    q, v = [0.0], [0.0]
    for _ in range(3000):
        v.append(v[-1] + DT * (a * q[-1] + b * v[-1] + c))
        q.append(q[-1] + DT * v[-1])
    fit = fit_local_dynamics(np.arange(len(q)) * DT, np.array(q), np.array(v))
    assert fit.natural_frequency_rad_s == pytest.approx(math.sqrt(-a), rel=1e-9)
    assert fit.damping_ratio == pytest.approx(-b / (2 * math.sqrt(-a)), rel=1e-9)
    assert fit.rest_position_rad == pytest.approx(-c / a, rel=1e-9)


def test_the_lag_is_found_between_samples():
    t = np.arange(0.0, 12.0, DT)
    command = 0.5 + 0.5 * np.sin(t)
    lagged = 0.9 + 0.7 * np.sin(t - 0.4237)
    assert tracking_lag_s(t, command, lagged) == pytest.approx(0.4237, abs=2e-5)


# -- the scenario --------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("minimal_robot")
    run_scenario(load_scenario("minimal_robot_trajectory"), out)
    return out, json.loads((out / "metrics.json").read_text())


@pytest.mark.slow
def test_the_books_goal_succeeds(result):
    _, m = result
    assert m["result"] == "succeeded"
    assert m["points"] == 23
    assert m["duration_s"] == pytest.approx(12.49, abs=1e-9)


@pytest.mark.slow
def test_the_model_figures_are_the_books(result):
    _, m = result
    assert m["inertia_about_joint_kg_m2"] == pytest.approx(I_AXIS, rel=1e-12)
    assert m["gravity_torque_amplitude_n_m"] == pytest.approx(MGL, rel=1e-12)
    assert m["upright_stiffness_n_m_rad"] == pytest.approx(KP - MGL, rel=1e-12)
    assert m["upright_natural_frequency_rad_s"] == pytest.approx(math.sqrt((KP - MGL) / I_AXIS), rel=1e-12)
    assert m["upright_damping_ratio"] == pytest.approx(KV / (2 * math.sqrt((KP - MGL) * I_AXIS)), rel=1e-12)


@pytest.mark.slow
def test_steady_state_error_at_the_final_pose(result):
    """Kp·e = -τ_g(q) at the goal's last point: the pendulum rests 0.46 rad past its command."""
    _, m = result
    command = m["final_command_rad"]
    assert command == pytest.approx(book_client_points()[-1][1], abs=1e-9)
    expected_error = command - rest_pose(command)
    assert expected_error == pytest.approx(-0.4594, abs=1e-4)
    settle_s = 20.5 - 3.0 - 12.49
    zeta = KV / (2 * math.sqrt(stiffness(rest_pose(command)) * I_AXIS))
    bound = math.exp(-KV / (2 * I_AXIS) * settle_s) / math.sqrt(1 - zeta**2) + 1e-8  # + CSV rounding
    assert m["steady_state_error_rad"] == pytest.approx(expected_error, abs=bound)
    assert m["expected"]["steady_state_error_rad"] == pytest.approx(expected_error, abs=1e-12)


def _spread(q_rest: float, amplitude: float) -> float:
    """Largest relative change of the stiffness within ``amplitude`` of ``q_rest``."""
    return MGL * (abs(math.sin(q_rest + LEAN)) * amplitude + amplitude**2 / 2) / stiffness(q_rest)


@pytest.mark.slow
def test_natural_frequency_and_damping_about_the_spawn_pose(result):
    """Spawned upright with command 0, the pendulum settles to where the camera's lean is held
    (0.047 rad), with the upright pendulum's dynamics: overdamped, ζ = 1.1."""
    _, m = result
    rest = rest_pose(0.0)
    k = stiffness(rest)
    spread = (k - stiffness(0.0)) / k  # the fit spans q from 0 to the rest pose
    assert m["hold_position_rad"] == pytest.approx(rest, abs=spread * rest)
    assert m["hold_natural_frequency_rad_s"] == pytest.approx(math.sqrt(k / I_AXIS), rel=spread / 2)
    assert m["hold_damping_ratio"] == pytest.approx(KV / (2 * math.sqrt(k * I_AXIS)), rel=spread / 2)
    # Within that, the upright formulas of Kp - m·g·l:
    assert m["hold_natural_frequency_rad_s"] == pytest.approx(math.sqrt((KP - MGL) / I_AXIS), rel=0.01)
    assert m["hold_damping_ratio"] == pytest.approx(KV / (2 * math.sqrt((KP - MGL) * I_AXIS)), rel=0.01)


@pytest.mark.slow
def test_natural_frequency_and_damping_about_the_final_pose(result):
    _, m = result
    rest = rest_pose(m["final_command_rad"])
    k = stiffness(rest)
    spread = _spread(rest, m["final_amplitude_rad"])
    assert spread < 0.01
    assert m["final_natural_frequency_rad_s"] == pytest.approx(math.sqrt(k / I_AXIS), rel=spread / 2)
    assert m["final_damping_ratio"] == pytest.approx(KV / (2 * math.sqrt(k * I_AXIS)), rel=spread / 2)


@pytest.mark.slow
def test_the_run_follows_the_nonlinear_model(result):
    _, m = result
    assert m["model_max_difference_rad"] <= m["peak_velocity_rad_s"] * DT
    assert m["tracking_lag_s"] == pytest.approx(m["expected"]["tracking_lag_s"], abs=DT)
    assert m["rms_tracking_error_rad"] == pytest.approx(m["expected"]["rms_tracking_error_rad"],
                                                        abs=m["model_max_difference_rad"])


@pytest.mark.slow
def test_the_lag_lies_between_the_linear_lags_of_the_swept_poses(result):
    """A 1 rad/s sine lags atan2(Kv·ω, k - I·ω²)/ω; the swing sweeps k between its values at the
    lowest and highest rest poses of the command's range (0..1 rad), so the lag lies between."""
    _, m = result

    def lag(k: float) -> float:
        return math.atan2(KV, k - I_AXIS) / 1.0

    stiff, soft = stiffness(rest_pose(1.0)), stiffness(rest_pose(0.0))
    assert lag(stiff) < m["tracking_lag_s"] < lag(soft)
    assert lag(stiff) < m["tracking_lag_s_linear_at_mean_pose"] < lag(soft)


@pytest.mark.slow
def test_figures(result):
    out, _ = result
    names = {p.name for p in out.iterdir()}
    assert {"coarse_points.png", "interpolated_command.png", "position.png", "tracking_error.png",
            "effort.png", "metrics.json", "trace.csv"} <= names

"""One joint of a chain identified with the other joints' load computed from the robot's model and
subtracted (:mod:`jointctl.identification.coupling`), against the model's own numbers.

The truth: a joint's inertia at the pose the others are held at is its mass-matrix diagonal entry
there (MuJoCo's ``mj_fullM`` through jointctl's model, computed here independently of the fit),
plus ``dt·b`` (MuJoCo integrates the joint damping implicitly: the joint behaves as ``M_ii + dt·b``);
its damping is the URDF's. MuJoCo integrates exactly the manipulator equation whose off-diagonal and
velocity terms the coupling removes, so the fit is exact up to rounding; with noise added to the
effort the 95 % intervals hold the truth as often as they claim.

Before the coupling (the fit of one joint with the others' motion ignored), on these same runs: the
planar arm's elbow 0.08869 ± 0.00013 kg·m² (truth 0.0805), damping 0.5226 ± 0.0011 (0.5); the arm's
joint 1 89.05 ± 0.33 (112.46), damping 243 ± 4 (10); joint 2 11.03 ± 0.02 (15.09), 23.1 ± 0.1 (5);
joint 4 1.618 ± 0.003 (2.0905), 31.85 ± 0.03 (30).
"""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.identification.coupling import chain_coupling
from jointctl.identification.identify import identify_on_robot
from jointctl.identification.plant_fit import fit_plant
from jointctl.model import load_robot_model
from jointctl.model.dynamics import RobotDynamics
from jointctl.recording.trace import load_trace
from jointctl.scenario.spec import load_scenario, scenario_for_robot

from .planar_arm import ELBOW_DAMPING, ELBOW_INERTIA, planar_arm_scenario

DT = 0.001
ELBOW_REST = 0.3


def model_truth(scenario, joint: str, pose) -> tuple[float, float]:
    """(M_ii at ``pose`` + dt·b, b) of ``joint`` from the scenario's robot model."""
    robot = load_robot_model(scenario.robot.description)
    dynamics = RobotDynamics(robot, scenario.gravity_m_s2)
    dynamics.set_pose(pose)
    k = dynamics.joint_names.index(joint)
    return float(dynamics.mass_matrix()[k, k] + scenario.timestep_s * dynamics.damping[k]), float(dynamics.damping[k])


@pytest.fixture(scope="module")
def elbow(tmp_path_factory):
    folder = tmp_path_factory.mktemp("planar_arm")
    scenario = load_scenario(planar_arm_scenario(folder, elbow=ELBOW_REST))
    fit, metrics = identify_on_robot(scenario, "elbow", out_dir=folder / "out")
    return scenario, fit, metrics, folder / "out"


def test_the_truth_is_the_elbows_inertia_about_its_axis_plus_the_implicit_damping(elbow) -> None:
    scenario, *_ = elbow
    inertia, damping = model_truth(scenario, "elbow", [0.0, ELBOW_REST])
    assert inertia == pytest.approx(ELBOW_INERTIA + DT * ELBOW_DAMPING, rel=1e-9)  # I_c + m·l_c² + dt·b
    assert damping == ELBOW_DAMPING


def test_the_elbow_is_identified_without_the_shoulders_load(elbow) -> None:
    scenario, fit, metrics, out = elbow
    inertia, damping = model_truth(scenario, "elbow", [0.0, ELBOW_REST])
    shoulder = load_trace(out / "trace.csv").joint("shoulder", "position")
    assert np.ptp(shoulder) > 0.01  # the held shoulder did move under the elbow's reaction [rad]
    assert metrics["coupling"] == "model" and metrics["coupling_pose"]["shoulder"] == pytest.approx(0.0, abs=0.01)
    assert metrics["coupling_rms"] > 0.05  # the shoulder's load on the elbow (0.11 N·m RMS) [N·m]
    assert metrics["model_inertia_kg_m2"] == pytest.approx(ELBOW_INERTIA, rel=1e-9)  # the model's, no dt·b
    assert metrics["inertia_kg_m2"] == pytest.approx(inertia, rel=0.03)
    assert metrics["damping_n_m_s_rad"] == pytest.approx(damping, rel=0.10)
    assert metrics["data"]["gaps_cut"] == [] and metrics["data"]["excitation_share_used"] == 1.0
    # Exact data: the fit is the model's to rounding, and its intervals shrink to rounding too.
    assert metrics["inertia_kg_m2"] == pytest.approx(inertia, rel=1e-6)
    assert metrics["damping_n_m_s_rad"] == pytest.approx(damping, rel=1e-6)
    assert metrics["inertia_kg_m2_ci95"] < 1e-6 * inertia
    assert (out / "identify_elbow.png").stat().st_size > 10_000


def recorded(out):
    """(t, positions N x 2, velocities N x 2, elbow effort, joint names) of the elbow's run."""
    trace = load_trace(out / "trace.csv")
    names = ["shoulder", "elbow"]
    q = np.column_stack([trace.joint(n, "position") for n in names])
    qd = np.column_stack([trace.joint(n, "velocity") for n in names])
    return trace.time_s, q, qd, trace.joint("elbow", "effort"), names


def test_without_the_coupling_the_same_run_reads_the_shoulders_load_as_elbow_inertia(elbow) -> None:
    scenario, _, _, out = elbow
    inertia, damping = model_truth(scenario, "elbow", [0.0, ELBOW_REST])
    t, q, qd, u, _ = recorded(out)
    alone = fit_plant(t, q[:, 1], qd[:, 1], u, joint_type="revolute")
    assert alone.coupling == "none"
    assert alone.inertia == pytest.approx(1.10 * inertia, rel=0.02)  # 10 % too heavy
    assert abs(alone.inertia - inertia) > 20 * alone.inertia_ci95  # and its interval far from the truth
    assert abs(alone.damping - damping) > 10 * alone.damping_ci95


def test_with_noise_on_the_effort_the_intervals_hold_the_truth_as_often_as_they_claim(elbow) -> None:
    # 20 draws of white noise (0.05 N·m) on the recorded effort: a 95 % interval misses the truth in 1
    # draw of 20 on average; 4 misses or more has a probability of 1.6 % (binomial), so at least 17 of 20.
    scenario, _, _, out = elbow
    inertia, damping = model_truth(scenario, "elbow", [0.0, ELBOW_REST])
    t, q, qd, u, names = recorded(out)
    coupling = chain_coupling(load_robot_model(scenario.robot.description), "elbow", names, t, q, qd,
                              gravity_m_s2=scenario.gravity_m_s2)
    covered = {"inertia": 0, "damping": 0}
    for seed in range(20):
        noisy = u + np.random.default_rng(seed).normal(0.0, 0.05, u.size)
        fit = fit_plant(t, q[:, 1], qd[:, 1], noisy, joint_type="revolute",
                        coupling_torque=coupling.torque, inertia_scale=coupling.inertia_scale)
        assert 0 < fit.inertia_ci95 < 0.03 * inertia and 0 < fit.damping_ci95 < 0.1 * damping
        covered["inertia"] += abs(fit.inertia - inertia) < fit.inertia_ci95
        covered["damping"] += abs(fit.damping - damping) < fit.damping_ci95
    assert covered["inertia"] >= 17 and covered["damping"] >= 17


@pytest.mark.parametrize("joint", ["joint1", "joint2", "joint4"])
def test_the_arms_joints_at_rest_are_their_mass_matrix_diagonal_plus_the_implicit_damping(joint) -> None:
    scenario = scenario_for_robot("arm7dof", "position")  # resting upright, every joint at 0
    fit, metrics = identify_on_robot(scenario, joint)
    inertia, damping = model_truth(scenario, joint, [0.0] * 7)
    assert max(abs(v) for v in metrics["coupling_pose"].values()) < 0.01  # held near the rest pose [rad]
    assert fit.coupling == "model" and fit.coupling_rms > 0
    assert fit.inertia == pytest.approx(inertia, rel=0.03) and fit.damping == pytest.approx(damping, rel=0.10)
    # Exact data: the intervals are rounding-wide (1e-13 of the value); the truth is within them and the
    # rounding of the model's matrices and of the pose the others were held at (3e-8 rad from rest).
    assert abs(fit.inertia - inertia) <= fit.inertia_ci95 + 1e-6 * inertia
    assert abs(fit.damping - damping) <= fit.damping_ci95 + 1e-6 * damping

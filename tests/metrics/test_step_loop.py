"""The joint loop as it runs (:class:`~jointctl.metrics.step_loop.JointLoop`) against the equations it integrates,
written here: MuJoCo's semi-implicit Euler over several physics steps a cycle, a command that arrives cycles late,
a feed-forward from a model that is not the plant, a run from where a session starts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jointctl.metrics.step_loop import JointLoop, reference_step

H = 0.001
M, B = 1.01, 10.0
G = 9.81


def euler(q: float, v: float, force: float, h: float, n: int) -> tuple[float, float]:
    """``n`` steps of ``h/n`` of MuJoCo's semi-implicit Euler with implicit damping: v⁺ = (v + h·f/m)/(1 + h·b/m),
    q⁺ = q + h·v⁺."""
    dt = h / n
    for _ in range(n):
        v = (v + dt * force / M) / (1 + dt * B / M)
        q = q + dt * v
    return q, v


def pd_on_measurement(reference: np.ndarray, p: float, d: float, *, delay: int = 0, substeps: int = 1,
                      start=(0.0, 0.0), load: float = 0.0) -> np.ndarray:
    """The positions of ``p·(r - q) - d·v`` reaching the joint ``delay`` cycles late (zero before), a constant
    ``load`` [N] pulling it down, ``substeps`` physics steps a cycle."""
    q, v = start
    pending = [0.0] * delay
    out = []
    for r in reference:
        out.append(q)
        pending.append(p * (r - q) - d * v)
        q, v = euler(q, v, pending.pop(0) - load, H, substeps)
    return np.array(out)


def test_several_physics_steps_a_cycle_are_integrated_as_mujoco_does():
    loop = JointLoop(M, B, H, p=400.0, d=5.0, derivative="measurement", integrator="euler", substeps=4)
    reference = reference_step(0.0, 0.1, hold_s=0.01, after_s=0.5, period_s=H)
    q, _, _ = loop.run(reference, start=(0.0, 0.0))
    assert np.max(np.abs(q - pd_on_measurement(reference, 400.0, 5.0, substeps=4))) < 1e-15


@pytest.mark.parametrize("delay", [1, 3])
def test_a_command_reaches_the_joint_cycles_late(delay):
    loop = JointLoop(M, B, H, p=400.0, d=5.0, derivative="measurement", integrator="euler", delay_cycles=delay)
    reference = reference_step(0.0, 0.1, hold_s=0.01, after_s=0.5, period_s=H)
    q, _, u = loop.run(reference, start=(0.0, 0.0))
    assert np.max(np.abs(q - pd_on_measurement(reference, 400.0, 5.0, delay=delay))) < 1e-15
    step = int(np.flatnonzero(reference)[0])
    assert u[step] == pytest.approx(400.0 * 0.1)  # commanded at the step...
    assert np.all(q[: step + delay + 1] == 0.0)  # ... it moves the joint delay cycles later, seen a cycle after


def test_a_delayed_loop_from_rest_had_its_holding_command_on_the_way():
    # From rest, the commands on their way are the one that holds: nothing moves before the step arrives.
    loop = JointLoop(M, B, H, hold=lambda q: M * G, p=400.0, derivative="measurement", integrator="euler",
                     delay_cycles=5)
    reference = reference_step(0.0, 0.1, hold_s=0.02, after_s=0.2, period_s=H)
    q, _, _ = loop.run(reference)
    rest = -M * G / 400.0
    assert q[0] == pytest.approx(rest, rel=1e-12)
    assert np.max(np.abs(q[:20 + 5 + 1] - rest)) < 1e-15


def test_a_started_loop_has_no_command_on_the_way_and_the_load_pulls_it_down():
    # As a session starts: the controller just started, its first commands still on their way (zero).
    loop = JointLoop(M, B, H, hold=lambda q: M * G, p=400.0, derivative="measurement", integrator="euler",
                     delay_cycles=3)
    reference = np.zeros(200)
    q, _, _ = loop.run(reference, start=(0.0, 0.0))
    assert np.max(np.abs(q - pd_on_measurement(reference, 400.0, 0.0, delay=3, load=M * G))) < 1e-15
    assert q[1] < 0.0  # falling before the first command arrives


def test_a_feed_forward_from_a_lighter_model_leaves_the_payload_on_the_p_term():
    # The plant weighs 2 kg more than the model the feed-forward is computed from: the P loop holds 2·g.
    plant, model = lambda q: (M + 2.0) * G, lambda q: M * G
    loop = JointLoop(M + 2.0, B, H, hold=plant, p=400.0, d=20.0, derivative="measurement", feedforward=True,
                     feedforward_hold=model, integrator="euler")
    q, _ = loop.rest(0.0)
    assert q == pytest.approx(-2.0 * G / 400.0, rel=1e-12)
    positions, _, efforts = loop.run(reference_step(0.0, 0.1, hold_s=0.01, after_s=5.0, period_s=H))  # e^-25
    assert positions[-1] == pytest.approx(0.1 - 2.0 * G / 400.0, abs=1e-9)
    assert efforts[-1] == pytest.approx((M + 2.0) * G, rel=1e-6)
    # With the plant's own model the feed-forward holds it all: it rests at its reference.
    assert JointLoop(M + 2.0, B, H, hold=plant, p=400.0, feedforward=True).rest(0.1)[0] == pytest.approx(0.1)


def test_an_integral_holds_the_payload_the_feed_forward_misses():
    loop = JointLoop(M + 2.0, B, H, hold=lambda q: (M + 2.0) * G, p=400.0, i=100.0, i_clamp=50.0,
                     feedforward=True, feedforward_hold=lambda q: M * G)
    q, integral = loop.rest(0.2)
    assert q == pytest.approx(0.2) and integral == pytest.approx(2.0 * G)
    assert math.isclose(loop.feedforward_effort(0.0), M * G)


def test_a_kept_holding_effort_is_the_one_computed_for_the_same_robot_and_the_other_joints_pose():
    from jointctl.metrics.step_loop import holding_effort
    from jointctl.model.loader import load_robot_model
    from jointctl.paths import robots_dir

    arm = load_robot_model(robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro")
    names = [j.name for j in arm.movable_joints]
    pose = dict.fromkeys(names, 0.3)
    memo: dict = {}
    kept = holding_effort(arm, names[1], pose, memo=memo)
    # The joint's own position is not part of the answer (the profile spans its range): the same one is kept.
    assert holding_effort(arm, names[1], {**pose, names[1]: -0.2}, memo=memo) is kept
    other = holding_effort(arm, names[1], {**pose, names[3]: 1.0}, memo=memo)  # another pose of a neighbour
    fresh = holding_effort(arm, names[1], {**pose, names[3]: 1.0})
    assert other is not kept and len(memo) == 2
    grid = np.linspace(-1.5, 1.5, 31)
    assert [other(q) for q in grid] == [fresh(q) for q in grid]
    assert [kept(q) for q in grid] != [fresh(q) for q in grid]

"""Joint limits are stops: the limit solver parameters model/mjcf.py gives every limited joint.

Theory (docs/simulation.md): with solref = (tau, zeta) = (2 dt, 1) and MuJoCo's default impedance
(dmin 0.9, dmax 0.95), a joint pushed into its limit by a constant f rests at a penetration
    r = (1 - d)/d² · dmax² · tau² · zeta² · invweight · f,   d in [dmin, dmax],
so (1 - dmax) · tau² · invweight · f <= r <= (1 - dmin)/dmin² · dmax² · tau² · invweight · f
(the upper bound is :func:`limit_overshoot_bound`). At dt = 1 ms: tau² = 4e-6 s², and the upper
factor is 0.1114 · 4e-6 = 4.46e-7 s².
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from jointctl.model import load_robot_model
from jointctl.model.mjcf import (
    LIMIT_DAMPRATIO,
    LIMIT_SOLIMP,
    limit_overshoot_bound,
    limit_solref,
)
from jointctl.paths import robots_dir
from jointctl.sim import MujocoWorld, WorldSettings
from jointctl.sim.objects import ObjectSpec

ONE_DOF_XACRO = robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro"
ARM_XACRO = robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro"
G = 9.81
MOVING_KG = 1.01  # piston 1 kg + sensor disk 0.01 kg
DT = 0.001
PUSH_N = 200.0
MUJOCO_DEFAULT_SOLREF = (0.02, 1.0)


@pytest.fixture(scope="module")
def one_dof():
    return load_robot_model(ONE_DOF_XACRO)


@pytest.fixture(scope="module")
def arm():
    return load_robot_model(ARM_XACRO)


def push(world: MujocoWorld, joint: str, command: float, seconds: float) -> dict[str, float]:
    """Command a constant effort [N or N·m] on ``joint`` for ``seconds``; return its overshoot past
    the nearer limit at the end [m or rad], its peak overshoot, final speed, applied actuator force
    and the most solver iterations any step took."""
    d = world.data
    k = world.joint_names.index(joint)
    qadr, vadr, act = world.qpos_adr[k], world.dof_adr[k], world.actuator_ids[k]
    lower, upper = world.robot.joint(joint).limits.lower, world.robot.joint(joint).limits.upper
    peak, iterations = 0.0, 0
    for _ in range(round(seconds / world.timestep_s)):
        d.ctrl[act] = command
        world.step()
        q = float(d.qpos[qadr])
        peak = max(peak, q - upper, lower - q)
        iterations = max(iterations, int(d.solver_niter[0]))
    q = float(d.qpos[qadr])
    return {"overshoot": max(q - upper, lower - q, 0.0), "peak": peak, "speed": abs(float(d.qvel[vadr])),
            "force": float(d.actuator_force[act]), "iterations": iterations}


# -- the parameters ------------------------------------------------------------


@pytest.mark.parametrize("timestep", [0.0005, 0.001, 0.002])
def test_every_limited_joint_gets_the_stop_of_the_timestep(one_dof, arm, timestep: float) -> None:
    assert limit_solref(timestep) == (2 * timestep, LIMIT_DAMPRATIO)
    for robot in (one_dof, arm):
        world = MujocoWorld(robot, WorldSettings(timestep_s=timestep))
        m = world.model
        assert m.opt.timestep == timestep  # the step is not shortened to make the stop stiff
        limited = [j for j in range(m.njnt) if m.jnt_limited[j]]
        assert len(limited) == len(robot.movable_joints)  # prismatic (one_dof) and revolute (arm)
        for j in limited:
            assert m.jnt_solref[j] == pytest.approx([2 * timestep, 1.0], abs=0)
            assert m.jnt_solimp[j] == pytest.approx(LIMIT_SOLIMP, abs=0)



def test_the_stop_survives_spawning_an_object(one_dof) -> None:
    """Spawning recompiles the model from the spec, which holds the limit parameters."""
    world = MujocoWorld(one_dof, WorldSettings(timestep_s=0.0005))
    world.spawn(ObjectSpec("weight", "cylinder", (0.05, 0.2), 10.0, (0.0, 0.0, 4.0)))
    j = world.model.joint("joint1").id
    assert world.model.jnt_solref[j] == pytest.approx([0.001, 1.0], abs=0)
    assert world.model.jnt_solimp[j] == pytest.approx(LIMIT_SOLIMP, abs=0)

def test_the_bound_is_the_formula(one_dof) -> None:
    # (1 - 0.9)/0.9² · 0.95² · (0.002 s)² · 1 · (1/1.01 kg) · 190.1 N = 0.0839 mm
    f = PUSH_N - MOVING_KG * G
    expected = 0.1 / 0.81 * 0.9025 * 4e-6 * f / MOVING_KG
    assert limit_overshoot_bound(f, 1 / MOVING_KG, DT) == pytest.approx(expected, rel=1e-12)
    assert limit_overshoot_bound(-f, 1 / MOVING_KG, DT) == limit_overshoot_bound(f, 1 / MOVING_KG, DT)
    # quadratic in the timestep (tau = 2 dt)
    assert limit_overshoot_bound(f, 1.0, 2 * DT) == pytest.approx(4 * limit_overshoot_bound(f, 1.0, DT))
    m = MujocoWorld(one_dof).model
    assert m.dof_invweight0[0] == pytest.approx(1 / MOVING_KG, rel=1e-9)  # MuJoCo's inverse inertia


# -- the 1-DOF piston pushed into its limits -------------------------------------


@pytest.mark.parametrize("side", ["upper", "lower"])
@pytest.mark.parametrize("load", ["200 N", "effort limit"])
def test_one_dof_pushed_into_a_limit_stays_at_it(one_dof, side: str, load: str) -> None:
    """From mid-range, a constant push drives the piston into the limit (it arrives at 10.5 or 27.5 m/s)
    and holds it there. Tolerances from the parameters (1 ms step, invweight 1/1.01 kg):

    - 200 N: constraint force f <= 200 + m g = 209.9 N, overshoot <= 4.46e-7 · 209.9 / 1.01
      = 0.093 mm (required: 1 mm);
    - effort limit 1000 N (commanded 10 000 N, clamped by the actuator's force range):
      f <= 1009.9 N, overshoot <= 0.446 mm (required: 5 mm).
    At the lower limit the floor also touches the piston's foot and takes a little of the load.
    """
    world = MujocoWorld(one_dof, WorldSettings(timestep_s=DT, gravity_m_s2=(0.0, 0.0, -G)),
                        initial_positions={"joint1": -0.5})
    effort_limit = one_dof.joint("joint1").limits.effort
    assert effort_limit == 1000.0
    force = PUSH_N if load == "200 N" else effort_limit
    sign = 1.0 if side == "upper" else -1.0
    command = sign * (PUSH_N if load == "200 N" else 10 * effort_limit)
    result = push(world, "joint1", command, 2.0)
    assert result["force"] == sign * force  # the effort limit is what pushes, not the command
    assert result["speed"] < 1e-9  # at rest: the overshoot is the steady one
    constraint_force = force - sign * MOVING_KG * G  # gravity helps at the lower limit
    bound = limit_overshoot_bound(constraint_force, world.model.dof_invweight0[0], DT)
    assert result["overshoot"] <= bound
    assert result["overshoot"] <= (1e-3 if load == "200 N" else 5e-3)  # the requirement
    if side == "upper":  # the limit alone holds it: theory from both sides (d between dmin and dmax)
        dmax = LIMIT_SOLIMP[1]
        lowest = (1 - dmax) * (2 * DT) ** 2 * constraint_force / MOVING_KG
        assert lowest <= result["overshoot"]


def test_mujocos_default_softness_would_fail_the_requirement(one_dof) -> None:
    """The control experiment: with MuJoCo's default solref (0.02 s, 1) the same push sinks past
    1 mm: r = (1 - dmax) · tau² · f/m = 0.05 · 4e-4 · 190.1/1.01 = 3.76 mm (d = dmax beyond 1 mm)."""
    world = MujocoWorld(one_dof, initial_positions={"joint1": 0.0})
    world.model.jnt_solref[:] = MUJOCO_DEFAULT_SOLREF
    result = push(world, "joint1", PUSH_N, 1.0)
    expected = 0.05 * 0.02**2 * (PUSH_N - MOVING_KG * G) / MOVING_KG
    assert result["overshoot"] == pytest.approx(expected, rel=1e-6)
    assert result["overshoot"] > 1e-3


# -- the arm's revolute joints ---------------------------------------------------

# Every joint at each limit, the rest of the arm at zero. joint3 at its lower limit (-3.1 rad) folds
# the forearm back onto the base, so the plate starts inside the base: left out (a contact, not a limit).
ARM_CASES = [(f"joint{k}", side) for k in range(7) for side in ("upper", "lower")
             if (f"joint{k}", side) != ("joint3", "lower")]


@pytest.mark.parametrize(("joint", "side"), ARM_CASES)
def test_arm_joint_pushed_with_its_effort_limit_stays_at_its_limit(arm, joint: str, side: str) -> None:
    """The arm starts at rest with ``joint`` on its limit and its motor saturated at the effort limit
    (commanded 10×) pushing into it; gravity and floor off so the motor alone loads the limit.
    Tolerance: overshoot <= 4.46e-7 s² · invweight · effort (invweight 0.03-1.03 /(kg·m²), efforts
    70-1300 N·m): at most 0.05 mrad, i.e. 0.05 mm at 1 m from the axis (required: 5 mm)."""
    lim = arm.joint(joint).limits
    start = lim.upper if side == "upper" else lim.lower
    world = MujocoWorld(arm, WorldSettings(timestep_s=DT, gravity_m_s2=(0.0, 0.0, 0.0), floor=False),
                        initial_positions={joint: start})
    assert world.data.ncon == 0  # nothing but the limit in the way
    sign = 1.0 if side == "upper" else -1.0
    result = push(world, joint, sign * 10 * lim.effort, 1.0)
    assert result["force"] == sign * lim.effort
    assert result["speed"] < 1e-8
    k = world.joint_names.index(joint)
    bound = limit_overshoot_bound(lim.effort, world.model.dof_invweight0[world.dof_adr[k]], DT)
    assert result["overshoot"] <= bound
    assert bound <= 5e-5
    assert result["peak"] <= 3 * bound  # it started on the limit: no impact to speak of


# -- the loop is not slowed ------------------------------------------------------


def test_the_stop_costs_no_steps_and_few_solver_iterations(one_dof) -> None:
    """Benchmark-free: the physics step is the scenario's, so one simulated second is 1000 steps
    whatever the stop; MuJoCo's solver converges in at most 2 iterations a step while the joint rests
    on the limit (Newton on one constraint row); and away from the limits there is no constraint row
    at all, so free motion costs exactly what it did."""
    world = MujocoWorld(one_dof, WorldSettings(timestep_s=DT), initial_positions={"joint1": -0.5})
    result = push(world, "joint1", PUSH_N, 1.0)
    assert world.time_s == pytest.approx(1.0, abs=1e-9)
    assert world.data.nefc == 1
    assert world.data.efc_type[0] == mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT
    assert result["iterations"] <= 2
    world.reset()
    world.step()
    assert world.data.nefc == 0


def test_motion_away_from_the_limits_is_bit_identical(one_dof) -> None:
    """The limit parameters act only while a limit is active: a P law moving the piston between
    -0.5 and -0.3 m gives the same trajectory, bit for bit, with MuJoCo's default softness."""
    traces = []
    for solref in (None, MUJOCO_DEFAULT_SOLREF):
        world = MujocoWorld(one_dof, initial_positions={"joint1": -0.5})
        if solref is not None:
            world.model.jnt_solref[:] = solref
        d = world.data
        q = np.empty(2000)
        for n in range(2000):
            d.ctrl[0] = 400.0 * (-0.3 - d.qpos[0]) + MOVING_KG * G
            world.step()
            q[n] = d.qpos[0]
        traces.append(q)
    assert traces[0].min() > -1.0 and traces[0].max() < 0.0
    assert np.array_equal(traces[0], traces[1])

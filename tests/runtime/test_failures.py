"""The failure policy: a controller that raises or outputs a non-finite effort is deactivated with
its chain within the cycle, its joints get zero effort, the rest of the loop carries on, and the
failure reaches the user; MuJoCo's warnings become PhysicsError."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from jointctl.errors import ControllerFailed, PhysicsError
from jointctl.hardware.interface import EFFORT
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from jointctl.trajectory.executor import GoalStatus
from jointctl.trajectory.messages import JointTrajectory
from tests.faulty_controllers import FAULTY_TYPE

ROOT = Path(__file__).resolve().parents[2]
PRE_POSE = {"joint0": 0.0, "joint1": 1.0, "joint2": 0.0, "joint3": -2.0, "joint4": 0.0, "joint5": 1.0, "joint6": 0.0}
STEP_AT_S = 0.2


def arm_scenario(fault: str) -> dict:
    """The arm holding its pre-pose; joint6's controller faults when its step command (at 0.2 s)
    passes 0.1 rad."""
    names = [f"joint{k}_position_controller" for k in range(7)]
    return {
        "name": "arm_fault", "robot": "arm7dof", "controller_file": "position",
        "controllers": {"joint6_position_controller": {"type": FAULTY_TYPE, "fail_above": 0.1, "fault": fault}},
        "start_controllers": ["joint_state_controller", *names],
        "initial_positions": PRE_POSE, "duration_s": 0.6,
        "commands": {
            **{n: {"type": "constant", "value": PRE_POSE[f"joint{k}"]} for k, n in enumerate(names[:6])},
            "joint6_position_controller": {"type": "step", "from": 0.0, "to": 0.3, "at": STEP_AT_S},
        },
    }


def run_with_trace(session: Session) -> list[tuple[float, list[float], list[float]]]:
    """Run the session; per cycle after the write: (t, effort commands, MuJoCo's ctrl)."""
    rows = []
    hw, data = session.hardware, session.world.data
    session.loop.add_observer(lambda t: rows.append((t, list(hw.command_buffer(EFFORT)), data.ctrl.tolist())))
    session.run()
    return rows


@pytest.mark.parametrize(("fault", "reason"), [("raise", "RuntimeError in update: deliberate fault"),
                                               ("nan", "non-finite command nan for joint 'joint6'")])
def test_a_failing_controller_is_deactivated_and_its_joint_gets_zero_effort_within_the_cycle(
        write_scenario, fault, reason):
    with Session(load_scenario(write_scenario(arm_scenario(fault)))) as session:
        rows = run_with_trace(session)
        manager = session.manager
    failure, = manager.failures
    assert failure.controller == "joint6_position_controller" and reason in failure.reason
    assert failure.chain == ("joint6_position_controller",) and failure.joints == ("joint6",)
    assert failure.time_s == pytest.approx(STEP_AT_S)
    before = [r for r in rows if r[0] < STEP_AT_S - 1e-9]
    after = [r for r in rows if r[0] >= STEP_AT_S - 1e-9]
    assert all(math.isfinite(e) for r in before for e in r[1])
    # From the failing cycle on, joint 6's effort and MuJoCo's control for it are exactly zero.
    assert after and all(r[1][6] == 0.0 and r[2][6] == 0.0 for r in after)
    # The other controllers carried on: joint 1 and 3 hold the pre-pose against gravity.
    assert all(abs(r[1][1]) > 1.0 for r in after)
    assert session.hardware.position[1] == pytest.approx(1.0, abs=0.01)
    assert session.hardware.position[3] == pytest.approx(-2.0, abs=0.01)
    assert "joint6_position_controller" not in {c.name for c in manager.active}
    assert "joint5_position_controller" in {c.name for c in manager.active}
    with pytest.raises(ControllerFailed, match="failed at t = 0.200 s"):
        manager.raise_failures()


def test_a_chain_fails_together_and_its_goal_is_aborted(write_scenario):
    scenario = {
        "name": "chain_fault", "robot": "one_dof", "controller_file": "trajectory",
        "controllers": {"joint1_position_controller": {"type": FAULTY_TYPE, "fail_above": -0.4}},
        "start_controllers": ["joint_state_controller", "joint1_position_controller", "joint1_trajectory_controller"],
        "initial_positions": {"joint1": -0.5}, "duration_s": 0.1,
    }
    with Session(load_scenario(write_scenario(scenario))) as session:
        session.run(0.1)
        executor = session.manager.controller("joint1_trajectory_controller")
        goal = JointTrajectory.from_arrays(["joint1"], [2.0], [[-0.2]])
        handle = executor.submit(goal)
        session.run(2.0)
    assert handle.done and handle.result.status is GoalStatus.ABORTED
    assert "chain failed" in handle.result.error_string and "deliberate fault" in handle.result.error_string
    failure, = session.manager.failures
    assert set(failure.chain) == {"joint1_trajectory_controller", "joint1_position_controller"}
    assert [c.name for c in session.manager.active] == ["joint_state_controller"]  # the broadcaster runs on
    assert session.hardware.command_buffer(EFFORT)[0] == 0.0
    # Zero effort: the piston falls under gravity onto its lower limit (the joint's damping brakes it).
    assert session.hardware.position[0] == pytest.approx(-1.0, abs=0.005)


def test_the_cli_reports_a_failure_in_one_line_and_exits_non_zero(write_scenario, tmp_path):
    path = write_scenario(arm_scenario("raise"))
    result = subprocess.run([sys.executable, "-m", "tests.faulty_controllers", "run", str(path), "--out",
                             str(tmp_path / "o")], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert lines[0] == f"jointctl: took {path} as a scenario"  # then the one line of the error
    lines = lines[1:]
    assert len(lines) == 1 and lines[0].startswith("jointctl: error: controller: failed at t = 0.200 s"), lines
    assert "joint6_position_controller" in lines[0] and "zero effort" in lines[0]
    assert (tmp_path / "o" / "trace.csv").exists()  # the run went on to its end and was recorded


def test_an_unstable_simulation_is_a_physics_error_naming_the_warning(write_scenario):
    scenario = {"name": "unstable", "robot": "one_dof", "controller_file": "position",
                "start_controllers": ["joint_state_controller", "joint1_position_controller"],
                "initial_positions": {"joint1": -0.5}, "duration_s": 0.1}
    with Session(load_scenario(write_scenario(scenario))) as session:
        session.run(0.01)  # a valid world runs
        session.world.data.qvel[0] = 1e300  # what a diverging loop ends in
        with pytest.raises(PhysicsError) as caught:
            session.run(0.2)  # the counts are read every 100 cycles
    assert caught.value.field == "mjWARN_BADQVEL"

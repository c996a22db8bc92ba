"""The compiled cycle gives the Python loop's numbers: every built-in scenario it covers, and variants of
each part's law, run on both paths with the same trace (each column within 1e-9 of its range: the kernels do
the same operations in the same order, so the difference is rounding at most), the same events at the same
cycles (controller failures, physics warnings) and the same state left in the Python objects."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
import pytest

from jointctl.control.admittance_controller import AdmittanceController
from jointctl.control.cartesian_admittance_controller import CartesianAdmittanceController
from jointctl.control.joint_controllers import JointPositionController
from jointctl.control.joint_state_controller import JointStateController
from jointctl.errors import ExpressionError, PhysicsError
from jointctl.trajectory.errors import TrajectoryErrorCode
from jointctl.trajectory.goals import GoalStatus
from jointctl.recording.trace import Trace, load_trace
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from jointctl.trajectory.executor import TrajectoryExecutor
from jointctl.visuals.video import FrameCapture
from tests.conftest import step_scenario

#: Each column of the two traces agrees within this fraction of its range (the issue's bound).
RELATIVE = 1e-9


@dataclass
class Run:
    session: Session
    trace: Trace
    error: Exception | None
    capture: FrameCapture | None
    poses: list | None = None  # run.mcap's samples of the spawned objects (before the record is written)


def run_on(path: str | Path, loop: str, out: Path, overrides=(), *, before=None, video_fps=None,
           mcap=False) -> Run:
    """Run the scenario at ``path`` (or a built-in name) with ``loop`` (python or auto) into ``out``;
    ``before(session)`` runs first (a part of the run, a change of state)."""
    scenario = load_scenario(path, [*overrides, f"loop={loop}"])
    error = capture = None
    with Session(scenario, out_dir=out, mcap=mcap) as session:
        if video_fps:
            capture = FrameCapture(session.world, video_fps)
            session.loop.add_observer(capture)
        try:
            if before is not None:
                before(session)
            session.run()
        except PhysicsError as exc:
            error = exc
        poses = list(session.mcap.objects.samples) if mcap else None
    return Run(session, load_trace(out / "trace.csv"), error, capture, poses)


def both_paths(path, tmp_path: Path, overrides=(), **kwargs) -> tuple[Run, Run]:
    python = run_on(path, "python", tmp_path / "python", overrides, **kwargs)
    compiled = run_on(path, "auto", tmp_path / "compiled", overrides, **kwargs)
    assert python.session.loop.mode == "python"
    assert compiled.session.loop.mode == "compiled", compiled.session.loop.mode_reason
    return python, compiled


def assert_same_columns(python: Trace, compiled: Trace) -> None:
    assert list(python.columns) == list(compiled.columns)
    for name, a in python.columns.items():
        b = compiled[name]
        assert a.shape == b.shape, name
        assert np.array_equal(np.isnan(a), np.isnan(b)), name
        finite = ~np.isnan(a)
        if finite.any():
            span = np.ptp(a[finite]) or max(1.0, np.abs(a[finite]).max())
            assert np.abs(a[finite] - b[finite]).max() <= RELATIVE * span, name


#: What the Cartesian admittance controller keeps after a cycle (the analyses, the tuning page and the next
#: cycle read them).
CARTESIAN_STATE = ("velocity_reference", "velocity_command", "tare_force", "_tare", "_tare_sum", "_tare_count",
                   "sensed_force", "force", "virtual_force", "acceleration", "orientation_error", "velocity",
                   "torque", "_generalized", "_qd", "jv", "jr", "position", "rotation", "jr_columns", "_dls_rows",
                   "target_rotation")


def _plain(value):
    return value.tolist() if isinstance(value, np.ndarray) else value


def controller_state(c) -> tuple:
    if isinstance(c, TrajectoryExecutor):
        goal = c.goals.active
        return (c._ref, c.latest_feedback, c._next_feedback_s, c._next_stream_s, c._supervise_at,
                c._stream_deadline_s, c._last_time_s, c.goals_served, goal.id if goal else None,
                c._plan.end_s if c._plan else None)
    if isinstance(c, JointStateController):
        return c.published, c.latest
    if isinstance(c, AdmittanceController):
        return (c.velocity_reference, c.position, c.velocity, c.force, c._next_joint_state_s, c._next_force_s)
    if isinstance(c, CartesianAdmittanceController):
        return tuple((name, _plain(getattr(c, name, None))) for name in CARTESIAN_STATE)
    state = (c.pid.i_state, c.clamped_cycles, c.clamped_furthest, c._last_error, c._last_valid, c.reference)
    if isinstance(c, JointPositionController):
        state += (c._last_rate, c._edge_velocity, c.reference_input)
    return state


def assert_same(python: Run, compiled: Run) -> None:
    """The same trace, events at the same cycles and the same state left behind."""
    assert_same_columns(python.trace, compiled.trace)
    p, c = python.session, compiled.session
    assert p.loop.cycle == c.loop.cycle
    assert [(f.controller, f.time_s, f.reason) for f in p.manager.failures] == \
        [(f.controller, f.time_s, f.reason) for f in c.manager.failures]
    assert str(python.error) == str(compiled.error)
    assert [x.name for x in p.manager.active] == [x.name for x in c.manager.active]
    for a, b in zip(p.manager.loaded(), c.manager.loaded()):
        assert controller_state(a) == controller_state(b), a.name
    assert p.manager.references == c.manager.references
    assert [(g.id, g.status, g.result) for g in p.goals] == [(g.id, g.status, g.result) for g in c.goals]
    assert [(t, str(e)) for t, e in p.rejected_goals] == [(t, str(e)) for t, e in c.rejected_goals]
    assert p.hardware.position == c.hardware.position and p.hardware.effort == c.hardware.effort
    assert p.hardware.wrenches == c.hardware.wrenches
    assert p.hardware._until_warning_check == c.hardware._until_warning_check
    np.testing.assert_array_equal(p.world.data.qpos, c.world.data.qpos)
    for name, source in p.sources.items():
        assert (source._hold.k, source._hold.value) == (c.sources[name]._hold.k, c.sources[name]._hold.value) \
            if hasattr(source, "_hold") else True
    if python.poses is not None:  # run.mcap's samples of the spawned objects' poses
        a, b = python.poses, compiled.poses
        assert [t for t, _ in a] == [t for t, _ in b]
        for (_, poses_a), (_, poses_b) in zip(a, b):
            assert [spec for spec, *_ in poses_a] == [spec for spec, *_ in poses_b]
            for (_, *pose_a), (_, *pose_b) in zip(poses_a, poses_b):
                np.testing.assert_array_equal(np.concatenate(pose_a), np.concatenate(pose_b))
    if python.capture is not None:
        assert [t for _, _, t in python.capture.frames] == [t for _, _, t in compiled.capture.frames]
        for (_, a, _), (_, b, _) in zip(python.capture.frames, compiled.capture.frames):
            np.testing.assert_array_equal(a, b)


# -- the built-in scenarios whose parts all have a compiled form ----------------------------------------------

@pytest.mark.parametrize("name", ["one_dof_step", "one_dof_velocity_sine"])
def test_a_built_in_scenario_gives_the_same_run_on_both_paths(name, tmp_path):
    python, compiled = both_paths(name, tmp_path)
    assert_same(python, compiled)
    assert len(compiled.trace.time_s) == round(load_scenario(name).duration_s / 0.001)


@pytest.mark.slow
def test_the_dropped_weight_gives_the_same_run_on_both_paths(tmp_path):
    """one_dof_drop_weight: the weight spawned at its time (in Python, between two stretches), its contact with
    the disk, the force sensor, and run.mcap's samples of the weight's pose."""
    python, compiled = both_paths("one_dof_drop_weight", tmp_path, video_fps=15.0, mcap=True)
    assert_same(python, compiled)
    assert len(compiled.poses) > 100
    assert compiled.trace["ft_sensor.force_z"][-1] < -40.0  # the 10 kg weight rests on the disk at 5 m/s²


def test_one_dof_sine_with_its_expression_gives_the_same_run_on_both_paths(tmp_path):
    """The expression is evaluated in Python a stretch ahead, a message at a time: the same messages, the same
    hold left behind."""
    python, compiled = both_paths("one_dof_sine", tmp_path)
    assert_same(python, compiled)
    source = compiled.session.sources["joint1_position_controller"]
    assert source._hold.k == 399  # the last message of 4 s at 100 Hz, as the Python loop leaves it


def test_an_expression_failing_mid_run_holds_its_last_value_alike_on_both_paths(write_scenario, tmp_path):
    """``log(1.5-t)`` leaves its domain at 1.5 s: each later message is rejected and the last good value holds."""
    path = write_scenario(step_scenario(duration_s=2.5, commands={
        "joint1_position_controller": {"type": "expression", "expression": "-0.3+0.1*log(1.5-t)", "rate_hz": 50}}))
    python, compiled = both_paths(path, tmp_path)
    assert_same(python, compiled)
    a, b = (run.session.sources["joint1_position_controller"] for run in (python, compiled))
    assert a.rejected_samples == b.rejected_samples == 50  # 1.5 s to 2.5 s at 50 Hz, 2.48 s the last
    assert a.last_error == b.last_error is not None


def test_an_expression_with_no_value_to_hold_fails_the_run_at_the_same_cycle(write_scenario, tmp_path):
    """``log(1.5-t)`` leaves its domain at 1.5 s; reset there, the source has no value to hold: the next run
    raises at its first cycle on both paths, the source's error counted once."""
    path = write_scenario(step_scenario(duration_s=2.0, commands={
        "joint1_position_controller": {"type": "expression", "expression": "-0.3+0.1*log(1.5-t)"}}))
    for loop in ("python", "auto"):
        session = Session(load_scenario(path, [f"loop={loop}"]))
        session.run(1.6)
        source = session.sources["joint1_position_controller"]
        source.reset()
        with pytest.raises(ExpressionError, match="i=160, t=1.6 s: math domain error"):
            session.run(0.1)
        assert session.loop.cycle == 1600 and source.rejected_samples == 1
        assert session.loop.mode == ("python" if loop == "python" else "compiled")


# -- each law's variants ----------------------------------------------------------------------------------------

POSITION = "controllers.joint1_position_controller"


@pytest.mark.parametrize("overrides", [
    [f"{POSITION}.pid={{p: 400.0, i: 0.0, d: 20.0}}"],  # derivative on the error's difference: the kick
    [f"{POSITION}.pid={{p: 400.0, i: 0.0, d: 20.0}}", f"{POSITION}.derivative=measurement"],
    [f"{POSITION}.pid={{p: 300.0, i: 2000.0, d: 5.0, i_clamp: 3.0}}"],  # the integral saturates at its clamp
    [f"{POSITION}.pid={{p: 300.0, i: 2000.0, d: 5.0, i_clamp: 3.0, antiwindup: true}}"],
    [f"{POSITION}.pid={{p: 400.0, i: 0.0, d: 20.0}}", f"{POSITION}.feedforward={{damping: true}}",
     "commands.joint1_position_controller={type: step, from: -0.2, to: -0.5, at: 0.1, ramp_s: 0.05}"],
    ["commands.joint1_position_controller={type: constant, value: -0.35}", "record={every: 7}"],
    ["commands.joint1_position_controller={type: sine, amplitude: 0.2, frequency_hz: 2.0, offset: -0.5, "
     "rate_hz: 250}", "gravity=-3.0"],
    ["commands.joint1_position_controller={type: chirp, amplitude: 0.05, f_start_hz: 0.5, f_end_hz: 8.0, "
     "duration_s: 0.4, offset: -0.3, at: 0.1}"],
    ["commands.joint1_position_controller={type: expression, expression: '-0.3+0.05*sin(t*20)+0.001*i', "
     "rate_hz: 333}"],
], ids=["d on error", "d on measurement", "i clamp", "antiwindup", "damping feed-forward, ramp", "every 7",
        "sine", "chirp", "expression at 333 Hz"])
def test_the_position_controller_and_the_sources_give_the_same_run(overrides, write_scenario, tmp_path):
    path = write_scenario(step_scenario(duration_s=0.6))
    assert_same(*both_paths(path, tmp_path, overrides))


def test_the_velocity_watchdog_times_a_silent_reference_out_alike(write_scenario, tmp_path):
    """A reference given at the edge door (no source) holds for ``command_timeout_s`` (0.1 s) from the cycle
    that first sees it, then zero velocity; a new one (given between two runs, not yet seen when the second run
    is packed) holds again from its first cycle. The same on both paths, alternating between them too."""
    velocity = "joint1_velocity_controller"
    path = write_scenario(step_scenario(
        controller_file="velocity", start_controllers=["joint_state_controller", velocity], commands={},
        gravity=0.0, initial_positions={"joint1": -0.3}, duration_s=0.6,
        controllers={velocity: {"command_timeout_s": 0.1}}))

    def given(session):
        controller = session.manager.controller(velocity)
        controller.set_reference(0.05)
        session.run(0.3)
        assert controller.timed_out
        controller.set_reference(-0.05)

    python = run_on(path, "python", tmp_path / "python", ["duration_s=0.3"], before=given)
    compiled = run_on(path, "auto", tmp_path / "compiled", ["duration_s=0.3"], before=given)
    assert compiled.session.loop.mode == "compiled"
    assert_same(python, compiled)
    reference = compiled.trace["joint1.reference"]
    expected = np.zeros(600)
    for first, value in ((0, 0.05), (300, -0.05)):  # held while its age (loop times k·period) is <= 0.1 s
        held = [k for k in range(first, first + 300) if k * 0.001 - first * 0.001 <= 0.1]
        assert 100 <= len(held) <= 101
        expected[held] = value
    np.testing.assert_array_equal(reference, expected)


def test_a_continuous_joint_wraps_its_error_alike(tmp_path):
    overrides = ["commands={joint1_position_controller: {type: step, from: -3.0, to: 3.0, at: 0.05}}",
                 "duration_s=2.0", "initial_positions={joint1: -3.0}", "gravity=0.0"]
    python, compiled = both_paths(load_scenario("minimal_robot_trajectory").source, tmp_path,
                                  [*overrides, "goals=[]", "start_controllers=[joint_state_controller, "
                                                           "joint1_position_controller]"])
    assert_same(python, compiled)
    # 3 rad from -3 rad is 0.28 rad backwards: p·(-0.28) N·m, not p·6 N·m forwards
    assert (compiled.trace.joint("joint1", "effort")[100:] < 0).all()


def test_seven_velocity_loops_with_a_force_sensor_and_a_video_give_the_same_run(write_scenario, tmp_path):
    names = [f"joint{k}_velocity_controller" for k in range(7)]
    scenario = {
        "name": "arm_velocities", "robot": "arm7dof", "controller_file": "velocity", "gravity": 0.0,
        "start_controllers": ["joint_state_controller", *names], "duration_s": 0.5, "record": {"every": 3},
        "initial_positions": {"joint1": 1.0, "joint3": -2.0, "joint5": 1.0},
        "commands": {**{n: {"type": "sine", "amplitude": 0.03 / (1 + k) if k % 2 else 0.15, "frequency_hz": 1.0 + k,
                            "rate_hz": 500, "derivative": k % 2 == 1} for k, n in enumerate(names[:6])},
                     names[6]: {"type": "step", "from": 0.0, "to": 0.15, "at": 0.2}},  # within ±0.2 rad/s
    }
    python, compiled = both_paths(write_scenario(scenario), tmp_path, video_fps=30.0)
    assert_same(python, compiled)
    assert np.abs(compiled.trace["ft_sensor.torque_z"]).max() > 0  # the plate's inertia loads the sensor
    assert len(compiled.capture.frames) == 15


# -- the natural admittance controllers, chained in front of velocity controllers ---------------------------------

NAC = "controllers.joint1_admittance_controller"


@pytest.mark.slow
@pytest.mark.parametrize("overrides", [
    [],
    [f"{NAC}.joint_state_rate_hz=50", f"{NAC}.force_rate_hz=1000"],  # the chapter's node: joint states held
    [f"{NAC}.joint_state_rate_hz=50", f"{NAC}.force_rate_hz=50"],    # every signal held at 50 Hz
], ids=["every cycle", "book node", "all at 50 Hz"])
def test_the_one_dof_admittance_drop_gives_the_same_run_on_both_paths(overrides, tmp_path):
    """one_dof_nac_drop: the admittance controller's kernel (with its sample-and-hold) writes the chained velocity
    controller's reference before that controller's kernel reads it, as the manager orders them in Python."""
    python, compiled = both_paths("one_dof_nac_drop", tmp_path, ["duration_s=3.0", *overrides])
    assert_same(python, compiled)
    nac = compiled.session.manager.controller("joint1_admittance_controller")
    assert compiled.session.manager.references[nac.index] == nac.velocity_reference  # the chain's hand-over
    assert compiled.trace["ft_sensor.force_z"][-1] < -40.0  # the 10 kg weight rests on the disk


ARM_NAC = "controllers.arm7dof_nac_controller"


@pytest.mark.parametrize("overrides", [
    [],
    [f"{ARM_NAC}.wrist_joints=[]"],  # H diagonal, every joint integrated
    [f"{ARM_NAC}.tare=false"],
    [f"{ARM_NAC}.tare_time_s=0", f"{ARM_NAC}.wrist_joints=[6, 4]", f"{ARM_NAC}.max_velocity=0.05"],
], ids=["chapter", "no wrist", "no tare", "two wrist joints, clamped"])
def test_the_cartesian_admittance_gives_the_same_run_on_both_paths(overrides, tmp_path):
    """arm7dof_nac_catch's first second: the tare window, then the flange pulled to the attractor (the wrist
    holding its orientation) through seven chained velocity controllers."""
    python, compiled = both_paths("arm7dof_nac_catch", tmp_path, ["duration_s=1.0", *overrides])
    assert_same(python, compiled)
    nac = compiled.session.manager.controller("arm7dof_nac_controller")
    assert np.abs(nac.velocity_command).max() > 1e-3  # the admittance moves the arm


@pytest.mark.slow
@pytest.mark.parametrize("overrides", [[], [f"{ARM_NAC}.wrist_joints=[]"]], ids=["chapter wrist", "no wrist"])
def test_the_cartesian_admittance_with_the_models_inertia_gives_the_same_run_on_both_paths(overrides, tmp_path):
    """use_model_inertia: M(q) from mj_fullM every cycle, Tᵀ·M·T with the wrist, the Cholesky solve: the kernel
    repeats the Python's float operations."""
    python, compiled = both_paths("arm7dof_nac_catch", tmp_path,
                                  ["duration_s=1.0", f"{ARM_NAC}.use_model_inertia=true", *overrides])
    assert_same(python, compiled)
    nac = compiled.session.manager.controller("arm7dof_nac_controller")
    assert nac.use_model_inertia and np.abs(nac.velocity_command).max() > 1e-3  # the admittance moves the arm


@pytest.mark.slow
def test_the_arm_catches_the_weight_alike_on_both_paths(tmp_path):
    """arm7dof_nac_catch up to 2 s after the drop at 10 s (the weight lands at 11.1 s)."""
    python, compiled = both_paths("arm7dof_nac_catch", tmp_path, ["duration_s=12.0"])
    assert_same(python, compiled)
    assert compiled.trace["ft_sensor.force_z"].min() < -20.0  # the weight's impact on the plate


def test_the_cartesian_admittance_may_alternate_between_the_paths(tmp_path):
    """The Cartesian controller's state (integrated velocities, tare sums, Jacobians, orientation error...) goes
    into a compiled run and comes back out: a run split at cycles inside and after the tare window, on alternating
    paths, is the run on one path."""
    def alternate(session):
        compiler = session.loop.compiler
        for k, part in enumerate((0.05, 0.1003, 0.001, 0.2, 0.3, 0.1)):
            session.loop.compiler = compiler if k % 2 else None
            session.run(part)

    python = run_on("arm7dof_nac_catch", "python", tmp_path / "python", ["duration_s=0.8"])
    mixed = run_on("arm7dof_nac_catch", "auto", tmp_path / "mixed", ["duration_s=0.0487"], before=alternate)
    assert mixed.session.loop.mode == "compiled"
    assert_same(python, mixed)


# -- events at the same cycles ---------------------------------------------------------------------------------

def test_a_non_finite_command_fails_its_controller_at_the_same_cycle_and_the_run_goes_on(write_scenario, tmp_path):
    """p·e overflows to +inf while d·ė overflows to -inf on the second cycle: inf - inf is not a number."""
    scenario = {"name": "overflow", "robot": "one_dof", "controller_file": "velocity", "gravity": 0.0,
                "start_controllers": ["joint_state_controller", "joint1_velocity_controller"],
                "controllers": {"joint1_velocity_controller": {"pid": {"p": 1e308, "i": 0.0, "d": 1e308}}},
                "initial_positions": {"joint1": -0.5}, "duration_s": 0.05,
                "commands": {"joint1_velocity_controller": {"type": "constant", "value": 5.0}}}
    python, compiled = both_paths(write_scenario(scenario), tmp_path)
    assert_same(python, compiled)
    failure, = compiled.session.manager.failures
    assert failure.time_s == pytest.approx(0.001) and "non-finite command nan" in failure.reason
    assert compiled.session.loop.cycle == 50


@pytest.mark.parametrize("overrides", [[], [f"{ARM_NAC}.wrist_joints=[]"]], ids=["chapter wrist", "no wrist"])
def test_a_model_inertia_not_positive_definite_fails_the_cartesian_chain_at_the_same_cycle(overrides, tmp_path):
    """A negative armature on the controller's own model (not the simulated one) makes M(q) indefinite: the Python
    update raises LinAlgError at the first cycle after the tare window (0.2 s) and the manager fails the chain; the
    kernel cannot make that update and hands the cycle to Python from it, where it raises alike. The same failure,
    cycle, controllers stopped, trace and state."""
    def spoil(session):
        session.manager.controller("arm7dof_nac_controller").dynamics._model.dof_armature[:] = -100.0

    python, compiled = both_paths("arm7dof_nac_catch", tmp_path,
                                  ["duration_s=0.3", f"{ARM_NAC}.use_model_inertia=true", *overrides], before=spoil)
    (p,), (c,) = python.session.manager.failures, compiled.session.manager.failures
    assert (p.controller, p.time_s) == ("arm7dof_nac_controller", 0.2) and "LinAlgError" in p.reason
    assert (c.controller, c.time_s, c.reason, c.chain, c.joints) == (p.controller, p.time_s, p.reason, p.chain,
                                                                      p.joints)
    assert len(p.chain) == 8
    assert [x.name for x in python.session.manager.active] == [x.name for x in compiled.session.manager.active]
    assert python.session.loop.cycle == compiled.session.loop.cycle == 300
    assert_same(python, compiled)


def test_a_physics_warning_ends_the_run_at_the_same_cycle(write_scenario, tmp_path):
    def diverge(session):
        session.run(0.01)
        session.world.data.qvel[0] = 1e300  # what a diverging loop ends in

    python, compiled = both_paths(write_scenario(step_scenario(duration_s=0.2)), tmp_path, before=diverge)
    assert isinstance(compiled.error, PhysicsError) and compiled.error.field == "mjWARN_BADQVEL"
    assert_same(python, compiled)
    assert compiled.session.loop.cycle == 99  # the counts are read after every 100th step: cycle 99 raised


def test_runs_may_alternate_between_the_paths_at_cycle_boundaries(write_scenario, tmp_path):
    """Python's state goes into the compiled run and comes back out: a run split into parts on alternating paths
    is the run on one path."""
    path = write_scenario(step_scenario(duration_s=0.6, controllers={
        "joint1_position_controller": {"pid": {"p": 300.0, "i": 500.0, "d": 10.0, "i_clamp": 5.0}}}))

    def alternate(session):
        compiler = session.loop.compiler
        for k, part in enumerate((0.05, 0.1333, 0.001, 0.2)):
            session.loop.compiler = compiler if k % 2 else None
            session.run(part)

    python = run_on(path, "python", tmp_path / "python", ["duration_s=0.6"])
    mixed = run_on(path, "auto", tmp_path / "mixed", ["duration_s=0.2157"], before=alternate)
    assert mixed.session.loop.mode == "compiled"
    assert_same(python, mixed)


def test_a_stop_request_ends_a_compiled_run_after_its_stretch(write_scenario):
    from jointctl.compiled.run import STRETCH_CYCLES

    session = Session(load_scenario(write_scenario(step_scenario())))
    original = session.loop.compiler

    def compile_and_ask_to_stop(loop):
        run = original(loop)
        loop.request_stop()  # before the first stretch: the run ends at once
        return run

    session.loop.compiler = compile_and_ask_to_stop
    assert session.loop.run() == 0 and session.loop.mode == "compiled"
    session.loop.compiler = original
    assert session.loop.run(cycles=STRETCH_CYCLES + 7) == STRETCH_CYCLES + 7


# -- the model feed-forward --------------------------------------------------------------------------------------

@pytest.mark.parametrize("terms", ["{gravity: true}", "{gravity: true, damping: true, inertia: true}"])
def test_the_model_feed_forward_gives_the_same_run(terms, write_scenario, tmp_path):
    """Seven position controllers adding g(q) (and M(q)·q̈_ref, 0 for plain commands, and b·q̇_ref) from the
    robot model: the manager's feed-forward update runs compiled before its first user."""
    names = [f"joint{k}_position_controller" for k in range(7)]
    scenario = {
        "name": "arm_positions", "robot": "arm7dof", "controller_file": "position", "gravity": -9.81,
        "start_controllers": ["joint_state_controller", *names], "duration_s": 0.4, "record": {"every": 2},
        "initial_positions": {"joint1": 0.5, "joint3": -1.0},
        "controllers": {n: {"feedforward": yaml.safe_load(terms)} for n in names},
        "commands": {names[1]: {"type": "step", "from": 0.5, "to": 0.7, "at": 0.1, "ramp_s": 0.1},
                     names[3]: {"type": "sine", "amplitude": 0.1, "frequency_hz": 2.0, "offset": -1.0,
                                "rate_hz": 1000}},
    }
    python, compiled = both_paths(write_scenario(scenario), tmp_path)
    assert_same(python, compiled)
    ff_p, ff_c = python.session.manager.context.feedforward, compiled.session.manager.context.feedforward
    assert ff_p.gravity == ff_c.gravity and ff_p.inertia == ff_c.inertia
    # gravity holds the arm: joint1's g(q) at 0.7 rad is tens of N·m, and its command carries it
    assert abs(ff_c.gravity[1]) > 10.0


def test_the_one_dof_trajectory_robot_holds_with_its_gravity_feed_forward(tmp_path):
    """one_dof_trajectory's position controller (gravity, damping and inertia feed-forward), held by a plain
    command (no executor, no goal)."""
    overrides = ["goals=[]", "duration_s=0.5",
                 "start_controllers=[joint_state_controller, joint1_position_controller]",
                 "commands={joint1_position_controller: {type: step, from: -0.5, to: -0.3, at: 0.1}}"]
    python, compiled = both_paths("one_dof_trajectory", tmp_path, overrides)
    assert_same(python, compiled)
    assert compiled.session.manager.controller("joint1_position_controller")._gravity


# -- the trajectory executor ---------------------------------------------------------------------------------------

def goal_outcomes(run: Run) -> list[tuple]:
    """Each scenario goal's status, error code and the cycle it ended at."""
    return [(g.status, g.result.error_code if g.result else None,
             round(g.result.time_s / 0.001) if g.result else None) for g in run.session.goals]


SUCCEEDED, ACTIVE = GoalStatus.SUCCEEDED, GoalStatus.ACTIVE
LINEAR_STREAM = "{interpolation: linear, stream_rate_hz: %d, velocity_feedforward: false}"


@pytest.mark.slow
@pytest.mark.parametrize(("name", "overrides", "statuses"), [
    ("one_dof_trajectory", [], [SUCCEEDED]),
    ("one_dof_trajectory", [f"controllers.joint1_trajectory_controller={LINEAR_STREAM % 100}",
                            "controllers.joint1_position_controller.feedforward={gravity: false, damping: false, "
                            "inertia: false}"], [SUCCEEDED]),
    ("minimal_robot_trajectory", [], [SUCCEEDED]),
    ("arm7dof_pose", ["duration_s=14.5"], [SUCCEEDED]),
    ("arm7dof_pose", ["duration_s=6.0", f"controllers.arm7dof_trajectory_controller={LINEAR_STREAM % 50}"],
     [ACTIVE]),
    ("arm7dof_streamer", ["duration_s=3.0"], []),
], ids=["one_dof default", "one_dof chapter mode", "minimal robot", "arm pose", "arm pose streamed", "streamer"])
def test_a_trajectory_scenario_gives_the_same_run_and_goal_results(name, overrides, statuses, tmp_path):
    """The chapter's trajectory scenarios (cubic at the loop rate with the model feed-forward; linear streamed at
    100 or 50 Hz without): the same trace, the same goal results at the same cycles."""
    python, compiled = both_paths(name, tmp_path, overrides)
    assert_same(python, compiled)
    assert goal_outcomes(python) == goal_outcomes(compiled)
    assert [status for status, _, _ in goal_outcomes(compiled)] == statuses


@pytest.mark.slow
def test_a_trajectory_scenario_gives_the_same_metrics(tmp_path):
    """minimal_robot_trajectory's analysis (its theory against the run) reads the same numbers on both paths."""
    from jointctl.scenario.run import run_scenario

    metrics = {loop: run_scenario(load_scenario("minimal_robot_trajectory", [f"loop={loop}"]), tmp_path / loop,
                                  mcap=False) for loop in ("python", "auto")}
    assert metrics["auto"].pop("loop") == "compiled" and metrics["python"].pop("loop") == "python"
    for m in metrics.values():
        m.pop("real_time_factor"), m.pop("loop_reason", None)
    assert metrics["python"] == metrics["auto"]


def test_a_goal_ends_at_its_end_on_both_paths_and_feedback_is_kept(write_scenario, tmp_path):
    """A short cubic goal with a goal tolerance: it succeeds at the first cycle at or after its end where the
    joint is within the tolerance and at rest, at the same cycle on both paths; a second goal arrives mid-run
    (between two cycles' times) and succeeds too."""
    scenario = {
        "name": "two_goals", "robot": "one_dof", "controller_file": "trajectory", "gravity": -9.81,
        "start_controllers": ["joint_state_controller", "joint1_position_controller",
                              "joint1_trajectory_controller"],
        "controllers": {"joint1_trajectory_controller": {"goal_tolerance": 0.01, "goal_time_s": 1.0}},
        "initial_positions": {"joint1": -0.5}, "duration_s": 2.5,
        "goals": [{"controller": "joint1_trajectory_controller", "at_s": 0.2,
                   "trajectory": {"joint_names": ["joint1"], "points": [
                       {"positions": [-0.4], "time_from_start": 0.3}, {"positions": [-0.3], "time_from_start": 0.6}]}},
                  {"controller": "joint1_trajectory_controller", "at_s": 1.5033,
                   "trajectory": {"joint_names": ["joint1"], "points": [
                       {"positions": [-0.6], "time_from_start": 0.5}]}}],
    }
    python, compiled = both_paths(write_scenario(scenario), tmp_path)
    assert_same(python, compiled)
    outcomes = goal_outcomes(compiled)
    assert outcomes == goal_outcomes(python)
    assert [status for status, _, _ in outcomes] == [GoalStatus.SUCCEEDED, GoalStatus.SUCCEEDED]
    assert 800 <= outcomes[0][2] < 1800 and outcomes[1][2] >= 2004  # after each goal's end (0.8 s, 2.004 s)
    # feedback every 50 ms of the goal (kept, no callback): the last one within 50 ms of its end
    feedback = compiled.session.manager.controller("joint1_trajectory_controller").latest_feedback
    assert outcomes[1][2] * 0.001 - 0.05 < feedback.time_s <= outcomes[1][2] * 0.001


def test_a_path_tolerance_violation_aborts_the_goal_at_the_same_cycle_on_both_paths(write_scenario, tmp_path):
    """A goal faster than the joint can follow (0.4 rad in 0.1 s under a weak loop) strays beyond a 2 mrad path
    tolerance: aborted PATH_TOLERANCE_VIOLATED at the same cycle, then the stop plan brings the joint to rest."""
    scenario = {
        "name": "stray", "robot": "one_dof", "controller_file": "trajectory", "gravity": -9.81,
        "start_controllers": ["joint_state_controller", "joint1_position_controller",
                              "joint1_trajectory_controller"],
        "controllers": {"joint1_trajectory_controller": {"path_tolerance": 0.002},
                        "joint1_position_controller": {"pid": {"p": 50.0, "i": 0.0, "d": 2.0}}},
        "initial_positions": {"joint1": -0.5}, "duration_s": 1.0,
        "goals": [{"controller": "joint1_trajectory_controller", "at_s": 0.1,
                   "trajectory": {"joint_names": ["joint1"], "points": [
                       {"positions": [-0.1], "time_from_start": 0.1}]}}],
    }
    python, compiled = both_paths(write_scenario(scenario), tmp_path)
    assert_same(python, compiled)
    (status, code, cycle), = goal_outcomes(compiled)
    assert (status, code) == (GoalStatus.ABORTED, TrajectoryErrorCode.PATH_TOLERANCE_VIOLATED)
    assert 100 < cycle < 200  # while the goal runs
    assert goal_outcomes(python) == [(status, code, cycle)]
    executor = compiled.session.manager.controller("joint1_trajectory_controller")
    assert executor._plan.stopping and executor.desired_velocity == [0.0]


def test_a_cancel_stops_the_goal_at_the_same_cycle_on_both_paths(write_scenario, tmp_path):
    """A goal canceled between two runs: the next cycle (in Python on the compiled path) ends it PREEMPTED and
    starts the stop, which the compiled cycles then follow."""
    scenario = {
        "name": "cancel", "robot": "one_dof", "controller_file": "trajectory", "gravity": -9.81,
        "start_controllers": ["joint_state_controller", "joint1_position_controller",
                              "joint1_trajectory_controller"],
        "initial_positions": {"joint1": -0.5}, "duration_s": 0.6,
        "goals": [{"controller": "joint1_trajectory_controller", "at_s": 0.05,
                   "trajectory": {"joint_names": ["joint1"], "points": [
                       {"positions": [-0.1], "time_from_start": 1.0}]}}],
    }

    def cancel_mid_goal(session):
        session.run(0.3)
        session.goals[0].cancel()

    python, compiled = both_paths(write_scenario(scenario), tmp_path, before=cancel_mid_goal)
    assert_same(python, compiled)
    assert goal_outcomes(compiled) == [(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL, 300)]
    assert compiled.session.manager.controller("joint1_trajectory_controller").desired_velocity == [0.0]


def test_the_plan_kernel_samples_as_the_plan_does():
    """Linear, cubic (spline) and quintic pieces, a partial goal's stop part, before, inside, at and after the
    knots: the same bits as Interpolant.sample."""
    from jointctl.trajectory.executor_kernel import ExecutorArrays, plan_sample
    from jointctl.trajectory.interpolation import build_interpolant

    times = np.array([0.0, 0.13, 0.5, 0.77, 1.2])
    positions = np.array([[0.0, 1.0], [0.3, 0.8], [0.1, 0.4], [0.2, 0.9], [0.25, 0.5]])
    velocities = np.array([[0.0, 0.1], [0.5, -0.8], [0.1, 0.3], [-0.2, 0.4], [0.0, 0.0]])
    accelerations = velocities * 3.0
    for interp in (build_interpolant(times, positions, kind="linear"),
                   build_interpolant(times, positions, kind="spline", start_velocity=[0.1, -0.2]),
                   build_interpolant(times, positions, velocities, accelerations, kind="quintic")):
        arrays = ExecutorArrays.__new__(ExecutorArrays)
        plan = type("P", (), {"parts": [(interp, np.array([1, 0]))]})()
        arrays._pack_plan(plan, 2)
        ts = np.concatenate(([-0.1, 1.2, 1.3], times, 0.001 * np.arange(1250)))
        for t in ts:
            q, v, a = interp.sample(t)
            for column, j in ((0, 1), (1, 0)):
                got = plan_sample(arrays.times, arrays.knots, arrays.order, arrays.coefficients, arrays.ends, j, t)
                assert got == (q[column], v[column], a[column]), (interp.kind, t)


def test_a_goal_with_a_feedback_callback_takes_the_run_on_in_python(write_scenario, tmp_path):
    """Feedback given to a callback is delivered in the loop's cycle: the compiled run takes the goal, then hands
    the rest of the run to the Python loop; the callback sees the same feedback at the same times."""
    from jointctl.trajectory.messages import JointTrajectory

    seen = {}

    def submit_with_a_callback(session):
        session.run(0.1)
        executor = session.manager.controller("joint1_trajectory_controller")
        seen[session.loop.compiler is not None] = received = []
        trajectory = JointTrajectory.from_dict({"joint_names": ["joint1"],
                                                "points": [{"positions": [-0.3], "time_from_start": 0.3}]})
        executor.submit(trajectory, on_feedback=received.append)

    overrides = ["goals=[]", "duration_s=0.5"]
    python = run_on("one_dof_trajectory", "python", tmp_path / "python", overrides, before=submit_with_a_callback)
    compiled = run_on("one_dof_trajectory", "auto", tmp_path / "compiled", overrides, before=submit_with_a_callback)
    assert compiled.session.loop.mode == "python" and "callback" in compiled.session.loop.mode_reason
    assert_same(python, compiled)
    assert seen[True] == seen[False] and len(seen[True]) >= 6  # every 50 ms from 0.1 s to the goal's end (0.4 s)


def test_a_partial_goal_and_a_stream_with_its_watchdog_give_the_same_run(tmp_path):
    """On the arm: a goal naming two joints (the others brought to rest by the plan's stop part), then streamed
    references replacing it (PREEMPTED), held with velocity zeroed when the stream stops (the watchdog, 0.5 s)."""
    from jointctl.trajectory.messages import JointTrajectory

    def partial_goal_then_stream(session):
        session.run(0.05)
        executor = session.manager.controller("arm7dof_trajectory_controller")
        trajectory = JointTrajectory.from_dict({"joint_names": ["joint3", "joint1"], "points": [
            {"positions": [-0.08, 0.08], "velocities": [-0.1, 0.1], "time_from_start": 0.5},
            {"positions": [-0.15, 0.15], "velocities": [0.0, 0.0], "time_from_start": 1.0}]})
        session.goals.append(executor.submit(trajectory))
        session.run(0.6)
        desired = executor.desired
        executor.stream_reference(desired, [0.0, 0.05, 0.0, 0.0, 0.0, 0.0, 0.0])

    python, compiled = both_paths("arm7dof_streamer", tmp_path, ["duration_s=0.8", "record.every=1"],
                                  before=partial_goal_then_stream)
    assert_same(python, compiled)
    assert goal_outcomes(compiled) == [(GoalStatus.PREEMPTED, TrajectoryErrorCode.SUCCESSFUL, 650)]
    reference = compiled.trace.joint("joint1", "reference")  # the position reference in use
    executor = compiled.session.manager.controller("arm7dof_trajectory_controller")
    assert executor._stream_deadline_s == math.inf and executor.desired_velocity[1] == 0.0  # the watchdog fired
    assert np.ptp(reference[651:]) == 0.0 and 0.0 < reference[651] < 0.15  # held where the stream put it

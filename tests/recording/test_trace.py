"""The trace recorder: columns, decimation, spooling, faithful CSV."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from jointctl.recording.trace import TraceRecorder, load_trace, trace_columns
from tests.conftest import step_scenario


def test_columns_group_by_quantity_then_sensor_axes():
    assert trace_columns(["a", "b"], ["ft"]) == [
        "time_s", "a.reference", "b.reference", "a.position", "b.position", "a.velocity",
        "b.velocity", "a.effort", "b.effort", "ft.force_x", "ft.force_y", "ft.force_z",
        "ft.torque_x", "ft.torque_y", "ft.torque_z",
    ]


def test_trace_matches_the_hardware_state_of_each_cycle(write_scenario, tmp_path):
    session = Session(load_scenario(write_scenario(step_scenario(duration_s=0.15))), out_dir=tmp_path)
    seen = []
    session.loop.add_observer(lambda t: seen.append((t, session.hardware.position[0],
                                                      session.hardware.effort[0])))
    session.run()
    session.close()
    trace = load_trace(tmp_path / "trace.csv")
    assert len(trace.time_s) == 150
    np.testing.assert_allclose(trace.time_s, [s[0] for s in seen], rtol=0, atol=1e-12)
    np.testing.assert_allclose(trace.joint("joint1", "position"), [s[1] for s in seen], rtol=1e-9)
    np.testing.assert_allclose(trace.joint("joint1", "effort"), [s[2] for s in seen], rtol=1e-9, atol=1e-9)
    command = trace.joint("joint1", "reference")
    assert command[0] == -0.2 and command[-1] == -0.5  # the step at 0.1 s


def test_decimation_keeps_one_cycle_in_every(write_scenario, tmp_path):
    scenario = load_scenario(write_scenario(step_scenario(duration_s=0.1, record={"every": 10})))
    with Session(scenario, out_dir=tmp_path) as session:
        session.run()
    trace = load_trace(tmp_path / "trace.csv")
    np.testing.assert_allclose(trace.time_s, np.arange(10) * 0.01, atol=1e-12)


def test_rows_spool_to_disk_in_chunks_and_the_spool_is_removed(write_scenario, tmp_path):
    scenario = load_scenario(write_scenario(step_scenario(duration_s=0.1, loop="python")))
    session = Session(scenario)
    recorder = TraceRecorder(tmp_path / "trace.csv", session.hardware,
                             session.manager.references, chunk_rows=16)
    session.loop.add_observer(recorder)
    session.run()
    assert recorder.rows_written == 96  # six full chunks of 16 went to disk during the run
    assert len(recorder._rows) == 4
    recorder.close()
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())
    assert len(load_trace(tmp_path / "trace.csv").time_s) == 100


def test_a_compiled_run_spools_its_rows_at_the_end_of_each_stretch(write_scenario, tmp_path):
    scenario = load_scenario(write_scenario(step_scenario(duration_s=0.1)))
    session = Session(scenario)
    recorder = TraceRecorder(tmp_path / "trace.csv", session.hardware,
                             session.manager.references, chunk_rows=16)
    session.loop.add_observer(recorder)
    compiler, session.loop.compiler = session.loop.compiler, None
    session.loop.run(cycles=3)  # in Python: three rows in memory
    assert session.loop.mode == "python" and len(recorder._rows) == 3
    session.loop.compiler = compiler
    session.run(0.097)
    assert session.loop.mode == "compiled"
    assert recorder.rows_written == 100 and not recorder._rows  # the stretch's rows follow the three
    recorder.close()
    trace = load_trace(tmp_path / "trace.csv")
    np.testing.assert_allclose(trace.time_s, np.arange(100) * 0.001, rtol=0, atol=1e-12)


def test_every_must_be_positive(write_scenario, tmp_path):
    session = Session(load_scenario(write_scenario(step_scenario())))
    with pytest.raises(ValueError, match="every"):
        TraceRecorder(tmp_path / "t.csv", session.hardware, [float("nan")], every=0)


def test_joint_without_a_controller_records_nan_command(write_scenario, tmp_path):
    session = Session(load_scenario(write_scenario(step_scenario())))
    with TraceRecorder(tmp_path / "t.csv", session.hardware, [float("nan")]) as recorder:
        session.loop.add_observer(recorder)
        session.loop.run(cycles=3)
    assert np.isnan(load_trace(tmp_path / "t.csv").joint("joint1", "reference")).all()


def test_a_trace_kept_in_memory_is_the_files_at_full_precision(write_scenario, tmp_path):
    # The same run twice (simulated time: bit for bit the same), once to trace.csv and once in memory: the file
    # keeps ten significant digits (%.10g), so its numbers are the memory's within half a unit of the tenth digit.
    scenario = load_scenario(write_scenario(step_scenario(duration_s=0.2, record={"every": 3})))
    out = tmp_path / "run"
    with Session(scenario, out_dir=out) as on_disk:
        on_disk.run()
    with Session(scenario, keep_trace=True) as in_memory:
        in_memory.run()
    assert in_memory.trace_path is None and sorted(p.name for p in out.iterdir()) == ["trace.csv"]
    file, memory = load_trace(out / "trace.csv"), in_memory.trace()
    assert list(memory.columns) == list(file.columns) and len(memory.time_s) == len(file.time_s) == 67
    for name, column in file.columns.items():
        np.testing.assert_allclose(column, memory[name], rtol=5e-10, atol=0, err_msg=name)
    assert not np.array_equal(file.joint("joint1", "position"), memory.joint("joint1", "position"))


def test_a_memory_trace_is_there_once_closed():
    session = Session(load_scenario("one_dof_step"), keep_trace=True)
    session.run(0.01)
    with pytest.raises(RuntimeError, match="once the recorder is closed"):
        session.trace()
    session.close()
    assert len(session.trace().time_s) == 10

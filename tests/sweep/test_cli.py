"""``jointctl sweep`` on the command line: its files, and bad input refused in one line before anything runs."""

from __future__ import annotations

import csv
import json

import pytest

from jointctl.cli import main


def test_a_sweep_in_this_process_writes_its_table_summary_and_figures(tmp_path, capsys):
    out = tmp_path / "sweep"
    code = main(["sweep", "one_dof_step", "--vary", "payload_kg=[0, 4]", "--set", "duration_s=1.5",
                 "--spec", "overshoot_pct<=50", "--in-process", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    printed = json.loads(captured.out)
    assert (printed["runs"], printed["passed"], printed["failed"], printed["errors"]) == (2, 1, 1, 0)
    assert printed["worst"]["overshoot_pct"]["values"] == {"payload_kg": 4}
    assert "sweep: 2/2 runs (100 %)" in captured.err and f"wrote {out}/" in captured.err
    with (out / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["payload_kg"] for r in rows] == ["0", "4"] and [r["pass"] for r in rows] == ["true", "false"]
    files = {p.name for p in out.iterdir()}
    assert {"results.csv", "summary.json", "traces.npz", "responses.png", "overshoot_pct_vs_payload_kg.png"} <= files


def test_a_list_without_brackets_gives_the_same_rows(tmp_path, capsys):
    tables = []
    for k, values in enumerate(("0,5", "[0, 5]")):
        out = tmp_path / str(k)
        assert main(["sweep", "one_dof_step", "--vary", f"payload_kg={values}", "--set", "duration_s=1.5",
                     "--in-process", "--no-figures", "--out", str(out)]) == 0, capsys.readouterr().err
        tables.append((out / "results.csv").read_text())
    assert tables[0] == tables[1]
    rows = list(csv.DictReader(tables[0].splitlines()))
    assert [r["payload_kg"] for r in rows] == ["0", "5"] and all(r["error"] == "" for r in rows)


def test_a_small_sweep_runs_in_this_process_and_says_so_in_one_line(tmp_path, capsys):
    # Two runs of 1.5 simulated seconds of the 1-DOF robot: far less than a local cluster's start.
    out = tmp_path / "sweep"
    assert main(["sweep", "one_dof_step", "--vary", "payload_kg=0,5", "--set", "duration_s=1.5", "--no-figures",
                 "--out", str(out)]) == 0
    err = capsys.readouterr().err
    said = [line for line in err.splitlines() if "in this process" in line]
    assert len(said) == 1 and said[0].startswith("jointctl: 2 runs of about ") and "--workers" in said[0], err
    assert "runs on this process" in err


@pytest.mark.parametrize("args, says", [
    (["--vary", "foo=1:2"], "--vary: foo: a grid is a:b:n"),
    (["--vary", "gravty=[1, 2]"], "--vary: gravty: unknown field (did you mean 'gravity'?"),
    (["--vary", "model.joint1.dampin=1:2:2"], "model.joint1.dampin: unknown field (did you mean 'damping'?"),
    (["--vary", "controllers.joint1_position_controller.pid.pp=[1, 2]"], "pid.pp: unknown field (did you mean 'p'?"),
    (["--vary", "controllers.joint1_position_controller.pid.p=[400, -8]"], "pid.p: must not be negative (got -8.0)"),
    (["--vary", "latency_cycles=0:1:3"], "latency_cycles: a grid or list of latencies must be whole numbers"),
    (["--vary", "payload_kg=[-1, 0]"], "payload_kg: must be a mass, 0 or more [kg] (got -1)"),
    (["--vary", "payload_kg=normal(1, 2)"], "--samples: a distribution needs the number of samples"),
    (["--vary", "payload_kg=[0, 1]", "--spec", "overshot_pct<=10"], "--spec: unknown metric (did you mean"),
    (["--vary", "payload_kg=[0, 1]", "--workers", "0"], "--workers: must be a whole number"),
    (["--vary", "payload_kg=[0, 1]", "--seed", "-2"], "--seed: must be a whole number, 0 or more"),
    ([], "nothing to vary"),
])
def test_bad_input_is_one_line_with_exit_status_2_and_nothing_runs(tmp_path, capsys, args, says):
    out = tmp_path / "sweep"
    assert main(["sweep", "one_dof_step", *args, "--in-process", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("jointctl: error: ") and err.count("\n") == 1 and says in err, err
    assert not out.exists()


def test_the_scheduler_and_the_local_workers_do_not_go_together(tmp_path, capsys):
    assert main(["sweep", "one_dof_step", "--vary", "payload_kg=[0]", "--scheduler", "tcp://127.0.0.1:1",
                 "--workers", "2", "--out", str(tmp_path / "x")]) == 2
    assert "--workers" in capsys.readouterr().err

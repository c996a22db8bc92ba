"""Where a sweep runs when no engine is asked for: here when its runs take less than a local cluster saves."""

from __future__ import annotations

import pytest

from jointctl.sweep.sweep import CLUSTER_START_S, runs_here


def test_a_sweep_runs_here_unless_a_cluster_would_save_more_than_its_start():
    # One after the other the runs take T; n workers take at best T/n: the cluster saves T·(1 - 1/n), and costs its
    # start. Here while T·(1 - 1/n) < the start.
    assert runs_here(0.1, 2)
    assert runs_here(1.99 * CLUSTER_START_S, 2) and not runs_here(2.01 * CLUSTER_START_S, 2)
    assert runs_here(1.49 * CLUSTER_START_S, 3) and not runs_here(1.51 * CLUSTER_START_S, 3)
    assert runs_here(1e6, 1)  # one worker never saves anything


@pytest.mark.slow
def test_a_sweep_on_kept_worlds_writes_the_table_of_one_that_builds_every_run(tmp_path):
    # Payloads outer, gains inner: each payload's world is built once and restarted for its other gains; the table
    # (every figure in full) is that of runs built whole, byte for byte, and the loop compiled in every run.
    from jointctl.sweep import run_sweep

    vary = ["payload_kg=[0, 2]", "controllers.joint1_position_controller.pid.p=[300, 500]",
            "initial_positions.joint1=[-0.2, -0.25]"]
    tables = {}
    for reuse in (True, False):
        result = run_sweep("one_dof_step", vary, in_process=True, out_dir=tmp_path / str(reuse), figures=False,
                           overrides=["duration_s=1.2"], reuse=reuse)
        assert len(result.rows) == 8 and not result.errors
        assert all(row.loop == "compiled" for row in result.rows)
        tables[reuse] = (tmp_path / str(reuse) / "results.csv").read_bytes()
    assert tables[True] == tables[False]

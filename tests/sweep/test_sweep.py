"""Where a sweep runs when no engine is asked for: here when its runs take less than a local cluster saves."""

from __future__ import annotations

from jointctl.sweep.sweep import CLUSTER_START_S, runs_here


def test_a_sweep_runs_here_unless_a_cluster_would_save_more_than_its_start():
    # One after the other the runs take T; n workers take at best T/n: the cluster saves T·(1 - 1/n), and costs its
    # start. Here while T·(1 - 1/n) < the start.
    assert runs_here(0.1, 2)
    assert runs_here(1.99 * CLUSTER_START_S, 2) and not runs_here(2.01 * CLUSTER_START_S, 2)
    assert runs_here(1.49 * CLUSTER_START_S, 3) and not runs_here(1.51 * CLUSTER_START_S, 3)
    assert runs_here(1e6, 1)  # one worker never saves anything

"""Tuning without a ruler, in simulation: how many times faster than real time.

*Identify*: ``jointctl identify one_dof --joint joint1`` (a 10 s chirp with 3 s of rest: 13 s of loop
time) and the least-squares fit. *Sweep*: ``jointctl bode`` on the chapter's position loop, 20
log-spaced frequencies from 0.5 to 20 Hz (about 87 s of loop time). *Autotune*: ζ 0.7 at 5 Hz on
the 1-DOF robot, its design and its checks on the robot (a step and a 16-point sweep). Each is
reported as loop time simulated over wall-clock time (the real-time factor); target: the sweep at
>= 50x.
"""

from __future__ import annotations

import math
import time

import numpy as np

from benchmarks.common import Result


def run() -> list[Result]:
    from jointctl.identification.autotune import autotune
    from jointctl.identification.frequency_response import measure
    from jointctl.identification.identify import SETTLE_AFTER_S, SETTLE_S, identify_on_robot
    from jointctl.scenario.spec import scenario_for_robot

    def one_dof(overrides=()):
        return scenario_for_robot("one_dof", "position", list(overrides))

    t0 = time.perf_counter()
    identify_on_robot(one_dof(), "joint1", duration_s=10.0)
    identify_wall = time.perf_counter() - t0
    identify_sim = SETTLE_S + 10.0 + SETTLE_AFTER_S

    frequencies = np.logspace(math.log10(0.5), math.log10(20.0), 20)
    t0 = time.perf_counter()
    _, context = measure(one_dof(), "joint1_position_controller", frequencies)
    sweep_wall = time.perf_counter() - t0
    sweep_factor = context["simulated_s"] / sweep_wall

    t0 = time.perf_counter()
    autotune(one_dof, "joint1_position_controller", bandwidth_hz=5.0, zeta=0.7, step=0.1)
    autotune_wall = time.perf_counter() - t0
    return [
        Result("identify", "identify joint1 (13 s of loop time)", identify_sim / identify_wall, "x real time"),
        Result("identify", "bode sweep, 20 frequencies", sweep_factor, "x real time", ">= 50x", sweep_factor >= 50),
        Result("identify", "bode sweep wall time", sweep_wall, "s"),
        Result("identify", "autotune incl. checks on the robot", autotune_wall, "s"),
    ]


if __name__ == "__main__":
    for row in run():
        print(row)

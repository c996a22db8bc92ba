"""What run.mcap costs a run, on one_dof_step and arm7dof_pose, as ratios measured in the same run.

*Plain*: ``Session(out_dir=...)``, the trace recorder only (trace.csv). *With run.mcap*: the same with
``mcap=True``: during the run only the spawned objects' poses and the events are kept; the per-cycle
messages and TF are made after it from the trace's rows. *In the loop*: the rejected design, for
comparison: every cycle's messages formatted and handed to the Foxglove SDK's MCAP writer by a loop
observer during the run (the live stream's path at the loop's rate).

The loop's real-time factor (``loop.run`` alone) and the end-to-end time (build, run, write the records)
are compared; runs are interleaved so that a busy moment slows every variant alike.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import foxglove
from foxglove.mcap import MCAPWriteOptions

from benchmarks.common import Result
from jointctl.recording.foxglove_messages import RecordFormat, reference_kinds
from jointctl.recording.mcap_record import open_channels
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario

REPEATS = 5
SCENARIOS = (("one_dof_step", ["duration_s=10"]), ("arm7dof_pose", []))


class InLoopMcap:
    """The rejected design: every cycle's per-cycle messages written to an MCAP file from the loop."""

    def __init__(self, session: Session, path: Path) -> None:
        hw, manager = session.hardware, session.manager
        joints = tuple(hw.joint_names)
        self.format = RecordFormat(session.robot, joints, reference_kinds(manager, joints), hw.sensor_names)
        self.context = foxglove.Context()
        self.writer = foxglove.open_mcap(path, allow_overwrite=True, context=self.context,
                                         writer_options=MCAPWriteOptions(compression_threads=0))
        channels = open_channels(self.context, self.format)
        self.channels = [channels[t] for t in self.format.cycle_topics()]
        self.hw, self.references = hw, manager.references
        self.wrenches = tuple(hw.wrenches[s] for s in hw.sensor_names)
        session.loop.add_observer(self)

    def __call__(self, time_s: float) -> None:
        hw = self.hw
        row = [time_s, *self.references, *hw.position, *hw.velocity, *hw.effort]
        for wrench in self.wrenches:
            row += wrench
        ns = round(time_s * 1e9)
        for channel, message in zip(self.channels, self.format.row_messages(row, ns)):
            channel.log(message, log_time=ns)

    def close(self) -> None:
        self.writer.close()


def one_run(scenario, variant: str) -> tuple[float, float]:
    """(loop real-time factor, end-to-end seconds) of one run of ``variant``: plain, mcap or in_loop."""
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        session = Session(scenario, out_dir=out, mcap=variant == "mcap")
        extra = InLoopMcap(session, Path(out) / "in_loop.mcap") if variant == "in_loop" else None
        loop_start = time.perf_counter()
        session.loop.run(scenario.duration_s)
        loop_s = time.perf_counter() - loop_start
        session.close()
        if extra is not None:
            extra.close()
        total = time.perf_counter() - start
    return scenario.duration_s / loop_s, total


def measure(name: str, overrides: list[str]) -> dict[str, tuple[float, float]]:
    scenario = load_scenario(name, overrides)
    runs: dict[str, list[tuple[float, float]]] = {"plain": [], "mcap": [], "in_loop": []}
    for _ in range(REPEATS):
        for variant in runs:
            runs[variant].append(one_run(scenario, variant))
    return {v: (statistics.median(r[0] for r in rs), statistics.median(r[1] for r in rs)) for v, rs in runs.items()}


def rows_of(name: str, overrides: list[str]) -> int:
    """The trace rows of a run of ``name``."""
    scenario = load_scenario(name, overrides)
    return round(scenario.duration_s / scenario.loop_period_s / scenario.record_every)


def run() -> list[Result]:
    rows = []
    for name, overrides in SCENARIOS:
        m = measure(name, overrides)
        (plain_rtf, plain_s), (mcap_rtf, mcap_s), (loop_rtf, loop_s) = m["plain"], m["mcap"], m["in_loop"]
        bench = f"run.mcap {name}"
        rows += [
            Result(bench, "loop real-time factor, trace.csv only", plain_rtf, "x"),
            Result(bench, "loop with run.mcap / without", mcap_rtf / plain_rtf, "ratio", ">= 0.9",
                   mcap_rtf / plain_rtf >= 0.9),
            Result(bench, "loop with every cycle logged to MCAP in the loop / without (rejected)", loop_rtf / plain_rtf,
                   "ratio"),
            Result(bench, "end to end (build, run, records): with run.mcap / without", mcap_s / plain_s, "ratio"),
            Result(bench, "end to end: in-loop MCAP / without", loop_s / plain_s, "ratio"),
            Result(bench, "run.mcap written after the run, per trace row",
                   (mcap_s - plain_s) / rows_of(name, overrides) * 1e6, "us"),
        ]
    return rows


if __name__ == "__main__":
    for r in run():
        print(f"{r.benchmark:28} {r.measure:75} {r.value:.3g} {r.unit} {r.target} {'' if r.ok is None else r.ok}")

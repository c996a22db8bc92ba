"""The demo report's sweep: the chapter's 1-DOF position loop (Kp 400, no Kd) carrying a payload of 0 to 5 kg.

With m = the piston's moving mass + the payload, theory gives ωn = √(Kp/m), ζ = (b + Kd)/(2√(Kp·m)) and the
overshoot exp(-πζ/√(1-ζ²)): a payload slows the loop and takes its damping away. The runs are the scenario without
gravity (its sag at the start would still ring when the step comes, with ζ down to 0.1) and 6 s long (the
final value is read at the end). The section compares each run with theory and judges it against a 60 % overshoot
spec. It runs on a local cluster of two worker processes, or here when worker processes cannot be had.
"""

from __future__ import annotations

import math
from pathlib import Path

from jointctl.errors import JointCtlError
from jointctl.scenario.analyses.common import joint_plant
from jointctl.sweep.engine import Engine
from jointctl.sweep.runner import RunTask, build_session
from jointctl.sweep.sweep import run_sweep

TARGET = "one_dof_step"
VARY = ("payload_kg=0:5:6",)
SETTINGS = ("gravity=0", "duration_s=6")
SPEC = "overshoot_pct<=60"
FOLDER = "sweep_one_dof_step_payload"
WORKERS = 2


def demo_section(out: Path) -> str:
    """Run the sweep into ``out/sweep_one_dof_step_payload`` and return the report's Markdown section."""
    folder = Path(out) / FOLDER
    engine = Engine(workers=WORKERS)
    try:
        engine.start()
    except (JointCtlError, OSError, RuntimeError, TimeoutError):
        engine = Engine(in_process=True)
    with engine:
        result = run_sweep(TARGET, VARY, spec=SPEC, engine=engine, out_dir=folder, overrides=SETTINGS)
    with build_session(RunTask(-1, TARGET, {}, overrides=SETTINGS), None) as session:
        plant = joint_plant(session, "joint1")
    lines = [f"## Sweep: {TARGET} carrying a payload", "",
             f"`jointctl sweep {TARGET} --vary {VARY[0]} {' '.join('--set ' + s for s in SETTINGS)} --spec {SPEC}`: "
             f"{len(result.rows)} runs on {result.engine}, without gravity (the sag at the start would still ring at "
             "the step) for 6 s. The payload is a point mass on the sensor disk; the controller keeps the nominal "
             f"model. Theory with m = {plant.moving_mass_kg:.3g} kg + payload, Kp = {plant.kp:g}, "
             f"b + Kd = {plant.damping + plant.kd:g}: ωn = √(Kp/m), ζ = (b + Kd)/(2√(Kp·m)), overshoot "
             f"exp(-πζ/√(1-ζ²)). All files in [{FOLDER}/]({FOLDER}/) (`results.csv`, `summary.json`).", "",
             "| payload [kg] | ωn [rad/s] | theory | ζ | theory | overshoot [%] | theory | pass |",
             "|---|---|---|---|---|---|---|---|"]
    for row in result.rows:
        payload = row.values["payload_kg"]
        m = plant.moving_mass_kg + payload
        wn = math.sqrt(plant.kp / m)
        zeta = (plant.damping + plant.kd) / (2 * math.sqrt(plant.kp * m))
        overshoot = 100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))
        if row.error is not None:
            lines.append(f"| {payload:g} | {row.error} | {wn:.4g} | | {zeta:.4g} | | {overshoot:.4g} | |")
            continue
        metrics = row.metrics
        lines.append(f"| {payload:g} | {_fmt(metrics.get('natural_frequency_rad_s'))} | {wn:.4g} "
                     f"| {_fmt(metrics.get('damping_ratio'))} | {zeta:.4g} | {_fmt(metrics.get('overshoot_pct'))} "
                     f"| {overshoot:.4g} | {'yes' if row.passed else 'no'} |")
    lines.append("")
    for name in ("responses.png", "overshoot_pct_vs_payload_kg.png"):
        if (folder / name).is_file():
            lines.append(f"![{TARGET} sweep: {Path(name).stem}]({FOLDER}/{name})")
    lines.append("")
    return "\n".join(lines)


def _fmt(value) -> str:
    return "n/a" if value is None else f"{value:.4g}"


__all__ = ["demo_section"]

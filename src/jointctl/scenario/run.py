"""Run a scenario to an output folder: trace.csv, run.mcap, figures, metrics.json; and the demo report."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from jointctl.commands.limits import clamp_warning
from jointctl.scenario.analyses import check_analysis
from jointctl.scenario.session import Session
from jointctl.scenario.spec import Scenario, builtin_scenarios, load_scenario
from jointctl.errors import ConfigError
from jointctl.recording.metrics_file import json_ready, write_metrics
from jointctl.recording.trace import load_trace
from jointctl.visuals.video import FrameCapture, VideoSettings, robot_camera, write_video
from jointctl.visuals.viewer import LiveViewer

#: The demo report's videos: small GIFs only.
DEMO_VIDEO = VideoSettings(fps=15.0, width=320, height=240, mp4=False)


def run_scenario(
    scenario: Scenario,
    out_dir: str | Path,
    *,
    realtime: bool = False,
    speed: float = 1.0,
    package_path: tuple[str, ...] = (),
    video: VideoSettings | None = None,
    view: bool = False,
    mcap: bool = True,
) -> dict[str, Any]:
    """Run ``scenario``, write its outputs into ``out_dir`` and return the metrics. With ``video``,
    the world's states are kept at its frame rate and drawn after the run into ``video.gif`` (and
    ``video.mp4``), from its camera or the robot's (``robot.yaml``: ``video.camera``). With ``view``,
    MuJoCo's viewer shows the run in a window as it goes (paced to the wall clock). With ``mcap`` (the
    default), ``run.mcap`` beside ``trace.csv`` holds the run for Foxglove and PlotJuggler
    (:mod:`jointctl.recording.mcap_record`)."""
    out = Path(out_dir)
    with Session(scenario, out_dir=out, realtime=realtime, speed=speed,
                 package_path=package_path, mcap=mcap) as session:
        analysis = check_analysis(session)
        capture = camera = None
        if video is not None:
            if session.world is None:
                raise ConfigError("videos are drawn from the simulation; this hardware has none", field="--video")
            camera = video.camera or robot_camera(scenario.robot.extras,
                                                  source=str(scenario.robot.folder / "robot.yaml"))
            capture = FrameCapture(session.world, video.fps)
            session.loop.add_observer(capture)
        viewer = None
        if view:
            if session.world is None:
                raise ConfigError("the viewer shows the simulation; this hardware has none", field="--view")
            viewer = LiveViewer(session.world, session.loop)
            session.loop.add_observer(viewer)
        try:
            real_time_factor = session.run()
        finally:
            if viewer is not None:
                viewer.close()
    # A controller that failed was deactivated and the run went on (its trace is written), but
    # its figures would not describe the experiment: the run ends in an error instead.
    session.manager.raise_failures()
    metrics: dict[str, Any] = {"scenario": scenario.name, "duration_s": scenario.duration_s}
    if session.world is not None and session.robot.ros2_control:  # the simulation stood in for ROS 2 hardware
        metrics["stands_in_for"] = [component.stand_in() for component in session.robot.ros2_control]
    if analysis is not None:
        metrics.update(analysis(session, load_trace(session.trace_path), out, scenario.analysis))
    metrics["real_time_factor"] = real_time_factor
    metrics["loop"] = session.loop.mode  # compiled or python, and why python
    if session.loop.mode_reason:
        metrics["loop_reason"] = session.loop.mode_reason
    if capture is not None:
        metrics["video"] = {**write_video(capture.frames, out, video, camera), "frames": len(capture.frames),
                            "fps": video.fps}
    clamped = [w for w in (clamp_warning(c, session.robot, session.loop.period_s) for c in session.manager.loaded())
               if w is not None]
    if clamped:  # references the controllers clamped to their joints' limits as the run went
        metrics["warnings"] = [*metrics.get("warnings", []), *clamped]
    rejected = {n: s.rejected_samples for n, s in session.sources.items() if s.rejected_samples}
    if rejected:
        metrics["rejected_command_samples"] = rejected
    if session.rejected_goals:  # the robot held; the run says why
        metrics["rejected_goals"] = [{"time_s": t, "error": str(exc)} for t, exc in session.rejected_goals]
    metrics = json_ready(metrics)  # NaN and infinities (never settled, never happened) as null
    write_metrics(out, metrics)
    return metrics


def run_demo(out_dir: str | Path, names: Iterable[str] | None = None,
             sections: Iterable[Callable[[Path], str]] = ()) -> Path:
    """Run every built-in experiment (a scenario with an analysis), or ``names``, and write
    ``report.md``; returns its path. ``sections``: more of the report, each a function of the output
    folder returning its Markdown (the edges above this package add theirs, e.g. a sweep)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    parts = []
    scenarios = [load_scenario(name) for name in (names or builtin_scenarios())]
    for scenario in scenarios:
        if names is None and scenario.analysis is None:
            continue  # a robot to drive (arm7dof_streamer), not an experiment
        name = scenario.name
        metrics = run_scenario(scenario, out / name, video=DEMO_VIDEO)
        parts.append(_report_section(scenario, metrics, out / name, out))
    parts += [section(out) for section in sections]
    report = out / "report.md"
    report.write_text(
        "# jointctl demo report\n\n"
        "Each experiment ran in-process on MuJoCo at the scenario's loop rate; figures and\n"
        "`metrics.json` are in the experiment's folder. *Expected* values come from the model\n"
        "(moving mass, joint damping, controller gains, gravity) and textbook formulas.\n\n"
        + "\n".join(parts)
    )
    return report


def _report_section(scenario: Scenario, metrics: dict[str, Any], folder: Path, root: Path) -> str:
    lines = [f"## {scenario.name}", ""]
    if scenario.description:
        lines += [scenario.description, ""]
    if "loop" in metrics:  # which loop ran it: compiled, or python and why
        reason = metrics.get("loop_reason")
        lines += [f"Loop: {metrics['loop']}" + (f" ({reason})" if reason else "") + ".", ""]
    expected = metrics.get("expected", {})
    lines += ["| metric | measured | expected | difference |", "|---|---|---|---|"]
    for key, value in metrics.items():
        if key in ("expected", "plant", "scenario", "video") or not isinstance(value, (int, float)):
            continue
        exp = expected.get(key)
        if exp is None:
            lines.append(f"| {key} | {_fmt(value)} | | |")
        else:
            lines.append(f"| {key} | {_fmt(value)} | {_fmt(exp)} | {_difference(value, exp)} |")
    lines.append("")
    gif = folder / "video.gif"
    if gif.is_file():
        lines += [f"![{scenario.name}: the run]({gif.relative_to(root).as_posix()})", ""]
    for png in sorted(folder.glob("*.png")):
        rel = png.relative_to(root)
        lines.append(f"![{scenario.name}: {png.stem}]({rel.as_posix()})")
    lines.append("")
    return "\n".join(lines)


def _fmt(value: float) -> str:
    if isinstance(value, bool):  # a flag (moving_at_step)
        return "true" if value else "false"
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    return f"{value:.4g}"


def _difference(measured: float, expected: float) -> str:
    if measured is None or expected is None:
        return ""
    if abs(expected) > 1e-12:
        return f"{100 * (measured - expected) / abs(expected):+.2f} %"
    return f"{measured - expected:+.3g}"

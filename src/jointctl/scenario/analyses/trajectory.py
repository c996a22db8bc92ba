"""A 1-DOF trajectory goal in jointctl's default and in the chapter's mode (figures 11.8, 11.9)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from jointctl.errors import ConfigError
from jointctl.scenario.analyses.common import analysed_joint, rms_tracking_error, run_events, run_variant, units
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.trace import Trace


def analyse_trajectory_tracking(session: Session, trace: Trace, out: Path,
                                params: dict[str, Any]) -> dict[str, Any]:
    """A trajectory goal executed in jointctl's default and in the chapter's mode (figs. 11.8, 11.9)."""
    joint = analysed_joint(session, params)
    if not session.goals:
        raise ConfigError("the analysis needs an accepted trajectory goal", source=session.scenario.source,
                          field="goals")
    goal = session.goals[0]
    start = goal.validated.start_time_s
    end = start + float(goal.validated.times_s[-1])
    chapter_overrides = params.get("chapter_mode") or {}
    chapter = run_variant(session, out / "chapter_mode", dict(chapter_overrides))
    t = trace.time_s
    column = goal.trajectory.joint_names.index(joint)
    points_t = start + np.array([p.time_from_start_s for p in goal.trajectory.points])
    points_q = np.array([p.positions[column] for p in goal.trajectory.points])
    name = session.scenario.name
    unit, events = units(session, joint).position, run_events(session, trace)
    figures.plot_series(out / "coarse_points.png", points_t, {"trajectory points": points_q},
                        title=f"{name}: the client's coarse points (fig. 11.8)", ylabel="position", unit=unit,
                        markers=True)
    figures.plot_series(out / "interpolated_command.png", t,
                        {"chapter mode: linear, 100 Hz": chapter.joint(joint, "reference"),
                         "jointctl: cubic, 1 kHz": trace.joint(joint, "reference")},
                        title=f"{name}: interpolated command (fig. 11.9)", ylabel="position", unit=unit,
                        events=events)
    figures.plot_series(out / "position.png", t,
                        {"reference": trace.joint(joint, "reference"),
                         "position, chapter mode": chapter.joint(joint, "position"),
                         "position, jointctl feed-forward": trace.joint(joint, "position")},
                        title=f"{name}: {joint} position", ylabel="position", unit=unit, events=events)
    figures.plot_series(out / "tracking_error.png", t,
                        {"chapter mode": chapter.joint(joint, "reference") - chapter.joint(joint, "position"),
                         "jointctl feed-forward": trace.joint(joint, "reference") - trace.joint(joint, "position")},
                        title=f"{name}: tracking error", ylabel="reference - position", unit=unit, events=events)
    chapter_rms = rms_tracking_error(chapter, (joint,), start, end)
    ff_rms = rms_tracking_error(trace, (joint,), start, end)
    return {
        "result": goal.status.value,
        "points": len(goal.trajectory.points),
        "duration_s": end - start,
        "rms_tracking_error_m_chapter_mode": chapter_rms,
        "rms_tracking_error_m_feedforward": ff_rms,
        "error_reduction": chapter_rms / ff_rms,
    }

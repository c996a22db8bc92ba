"""The 7-DOF arm moved to a pose in jointctl's default, the chapter's streamer mode and with velocity
feed-forward only; and its droop without gravity compensation."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import fsolve

from jointctl.errors import ConfigError
from jointctl.metrics.expectations import share_of
from jointctl.model.dynamics import RobotDynamics
from jointctl.scenario.analyses.common import (common_units, effort_limit_levels, rms_tracking_error, run_events,
                                               run_variant)
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.trace import Trace


def analyse_arm_pose(session: Session, trace: Trace, out: Path, params: dict[str, Any]) -> dict[str, Any]:
    """The arm moved to a pose in jointctl's default, in the chapter's streamer mode and with
    velocity feed-forward only; and the droop of the pose without gravity compensation."""
    if not session.goals:
        raise ConfigError("the analysis needs an accepted trajectory goal", source=session.scenario.source,
                          field="goals")
    goal = session.goals[0]
    joints = goal.validated.joint_names
    start = goal.validated.start_time_s + float(goal.validated.times_s[0])  # the first point: the pose it leaves
    end = goal.validated.start_time_s + float(goal.validated.times_s[-1])
    variants = {name: run_variant(session, out / name, params.get(name) or {})
                for name in ("chapter_mode", "velocity_ff")}
    final = np.array([trace.joint(j, "position")[-1] for j in joints])
    target = goal.validated.positions[-1]
    metrics: dict[str, Any] = {
        "duration_s": end - start,
        "result": goal.status.value,
        "rms_tracking_error_rad_chapter_mode": rms_tracking_error(variants["chapter_mode"], joints, start, end),
        "rms_tracking_error_rad_velocity_ff": rms_tracking_error(variants["velocity_ff"], joints, start, end),
        "rms_tracking_error_rad_feedforward": rms_tracking_error(trace, joints, start, end),
        "final_error_rad": float(np.max(np.abs(final - target))),
    }
    metrics["error_reduction"] = (metrics["rms_tracking_error_rad_chapter_mode"]
                                  / metrics["rms_tracking_error_rad_feedforward"])
    t = trace.time_s
    name = session.scenario.name
    joint_units, events = common_units(session, joints), run_events(session, trace)
    for label, run in (("jointctl", trace), *variants.items()):
        figures.plot_series(out / f"tracking_error_{label}.png", t,
                            {j: run.joint(j, "reference") - run.joint(j, "position") for j in joints},
                            title=f"{name}: tracking error, {label.replace('_', ' ')}",
                            ylabel="reference - position", unit=joint_units.position, events=events)
    figures.plot_series(out / "effort.png", t, {j: trace.joint(j, "effort") for j in joints},
                        title=f"{name}: joint efforts", ylabel="effort", unit=joint_units.effort, events=events,
                        levels=[level for j in joints for level in effort_limit_levels(session, j, series=j)])
    droop_params = params.get("uncompensated")
    if droop_params is not None:
        pose = dict(zip(joints, target.tolist()))
        droop = run_variant(session, out / "uncompensated", droop_params, goals=(),
                             initial_positions=pose, duration_s=float(params.get("droop_duration_s", 10.0)))
        sag = np.array([droop.joint(j, "position")[-1] for j in joints]) - target
        metrics["uncompensated_droop_rad"] = float(np.max(np.abs(sag)))
        metrics["uncompensated_droop_by_joint_rad"] = sag.tolist()
        expected = static_droop(session, joints, target)
        metrics["expected_uncompensated_droop_by_joint_rad"] = expected.tolist()
        metrics["expected"] = {"uncompensated_droop_by_joint_rad": expected.tolist()}
        metrics["margins"] = {"uncompensated_droop_by_joint_rad": share_of(float(np.max(np.abs(expected))),
                                                                           "largest droop")}
        figures.plot_series(out / "uncompensated_droop.png", droop.time_s,
                            {j: droop.joint(j, "position") for j in joints},
                            title=f"{name}: holding the pose without gravity compensation",
                            ylabel="joint angle", unit=joint_units.position)
    return metrics


def static_droop(session: Session, joints: tuple[str, ...], pose: np.ndarray) -> np.ndarray:
    """Where position loops without gravity compensation (P and D only) hold ``pose`` [rad]: the
    deflection Δq that solves ``Kp·(-Δq) = g(pose + Δq)`` joint by joint, with g from the robot's
    dynamics library (the holding efforts, N·m) and Kp from the running controllers."""
    dynamics = RobotDynamics(session.robot, session.scenario.gravity_m_s2, joints=joints)
    kp = np.array([session.manager.commanding(j).pid.gains.p for j in joints])

    def residual(q: np.ndarray) -> np.ndarray:
        dynamics.set_pose(q, inertia=False)
        return kp * (pose - q) - dynamics.gravity_at_pose()

    return fsolve(residual, pose, xtol=1e-12) - pose

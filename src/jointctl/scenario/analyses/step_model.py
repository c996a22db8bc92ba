"""A scenario's joint loop as it runs, and its answer to the run's own reference: the model the step analysis
expects a run's figures from (:mod:`jointctl.scenario.analyses.step_theory`).

The loop is :class:`~jointctl.metrics.step_loop.JointLoop`, the one autotune designs on:

- the joint: the simulated robot's inertia about it (the session's ``plant``: a scenario's payload and model
  changes; the joint-space inertia's diagonal entry, armature included) at the pose the run ends in, its viscous
  damping, its effort limit, and the effort holding it against gravity over its range with the other joints where
  they end (:func:`~jointctl.metrics.step_loop.holding_effort`);
- its controller: the gains, the derivative law (on the error: the kick ``d·Δr/h`` on a step's first cycle, clamped
  with the rest at the effort limit; or on the measurement), the integral and its clamps, and the gravity
  feed-forward, computed from the controllers' model (which a payload does not change); ros_controllers' law, or
  ros2_controllers' pid_controller's (control_toolbox's PID: its first cycle differentiates the error from 0,
  :mod:`jointctl.control.position_loop`);
- the scenario's ``latency_cycles`` (a command reaches the joint that many cycles late) and, on the simulated
  robot, MuJoCo's own integration: semi-implicit Euler with the damping implicit, ``timestep_s`` steps a control
  period.

It starts where the run starts (the scenario's initial position, at rest, the controller just started: integral 0,
nothing on its way, its first rate the law's) and follows the command source's value at every control period of the run, so that its
response is the run's, to the model's accuracy: 5e-11 m on the 1-DOF robot.

Not modelled: the other joints' motion (held where they end; how their loops move the joint's own is the step
theory's linear loops'), Coulomb friction (``model.JOINT.friction``), the joint's range limits, sensor noise, the
wrapped error of a continuous joint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointctl.control.position_loop import law_of
from jointctl.metrics.step_loop import HoldingEffort, JointLoop, StepFigures, step_figures
from jointctl.scenario.session import Session

#: A command within this share of the effort limit is at it (a clamped one is the limit, to rounding).
LIMIT_TOLERANCE = 1e-9


@dataclass(frozen=True)
class StepModel:
    """The joint loop of a run (``loop``), started at ``start`` (position [m or rad], speed [m/s or rad/s]), and
    its response at every control period: ``time_s`` [s], the ``reference`` it followed, ``position`` [m or rad]
    (measured at the start of each cycle, as the trace records it) and the commanded ``effort`` [N or N·m]."""

    loop: JointLoop
    start: tuple[float, float]
    time_s: np.ndarray
    reference: np.ndarray
    position: np.ndarray
    effort: np.ndarray

    def position_at(self, time_s) -> np.ndarray:
        """The model's position [m or rad] at the loop times ``time_s`` [s] (a trace's: whole periods)."""
        return self.position[self._cycles(time_s)]

    def measured_effort_at(self, time_s) -> np.ndarray:
        """The effort [N or N·m] the joint's hardware reports at the loop times ``time_s`` [s], as a trace records
        it: read at the start of a cycle, the effort that acted over the last period, i.e. the command of the
        cycle before, ``delay_cycles`` earlier still (0 before any command has arrived)."""
        cycles = self._cycles(time_s) - 1 - self.loop.delay_cycles
        return np.where(cycles >= 0, self.effort[np.clip(cycles, 0, None)], 0.0)

    def _cycles(self, time_s) -> np.ndarray:
        return np.clip(np.rint(np.asarray(time_s, dtype=float) / self.loop.period_s).astype(int), 0,
                       self.position.size - 1)

    def figures(self) -> StepFigures:
        """The step's figures as autotune reads a step (:func:`~jointctl.metrics.step_loop.step_figures`:
        overshoot, 2 % settling time of the commanded move, start, final value, its error, peak effort, the
        share of cycles at the effort limit)."""
        return step_figures(self.time_s, self.position, self.reference, self.effort, self.loop.effort_limit)

    def limit_acted(self) -> bool:
        """Whether the effort limit shaped the response: a command at the limit, or (with the feed-forward, which
        is added after the PID's own clamp) a PID term at it."""
        limit = self.loop.effort_limit
        if not math.isfinite(limit):
            return False
        at = limit * (1 - LIMIT_TOLERANCE)
        if np.any(np.abs(self.effort) >= at):
            return True
        if not self.loop.feedforward:
            return False
        feedforward = np.fromiter(map(self.loop.feedforward_effort, self.position), float, self.position.size)
        return bool(np.any(np.abs(self.effort - feedforward) >= at))


def joint_loop(session: Session, joint: str, controller, pose: dict) -> JointLoop:
    """The :class:`~jointctl.metrics.step_loop.JointLoop` of ``joint`` under its position ``controller`` (as
    :func:`~jointctl.control.position_loop.position_loop` gives it) in ``session``'s robot, the other joints at
    ``pose`` (name -> position [m or rad]); see the module docstring."""
    scenario = session.scenario
    names = list(session.hardware.joint_names)
    dynamics = session.dynamics(session.plant, names)
    dynamics.set_pose([float(pose.get(name, 0.0)) for name in names])
    k = names.index(joint)
    gains = controller.pid.gains
    feedforward = "gravity" in controller.feedforward_terms
    model_hold = None
    if feedforward and session.plant is not session.robot:
        model_hold = session.holding_effort(session.robot, joint, pose) or HoldingEffort.zero()
    simulated = session.world is not None
    return JointLoop(
        mass=float(dynamics.mass_matrix()[k, k]), damping=float(dynamics.damping[k]), period_s=scenario.loop_period_s,
        effort_limit=controller.effort_limit, hold=session.holding_effort(session.plant, joint, pose),
        p=gains.p, i=gains.i, d=gains.d, i_clamp=gains.i_clamp_max, i_clamp_min=gains.i_clamp_min,
        antiwindup=gains.antiwindup, law=law_of(controller),
        derivative=controller.derivative, feedforward=feedforward, feedforward_hold=model_hold,
        integrator="euler" if simulated else "hold",
        substeps=max(1, int(round(scenario.loop_period_s / scenario.timestep_s))) if simulated else 1,
        delay_cycles=scenario.latency_cycles)


def step_model(session: Session, trace, joint: str, controller, pose: dict) -> StepModel:
    """The run of ``joint``'s loop (:func:`joint_loop`) over the run recorded in ``trace``: from where the run
    started, following the controller's command source at every control period until the trace's last time."""
    loop = joint_loop(session, joint, controller, pose)
    h = loop.period_s
    cycles = int(round(float(trace.time_s[-1]) / h)) + 1
    time_s = np.arange(cycles) * h
    source = session.sources[controller.name]
    try:
        from jointctl.commands.sources_kernel import sample_times
    except ImportError:  # (numba missing: the source's own sample)
        reference = np.array([float(source.sample(float(t))) for t in time_s])
    else:
        reference = sample_times(source, time_s)
    start = _start(session, trace, joint)
    position, _, effort = loop.run(reference, start=start)
    return StepModel(loop, start, time_s, reference, position, effort)


def _start(session: Session, trace, joint: str) -> tuple[float, float]:
    """(position [m or rad], speed) where the run started: the simulated robot's initial position, at rest; else
    the trace's first sample."""
    world = session.world
    if world is None:
        return float(trace.joint(joint, "position")[0]), float(trace.joint(joint, "velocity")[0])
    k = world.joint_names.index(joint)
    return float(world.initial_positions.get(joint, world.model.qpos0[world.qpos_adr[k]])), 0.0


__all__ = ["StepModel", "joint_loop", "step_model"]

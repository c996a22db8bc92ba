"""Part 2's minimal robot running the chapter's trajectory example (figures 11.8, 11.9), against theory.

The minimal robot is an inverted pendulum: link2 (and the camera box fixed to it) stands upright
on joint1, a revolute joint about a horizontal axis, under the book's position loop
``τ = Kp·err - Kv·q̇`` (no gravity compensation). Everything the theory needs is computed here
from the robot model (the URDF), not from MuJoCo; SI units throughout (rad, s, kg, m, N·m):

- ``m·l``: the first moment of mass about the joint of everything the joint carries (link2 plus the
  fixed kinect_link), and ``I`` their inertia about the joint axis;
- the gravity torque ``τ_g(q) = m·g·l·sin(q + φ)``, where ``φ`` is the angle by which the carried
  centre of mass leans off the joint's upright (the camera box sits 0.2 m forward, so φ > 0 and
  the pendulum leans even at q = 0);
- the loop holds ``q`` where ``Kp·wrap(command - q) + τ_g(q) = 0``: a steady error ``e = command -
  q`` with ``Kp·e = -τ_g(q)`` (the pendulum sags past its command), unique when Kp > m·g·l;
- about a pose ``q``, the loop is a spring-damper of stiffness ``k(q) = Kp - m·g·l·cos(q + φ)``
  (upright: ``Kp - m·g·l``, the inverted pendulum's effective stiffness), natural frequency
  ``√(k/I)``, damping ratio ``Kv / (2·√(k·I))``, and a sine of frequency ω lags by
  ``atan2(Kv·ω, k - I·ω²) / ω`` seconds;
- the whole run, through the nonlinear equation ``I·q̈ = Kp·wrap(c - q) - Kv·q̇ + τ_g(q)`` with the
  recorded command ``c``, the control held over each loop period as the loop holds it
  (:meth:`PendulumTheory.simulate`).

:func:`analyse_minimal_robot_trajectory` measures the same figures from the recorded run: the
local natural frequency and damping ratio by fitting ``q̈ = a·q + b·q̇ + c`` where the command is
held (the whole hold before the goal; after it ends, the last ``fit_amplitude_rad`` of the
settling), the steady error at the final pose, the tracking lag by cross-correlating command and
angle, and how far the run strays from :meth:`PendulumTheory.simulate`. ``expected`` holds the
theory of each measured figure: the local figures at the pose the loop holds (the fitted windows
span a little of the angle, over which the stiffness varies by ``m·g·l·|Δcos(q + φ)|``), the lag
and RMS error from the model run (the linear lag at the mean pose, reported beside it, only
approximates it: the swing from 0.19 to 1.56 rad sweeps the stiffness from 4.3 to 10.1 N·m/rad).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from jointctl.control.joint_controllers import wrap_angle
from jointctl.errors import ConfigError, ControllerError
from jointctl.metrics.expectations import share_of
from jointctl.model.mjcf import rpy_to_matrix
from jointctl.model.robot_model import RobotModel
from jointctl.scenario.analyses.common import effort_limit_levels, run_events, units
from jointctl.scenario.session import Session
from jointctl.recording import figures
from jointctl.recording.figures import Level
from jointctl.recording.trace import Trace
from jointctl.trajectory.executor import TrajectoryExecutor

#: Time after the goal starts before the tracking lag is measured [s]: the jump from the hold pose
#: to the goal's first point has died out by then (the slowest upright pole decays at ~2 /s).
DEFAULT_LAG_SKIP_S = 3.0
#: Longest lag the cross-correlation looks for [s].
MAX_LAG_S = 2.0
#: Steps of the model integration per loop period.
SUBSTEPS = 4
#: After the goal, the local dynamics are fitted where the angle stays this close to where the run
#: ends [rad]: small enough that the gravity torque is linear in the angle to a fraction of a percent.
DEFAULT_FIT_AMPLITUDE_RAD = 0.01


@dataclass(frozen=True)
class PendulumTheory:
    """A revolute joint carrying a rigid pendulum under a PD position loop, without gravity compensation.

    ``gravity_torque(q) = mgl_n_m·sin(q + lean_rad)`` is the torque [N·m] gravity applies about
    the joint axis (positive: towards positive q); ``inertia_kg_m2`` the pendulum's inertia about
    the axis; ``kp`` [N·m/rad] and ``kv`` [N·m·s/rad] the loop's gains; ``mass_length_kg_m`` the
    first moment of mass perpendicular to the axis (so ``mgl_n_m = g_perp·mass_length_kg_m``).
    """

    kp: float
    kv: float
    inertia_kg_m2: float
    mass_length_kg_m: float
    mgl_n_m: float
    lean_rad: float

    def gravity_torque(self, q: float) -> float:
        """Gravity's torque about the joint [N·m] at angle ``q`` [rad]."""
        return self.mgl_n_m * math.sin(q + self.lean_rad)

    def stiffness(self, q: float) -> float:
        """Loop stiffness about pose ``q`` [N·m/rad]: ``Kp - dτ_g/dq``."""
        return self.kp - self.mgl_n_m * math.cos(q + self.lean_rad)

    @property
    def upright_stiffness(self) -> float:
        """``Kp - m·g·l`` [N·m/rad]: the effective stiffness with the centre of mass straight up."""
        return self.kp - self.mgl_n_m

    def natural_frequency(self, stiffness: float) -> float:
        """``√(k/I)`` [rad/s] for a stiffness ``k`` [N·m/rad]."""
        return math.sqrt(stiffness / self.inertia_kg_m2)

    def damping_ratio(self, stiffness: float) -> float:
        """``Kv / (2·√(k·I))`` for a stiffness ``k`` [N·m/rad]."""
        return self.kv / (2.0 * math.sqrt(stiffness * self.inertia_kg_m2))

    def lag_s(self, stiffness: float, omega_rad_s: float) -> float:
        """Time lag [s] of a small sine of ``omega_rad_s`` about a pose of stiffness ``k``."""
        phase = math.atan2(self.kv * omega_rad_s, stiffness - self.inertia_kg_m2 * omega_rad_s**2)
        return phase / omega_rad_s

    def equilibrium(self, command: float) -> float:
        """The angle [rad] the loop holds for a constant ``command`` [rad]: the root of
        ``Kp·wrap(command - q) + τ_g(q)`` within half a turn of the command (unique for Kp > m·g·l)."""
        if self.kp <= self.mgl_n_m:
            raise ValueError(f"Kp = {self.kp} does not exceed m·g·l = {self.mgl_n_m:.4g}: no unique pose")
        from scipy.optimize import brentq

        def residual(q: float) -> float:
            return self.kp * (command - q) + self.gravity_torque(q)

        return float(brentq(residual, command - math.pi, command + math.pi, xtol=1e-15, rtol=1e-15))

    def steady_state_error(self, command: float) -> float:
        """``command - q`` [rad] at rest: negative when gravity pulls the pendulum past its command."""
        return command - self.equilibrium(command)

    def simulate(self, time_s: np.ndarray, command: np.ndarray, q0: float, v0: float) -> np.ndarray:
        """Angles [rad] at ``time_s`` from ``I·q̈ = u - Kv·q̇ + τ_g(q)`` with ``u = Kp·wrap(c - q) - Kv·q̇``
        evaluated at each sample and held until the next (as the loop holds its effort), gravity
        continuous (RK4, :data:`SUBSTEPS` steps a sample). ``command`` [rad] is sampled at ``time_s``."""
        t = np.asarray(time_s, dtype=float)
        c = np.asarray(command, dtype=float)
        out = np.empty_like(t)
        q, v = float(q0), float(v0)
        kp, kv, inv_i = self.kp, self.kv, 1.0 / self.inertia_kg_m2
        mgl, lean = self.mgl_n_m, self.lean_rad
        sin = math.sin
        for k in range(len(t)):
            out[k] = q
            if k + 1 == len(t):
                break
            error = c[k] - q
            if not -math.pi < error <= math.pi:
                error = wrap_angle(error)
            u = kp * error - kv * v
            h = (t[k + 1] - t[k]) / SUBSTEPS
            for _ in range(SUBSTEPS):
                a1 = (u + mgl * sin(q + lean)) * inv_i
                q2, v2 = q + 0.5 * h * v, v + 0.5 * h * a1
                a2 = (u + mgl * sin(q2 + lean)) * inv_i
                q3, v3 = q + 0.5 * h * v2, v + 0.5 * h * a2
                a3 = (u + mgl * sin(q3 + lean)) * inv_i
                q4, v4 = q + h * v3, v + h * a3
                a4 = (u + mgl * sin(q4 + lean)) * inv_i
                q += h * (v + 2 * v2 + 2 * v3 + v4) / 6.0
                v += h * (a1 + 2 * a2 + 2 * a3 + a4) / 6.0
        return out


def pendulum_theory(robot: RobotModel, joint: str, gravity_m_s2: Sequence[float], *,
                    kp: float, kv: float) -> PendulumTheory:
    """The :class:`PendulumTheory` of revolute ``joint`` of ``robot`` under ``gravity_m_s2`` (world
    frame, m/s²): the joint's base must be fixed to the world, and everything it carries fixed to
    its child link (each link's mass, centre of mass and inertia from the URDF)."""
    j = robot.joint(joint)
    if j.type not in ("revolute", "continuous") or not j.is_movable:
        raise ConfigError("needs a revolute or continuous joint", source=robot.source, field="joint", value=joint)
    # The joint frame at q = 0 in the world: fixed joints from the root down to the joint.
    rotation = rpy_to_matrix(j.origin.rpy)
    link = j.parent
    while link != robot.root_link:
        parent = next(p for p in robot.joints if p.child == link)
        if parent.is_movable:
            raise ConfigError("the joint's base must be fixed to the world", source=robot.source,
                              field=f"joint[{parent.name}]", value=parent.type)
        rotation = rpy_to_matrix(parent.origin.rpy) @ rotation
        link = parent.parent
    gravity = rotation.T @ np.asarray(gravity_m_s2, dtype=float)  # in the joint frame at q = 0
    axis = np.asarray(j.axis, dtype=float)
    first_moment = np.zeros(3)
    inertia = 0.0
    # Everything the joint carries, in the child link's frame (which is the joint frame).
    stack = [(j.child, np.eye(3), np.zeros(3))]
    while stack:
        name, rot, pos = stack.pop()
        inertial = robot.link(name).inertial
        if inertial is not None:
            r_com = rot @ rpy_to_matrix(inertial.origin.rpy)
            com = pos + rot @ np.asarray(inertial.origin.xyz, dtype=float)
            ixx, iyy, izz, ixy, ixz, iyz = inertial.inertia
            tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
            inertia += float(axis @ (r_com @ tensor @ r_com.T) @ axis)
            inertia += inertial.mass_kg * float(com @ com - (axis @ com) ** 2)
            first_moment += inertial.mass_kg * com
        for child in robot.child_joints(name):
            if child.is_movable:
                raise ConfigError("the pendulum must be rigid: a movable joint beyond the analysed one",
                                  source=robot.source, field=f"joint[{child.name}]", value=child.type)
            stack.append((child.child, rot @ rpy_to_matrix(child.origin.rpy),
                          pos + rot @ np.asarray(child.origin.xyz, dtype=float)))
    perpendicular = first_moment - axis * (axis @ first_moment)
    # τ_g(q) = axis·((R_axis(q)·mc) × g) = A·cos q + B·sin q
    a = float(axis @ np.cross(perpendicular, gravity))
    b = float(axis @ np.cross(np.cross(axis, perpendicular), gravity))
    return PendulumTheory(kp=kp, kv=kv, inertia_kg_m2=inertia,
                          mass_length_kg_m=float(np.linalg.norm(perpendicular)),
                          mgl_n_m=math.hypot(a, b), lean_rad=math.atan2(a, b))


# -- measurements ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class LocalDynamics:
    """A fit of ``q̈ = a·q + b·q̇ + c`` over a window where the command is constant."""

    natural_frequency_rad_s: float
    damping_ratio: float
    rest_position_rad: float
    amplitude_rad: float


def fit_local_dynamics(time_s: np.ndarray, position: np.ndarray, velocity: np.ndarray) -> LocalDynamics:
    """Natural frequency [rad/s], damping ratio and rest angle [rad] of a held joint's free motion.

    ``q̈`` is the forward difference of the recorded velocity, which at the loop's sampling is
    exactly the acceleration the state of each sample produced; a least-squares fit of
    ``q̈ = a·q + b·q̇ + c`` gives ``ωn = √(-a)``, ``ζ = -b/(2ωn)``, rest ``-c/a``.
    """
    t, q, v = (np.asarray(x, dtype=float) for x in (time_s, position, velocity))
    acc = np.diff(v) / np.diff(t)
    design = np.column_stack([q[:-1], v[:-1], np.ones(len(acc))])
    (a, b, c), *_ = np.linalg.lstsq(design, acc, rcond=None)
    if not a < 0:
        return LocalDynamics(math.nan, math.nan, math.nan, float(np.ptp(q)))
    wn = math.sqrt(-a)
    return LocalDynamics(wn, -b / (2 * wn), -c / a, float(np.ptp(q)))


def settled_tail(position: np.ndarray, amplitude_rad: float) -> np.ndarray:
    """A mask of the samples from the first one after which ``position`` stays within
    ``amplitude_rad`` of its last sample."""
    q = np.asarray(position, dtype=float)
    far = np.abs(q - q[-1]) > amplitude_rad
    outside = np.flatnonzero(far)
    mask = np.ones(len(q), dtype=bool)
    if outside.size:
        mask[: outside[-1] + 1] = False
    return mask


def tracking_lag_s(time_s: np.ndarray, command: np.ndarray, position: np.ndarray,
                   max_lag_s: float = MAX_LAG_S) -> float:
    """The delay [s] by which ``position`` best matches ``command`` up to a gain and an offset:
    the shift of largest correlation coefficient between ``command`` and the shifted ``position``
    (each over their overlap), refined between samples by a parabola. Needs uniform sampling."""
    t = np.asarray(time_s, dtype=float)
    dt = float(np.median(np.diff(t)))
    c = np.asarray(command, dtype=float)
    p = np.asarray(position, dtype=float)
    n = len(c)
    max_shift = min(int(round(max_lag_s / dt)), n // 2)
    scores = np.empty(max_shift + 1)
    for s in range(max_shift + 1):
        x, y = c[: n - s], p[s:]
        x, y = x - x.mean(), y - y.mean()
        scores[s] = np.dot(x, y) / math.sqrt(np.dot(x, x) * np.dot(y, y))
    k = int(np.argmax(scores))
    shift = float(k)
    if 0 < k < max_shift:
        left, mid, right = scores[k - 1], scores[k], scores[k + 1]
        denominator = left - 2 * mid + right
        if denominator != 0:
            shift += 0.5 * (left - right) / denominator
    return shift * dt


# -- the analysis ------------------------------------------------------------------------------------

def _executor(session: Session, params: dict[str, Any]) -> TrajectoryExecutor:
    name = params.get("controller")
    try:
        executor = session.manager.controller(name)
    except ControllerError:  # the manager names what it lacks; say which field asked for it
        executor = None
    if not isinstance(executor, TrajectoryExecutor):
        raise ConfigError("must name the trajectory executor", source=session.scenario.source,
                          field="analysis.controller", value=name)
    return executor


def analyse_minimal_robot_trajectory(session: Session, trace: Trace, out: Path,
                                     params: dict[str, Any]) -> dict[str, Any]:
    """The book's example client's goal on the minimal robot: figures 11.8 and 11.9, the angle
    against its command, the tracking error and the effort, with metrics against
    :class:`PendulumTheory` (``expected``). ``params``: ``joint``, ``controller`` (the executor),
    optional ``lag_skip_s`` (default :data:`DEFAULT_LAG_SKIP_S`), ``fit_amplitude_rad`` (default
    :data:`DEFAULT_FIT_AMPLITUDE_RAD`) and ``omega_rad_s`` (the goal's sine, default 1)."""
    joint = params.get("joint")
    if joint not in session.hardware.joint_names:
        raise ConfigError("names no joint of the robot", source=session.scenario.source,
                          field="analysis.joint", value=joint)
    executor = _executor(session, params)
    if joint not in executor.joint_names:
        raise ConfigError("the executor does not drive this joint", source=session.scenario.source,
                          field="analysis.joint", value=joint)
    if not session.goals:
        raise ConfigError("the analysis needs an accepted trajectory goal", source=session.scenario.source,
                          field="goals")
    position_controller = executor.targets[executor.joint_names.index(joint)]
    gains = position_controller.pid.gains
    theory = pendulum_theory(session.robot, joint, session.scenario.gravity_m_s2, kp=gains.p, kv=gains.d)

    goal = session.goals[0]
    start = goal.validated.start_time_s
    end = start + float(goal.validated.times_s[-1])
    column = goal.validated.joint_names.index(joint)
    points_t = start + goal.validated.times_s
    points_q = goal.validated.positions[:, column]

    t = trace.time_s
    command, position = trace.joint(joint, "reference"), trace.joint(joint, "position")
    velocity, effort = trace.joint(joint, "velocity"), trace.joint(joint, "effort")
    error = command - position

    # Held windows: before the goal (the spawn pose settling under command 0) and after its end.
    amplitude = float(params.get("fit_amplitude_rad", DEFAULT_FIT_AMPLITUDE_RAD))
    # Before the goal the whole hold is fitted: the spawn pose settling from rest excites both of its
    # (real) modes, where a tail would hold the slow one only, which no single fit can separate.
    hold = np.flatnonzero(t < start - 1e-9)
    settle = np.flatnonzero(t > end + 1e-9)
    settle = settle[settled_tail(position[settle], amplitude)]
    hold_fit = fit_local_dynamics(t[hold], position[hold], velocity[hold])
    settle_fit = fit_local_dynamics(t[settle], position[settle], velocity[settle])
    hold_command, final_command = float(command[hold][-1]), float(command[-1])
    hold_pose, final_pose = theory.equilibrium(hold_command), theory.equilibrium(final_command)
    k_hold, k_final = theory.stiffness(hold_pose), theory.stiffness(final_pose)

    # Tracking: from lag_skip_s into the goal to its end.
    skip = float(params.get("lag_skip_s", DEFAULT_LAG_SKIP_S))
    tracking = (t >= start + skip) & (t <= end)
    model = theory.simulate(t, command, float(position[0]), float(velocity[0]))
    lag = tracking_lag_s(t[tracking], command[tracking], position[tracking])
    model_lag = tracking_lag_s(t[tracking], command[tracking], model[tracking])
    mean_pose = theory.equilibrium(float(np.mean(command[tracking])))
    omega = float(params.get("omega_rad_s", 1.0))
    during_goal = (t >= start) & (t <= end)

    metrics: dict[str, Any] = {
        "result": goal.status.value,
        "points": len(goal.trajectory.points),
        "duration_s": end - start,
        "inertia_about_joint_kg_m2": theory.inertia_kg_m2,
        "mass_length_kg_m": theory.mass_length_kg_m,
        "gravity_torque_amplitude_n_m": theory.mgl_n_m,
        "lean_rad": theory.lean_rad,
        "upright_stiffness_n_m_rad": theory.upright_stiffness,
        "upright_natural_frequency_rad_s": theory.natural_frequency(theory.upright_stiffness),
        "upright_damping_ratio": theory.damping_ratio(theory.upright_stiffness),
        "hold_command_rad": hold_command,
        "hold_position_rad": hold_fit.rest_position_rad,
        "hold_natural_frequency_rad_s": hold_fit.natural_frequency_rad_s,
        "hold_damping_ratio": hold_fit.damping_ratio,
        "hold_amplitude_rad": hold_fit.amplitude_rad,
        "final_command_rad": final_command,
        "final_position_rad": float(position[-1]),
        "final_rest_position_rad": settle_fit.rest_position_rad,
        "steady_state_error_rad": final_command - float(position[-1]),
        "final_natural_frequency_rad_s": settle_fit.natural_frequency_rad_s,
        "final_damping_ratio": settle_fit.damping_ratio,
        "final_amplitude_rad": settle_fit.amplitude_rad,
        "final_stiffness_n_m_rad": k_final,
        "tracking_lag_s": lag,
        "tracking_lag_s_linear_at_mean_pose": theory.lag_s(theory.stiffness(mean_pose), omega),
        "rms_tracking_error_rad": float(np.sqrt(np.mean(error[tracking] ** 2))),
        "max_tracking_error_rad": float(np.max(np.abs(error[during_goal]))),
        "model_rms_difference_rad": float(np.sqrt(np.mean((position - model) ** 2))),
        "model_max_difference_rad": float(np.max(np.abs(position - model))),
        "peak_velocity_rad_s": float(np.max(np.abs(velocity))),
        "peak_effort_n_m": float(np.max(np.abs(effort))),
        "expected": {
            "hold_position_rad": hold_pose,
            "hold_natural_frequency_rad_s": theory.natural_frequency(k_hold),
            "hold_damping_ratio": theory.damping_ratio(k_hold),
            "final_position_rad": final_pose,
            "final_rest_position_rad": final_pose,
            "steady_state_error_rad": final_command - final_pose,
            "final_natural_frequency_rad_s": theory.natural_frequency(k_final),
            "final_damping_ratio": theory.damping_ratio(k_final),
            "tracking_lag_s": model_lag,
            "rms_tracking_error_rad": float(np.sqrt(np.mean((command - model)[tracking] ** 2))),
        },
        # Rest angles: a share of the sag the theory predicts at that pose.
        "margins": {"hold_position_rad": share_of(hold_command - hold_pose, "sag"),
                    **{key: share_of(final_command - final_pose, "sag")
                       for key in ("final_position_rad", "final_rest_position_rad", "steady_state_error_rad")}},
    }
    _figures(session, trace, out, joint, command, position, model, effort, points_t, points_q, final_pose, start,
             end)
    return metrics


def _figures(session: Session, trace: Trace, out: Path, joint: str, command, position, model, effort, points_t,
             points_q, final_pose: float, start: float, end: float) -> None:
    plot = figures.plot_series
    name, t = session.scenario.name, trace.time_s
    joint_units, events = units(session, joint), run_events(session, trace)
    angle = {"ylabel": "joint angle", "unit": joint_units.position}
    plot(out / "coarse_points.png", points_t, {"the client's points": points_q},
         title=f"{name}: the client's coarse, irregular points (fig. 11.8)", markers=True, **angle)
    during = (t >= start - 0.2) & (t <= end + 0.2)
    plot(out / "interpolated_command.png", t[during], {"linear interpolation, 100 Hz": command[during]},
         title=f"{name}: the server's interpolated command (fig. 11.9)", events=events, **angle)
    plot(out / "position.png", t, {"reference": command, "model (theory)": model, f"{joint} angle": position},
         title=f"{name}: commanded and actual angle", events=events,
         levels=[Level(final_pose, "predicted final pose", "expected")], **angle)
    plot(out / "tracking_error.png", t, {"command - angle": command - position},
         title=f"{name}: tracking error", ylabel="error", unit=joint_units.position, events=events)
    plot(out / "effort.png", t, {f"{joint} torque": effort}, title=f"{name}: joint torque",
         ylabel="torque", unit=joint_units.effort, levels=effort_limit_levels(session, joint), events=events)

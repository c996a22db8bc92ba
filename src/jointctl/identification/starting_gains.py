"""Starting gains for a robot nobody has tuned yet: a PD position loop per actuated joint, from the model.

For every joint with an ``EffortJointInterface`` transmission (the chapter's effort-based position
controllers), at the **home pose** (each joint at 0, or mid-range when 0 is outside its limits):

- the plant: the joint's inertia ``I`` (its mass-matrix diagonal entry at home, the other joints
  there too; kg or kg·m²) and the URDF damping ``b``;
- the gains: :func:`jointctl.identification.autotune.design` for a closed-loop bandwidth
  ``bandwidth_hz`` and damping ratio ``zeta`` on the sampled loop, with the derivative on the
  error, as ros_controllers' ``effort_controllers/JointPositionController`` computes for a plain
  position command (so the file behaves alike on jointctl and on a ros_control robot);
- the check against the effort limit: a step of ``step`` (a tenth of the joint's range, at most
  0.1 m or rad) from home must ask at most ``effort_fraction`` of the URDF effort limit,
  ``p·step + |τg(home)|`` (τg the gravity load at home). When it would ask more, the bandwidth is
  lowered until it fits, and the note says so; a joint whose gravity load alone exceeds that
  share cannot hold its own weight, and is refused. (A step's first cycle also asks the derivative
  kick ``d·step/period``: clamped at the limit for one cycle, as on any ros_control robot; a
  trajectory controller's commands carry velocities and have none.)
- the check against gravity: a P loop rests where ``p·e = τg``; the sag ``|τg|/p`` must be at most half the
  step, so the bandwidth is raised when the one asked is too soft to hold the load (and, when the effort limit
  allows no such stiffness, the note says how far it sags). The load is the larger of the gravity load at home
  and at the end of the step (a joint balanced above its axis holds nothing at home, and more a step away).
- a plant whose own damping already exceeds ``zeta`` at the bandwidth (a light joint with a stiff bearing,
  a geared yaw axis): ``d = 0``, ``p`` for the bandwidth, and the loop's own damping ratio said in the note.
- the step scenario init writes for the joint moves the reference along a ramp (``ramp_s``) when a step's
  derivative kick ``d·step/period`` would ask more than half of what the effort limit leaves: the ramp's
  kick ``d·step/ramp_s`` fits, and the step runs without clamping the effort (checked on the loop as it runs,
  :class:`~jointctl.identification.step_loop.JointLoop`); the step comes once the start's own sag has settled
  (``step_at_s``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from jointctl.errors import ConfigError
from jointctl.identification.autotune import design, loop_zeta, undamped_design
from jointctl.identification.plant_fit import IdentificationError
from jointctl.identification.step_loop import JointLoop, holding_effort, reference_step

#: The joint interfaces a starting position loop is written for.
EFFORT_INTERFACE = "EffortJointInterface"
#: The share of the effort limit a design step may ask (the rest is margin for disturbances).
EFFORT_FRACTION = 0.8
#: The sag allowed under the gravity load at home, as a share of the step: p ≥ |τg| / (SAG_FRACTION·step).
SAG_FRACTION = 0.5
#: The step checked against the effort limit: this share of the range, at most MAX_STEP [m or rad].
STEP_FRACTION = 0.1
MAX_STEP = 0.1


@dataclass(frozen=True)
class StartingGains:
    """One joint's starting position loop. ``inertia`` [kg or kg·m²] and ``damping`` [N·s/m or
    N·m·s/rad] at ``home`` [m or rad]; ``gravity_load`` [N or N·m] |τg| there; ``effort_limit`` [N or
    N·m]; ``step`` [m or rad] the step checked; ``gains`` {p, i, d}; ``bandwidth_hz`` and ``zeta``
    designed for (the bandwidth possibly lowered from the one asked: ``note`` says why); the step scenario's
    ``ramp_s`` [s] (0: a step), ``step_at_s`` [s] when it moves, the step's ``settling_s`` [s] and
    ``peak_effort`` [N or N·m] on the loop as it runs."""

    joint: str
    joint_type: str
    home: float
    inertia: float
    damping: float
    gravity_load: float
    effort_limit: float
    step: float
    gains: dict
    bandwidth_hz: float
    zeta: float
    note: str = ""
    ramp_s: float = 0.0
    step_at_s: float = 0.5
    settling_s: float = 0.0
    peak_effort: float = 0.0

    @property
    def controller(self) -> str:
        """The controller's name in the written YAML: ``<joint>_position_controller``."""
        return f"{self.joint}_position_controller"


def home_pose(robot) -> dict[str, float]:
    """Each movable joint at 0, or at mid-range when 0 is outside its limits [m or rad]."""
    pose = {}
    for joint in robot.movable_joints:
        lower, upper, _ = joint.range_and_speed()
        pose[joint.name] = 0.0 if lower <= 0.0 <= upper else 0.5 * (lower + upper)
    return pose


def effort_joints(robot) -> list[str]:
    """The movable joints an ``EffortJointInterface`` transmission drives, in document order; a
    ConfigError when there is none (jointctl drives only joints with a transmission)."""
    driven = {t.joint for t in robot.transmissions if EFFORT_INTERFACE in t.hardware_interfaces}
    joints = [j.name for j in robot.movable_joints if j.name in driven]
    if not joints:
        raise ConfigError("no movable joint has a <transmission> with an EffortJointInterface or a <ros2_control> "
                          "effort command interface: jointctl (as ros_control) drives only joints with one; add one "
                          "per joint",
                          source=robot.source, field="transmission")
    return joints


def starting_gains(robot, *, bandwidth_hz: float = 2.0, zeta: float = 0.7, period_s: float = 0.001,
                   gravity_m_s2=(0.0, 0.0, -9.81)) -> list[StartingGains]:
    """The starting loop of every effort-driven joint of ``robot`` (see the module docstring)."""
    from jointctl.model.dynamics import RobotDynamics

    for name, value in (("--bandwidth-hz", bandwidth_hz), ("--zeta", zeta)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ConfigError("must be a positive number", field=name, value=value)
    if not zeta < 1:
        raise ConfigError("must be below 1 (an underdamped loop)", field="--zeta", value=zeta)
    home = home_pose(robot)
    names = list(home)
    dynamics = RobotDynamics(robot, gravity_m_s2=gravity_m_s2)
    dynamics.set_pose([home[n] for n in names])
    mass_matrix = dynamics.mass_matrix()
    gravity = dynamics.gravity_at_pose()
    loops = []
    for joint_name in effort_joints(robot):
        k = names.index(joint_name)
        joint = robot.joint(joint_name)
        lower, upper, _ = joint.range_and_speed()
        step = min(MAX_STEP, STEP_FRACTION * (upper - lower)) if math.isfinite(upper - lower) else MAX_STEP
        limit = joint.limits.effort if joint.limits is not None and joint.limits.effort > 0 else math.inf
        hold = holding_effort(robot, joint_name, home, gravity_m_s2)
        load = max(abs(float(gravity[k])), abs(hold(home[joint_name] + step)) if hold else 0.0)
        here = home[joint_name]
        unstable = min(0.0, (hold(here + 1e-4) - hold(here - 1e-4)) / 2e-4) if hold else 0.0
        loop = _joint_loop(joint_name, joint.type, here, float(mass_matrix[k, k]), float(joint.damping),
                           load, limit, step, bandwidth_hz, zeta, period_s, -unstable)
        loops.append(_step_move(loop, hold, period_s))
    return loops


def _joint_loop(joint, joint_type, home, inertia, damping, gravity, limit, step, bandwidth_hz, zeta,
                period_s, tipping: float = 0.0) -> StartingGains:
    """One joint's loop (see the module docstring). ``tipping`` [N/m or N·m/rad] is how much gravity's pull
    grows per unit away from home for a joint balanced above its axis (``-∂τ_hold/∂q`` where negative): the
    loop's stiffness is ``p`` less that, so ``p`` is designed that much higher."""
    allowed = EFFORT_FRACTION * limit
    if gravity >= allowed:
        raise ConfigError(f"its gravity load at the home pose, {gravity:.4g}, is {100 * gravity / limit:.0f} % of its "
                          f"effort limit {limit:g}: it cannot hold itself there with margin (raise the limit, or "
                          "check the masses and the gravity direction)", field=f"joint {joint}", value=home)
    p_effort = (allowed - gravity) / step  # the most p a step may ask
    p_sag = gravity / (SAG_FRACTION * step)  # the least p that holds the load within the sag allowed
    p_low, p_high = min(p_sag, 0.9 * p_effort), p_effort
    asked = bandwidth_hz
    for _ in range(12):
        try:
            gains = design(inertia, damping, loop="position", bandwidth_hz=bandwidth_hz, zeta=zeta,
                           period_s=period_s, derivative="error")
        except IdentificationError as exc:
            if "own damping" not in exc.message:
                raise ConfigError(f"no PD gains for {bandwidth_hz:.3g} Hz and ζ {zeta:g} ({exc.message}); choose "
                                  "another --bandwidth-hz or --zeta", field=f"joint {joint}") from None
            gains = undamped_design(inertia, damping, bandwidth_hz, period_s)
        p = gains["p"]
        if p_low * (1 - 1e-9) <= p <= p_high * (1 + 1e-9):
            break
        # p grows about as the bandwidth squared: scale into the band, a little inside it.
        bandwidth_hz *= math.sqrt((p_high * 0.98 if p > p_high else p_low * 1.02) / p)
    else:
        raise ConfigError("found no bandwidth whose gains hold the load and whose step fits the effort limit",
                          field=f"joint {joint}", value=limit)
    notes = []
    if bandwidth_hz < asked:
        notes.append(f"bandwidth lowered from {asked:g} to {bandwidth_hz:.3g} Hz: a {step:g} step would ask more than "
                     f"{100 * EFFORT_FRACTION:.0f} % of the effort limit {limit:g}")
    elif bandwidth_hz > asked:
        notes.append(f"bandwidth raised from {asked:g} to {bandwidth_hz:.3g} Hz to hold the gravity load "
                     f"{gravity:.3g} within {SAG_FRACTION * step:.3g} (p ≥ load / sag)")
    if p_sag > p_effort:
        notes.append(f"sags {gravity / gains['p']:.3g} under its gravity load at home: the effort limit allows no "
                     "stiffer loop; a gravity feed-forward or a stronger motor would")
    if tipping > 0:
        gains = {**gains, "p": gains["p"] + tipping}
        notes.append(f"p raised by {tipping:.3g}: balanced above its axis at home, gravity pulls it away by that much "
                     "per unit of motion")
    if gains["d"] == 0.0:
        notes.append(f"d = 0: its own damping {damping:g} alone damps the loop more than ζ {zeta:g} at "
                     f"{bandwidth_hz:.3g} Hz (ζ {loop_zeta(inertia, damping, gains['p']):.3g})")
    return StartingGains(joint, joint_type, home, inertia, damping, gravity, limit, step, gains, bandwidth_hz, zeta,
                         "; ".join(notes))


def _step_move(loop: StartingGains, hold, period_s: float) -> StartingGains:
    """``loop`` with its step scenario's move: a ramp long enough that the derivative kick asks at most half of
    what :data:`EFFORT_FRACTION` of the limit leaves beside the load, lengthened until the step, run on the loop
    as it runs (the law, the clamp, gravity over the move), asks no more than that share of the limit; the
    step once the start's sag has settled (twice the step's settling time, at least 0.5 s)."""
    allowed = EFFORT_FRACTION * loop.effort_limit
    d = loop.gains["d"]
    room = max(allowed - loop.gravity_load, 1e-9)
    ramp_s = period_s * math.ceil(d * loop.step / (0.5 * room) / period_s) if d and math.isfinite(room) else 0.0
    ramp_s = 0.0 if ramp_s <= period_s else ramp_s
    joint_loop = JointLoop(loop.inertia, loop.damping, period_s, loop.effort_limit, hold, p=loop.gains["p"], d=d)
    for _ in range(8):
        moves = reference_step(loop.home, loop.step, hold_s=0.05, ramp_s=ramp_s, after_s=3.0, period_s=period_s)
        figures = joint_loop.step(moves)
        if figures.peak_effort <= allowed:
            break
        ramp_s = max(2 * ramp_s, 0.01)
    settling = figures.settling_s if math.isfinite(figures.settling_s) else 1.0
    step_at = max(0.5, math.ceil(20 * settling) / 10)
    note = loop.note
    if ramp_s:
        extra = (f"its step scenario ramps over {ramp_s:g} s: a step's first cycle would ask the derivative kick "
                 f"d·step/period = {d * loop.step / period_s:.4g}, more than half of what the effort limit "
                 f"{loop.effort_limit:g} leaves beside the load")
        note = f"{note}; {extra}" if note else extra
    return replace(loop, note=note, ramp_s=ramp_s, step_at_s=step_at, settling_s=settling,
                   peak_effort=figures.peak_effort)


__all__ = ["EFFORT_FRACTION", "StartingGains", "effort_joints", "home_pose", "starting_gains"]

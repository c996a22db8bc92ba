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
- the check against gravity: a P loop rests where ``p·e = τg``; the sag ``|τg|/p`` at home must be at
  most half the step, so the bandwidth is raised when the one asked is too soft to hold the load
  (and, when the effort limit allows no such stiffness, the note says how far it sags).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from jointctl.errors import ConfigError
from jointctl.identification.autotune import design
from jointctl.identification.plant_fit import IdentificationError

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
    designed for (the bandwidth possibly lowered from the one asked: ``note`` says why)."""

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
        raise ConfigError("no movable joint has a <transmission> with an EffortJointInterface: jointctl (as "
                          "ros_control) drives only joints with a transmission; add one per joint",
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
        loops.append(_joint_loop(joint_name, joint.type, home[joint_name], float(mass_matrix[k, k]),
                                 float(joint.damping), abs(float(gravity[k])), limit, step, bandwidth_hz, zeta,
                                 period_s))
    return loops


def _joint_loop(joint, joint_type, home, inertia, damping, gravity, limit, step, bandwidth_hz, zeta,
                period_s) -> StartingGains:
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
            raise ConfigError(f"no PD gains for {bandwidth_hz:.3g} Hz and ζ {zeta:g} ({exc.message}); choose "
                              "another --bandwidth-hz or --zeta", field=f"joint {joint}") from None
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
    return StartingGains(joint, joint_type, home, inertia, damping, gravity, limit, step, gains, bandwidth_hz, zeta,
                         "; ".join(notes))


__all__ = ["EFFORT_FRACTION", "StartingGains", "effort_joints", "home_pose", "starting_gains"]

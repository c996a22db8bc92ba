"""The compiled form of :class:`~jointctl.control.admittance_controller.AdmittanceController` (the 1-DOF natural
admittance controller, chained to a velocity controller): its ``update`` on arrays, statement for statement,
with the sample-and-hold of ``joint_state_rate_hz`` and ``force_rate_hz``.

The controller is a row of parameters and a row of state of the compiled cycle's tables (floats, indexed by
the names below). :func:`pack_admittance` makes them from the Python controller and :func:`unpack_admittance`
puts the state back (``velocity_reference``, the held position, velocity and force, the next sample times), so
a run can go on in Python at any cycle boundary.
"""

from __future__ import annotations

from jointctl.control.admittance_controller import AdmittanceController
from jointctl.jit import kernel

#: The parameters row: the hardware joint index, the velocity controller's reference slot, the sensor's row in
#: the hardware's wrenches and the force axis (0-2), M [kg], K [N/m], B [N·s/m], the attractor [m], the velocity
#: limit [m/s], the joint state's and the force's sample periods [s] (0: every cycle).
(JOINT, TARGET, SENSOR, AXIS, MASS, STIFFNESS, DAMPING, ATTRACTOR, MAX_VELOCITY, JOINT_STATE_PERIOD,
 FORCE_PERIOD) = range(11)
PARAMETERS = 11
#: The state row: the velocity reference [m/s], the held position [m], velocity [m/s] and force [N], the next
#: joint state and force sample times [s].
VELOCITY_REFERENCE, POSITION, VELOCITY, FORCE, NEXT_JOINT_STATE, NEXT_FORCE = range(6)
STATE = 6


def pack_admittance(c: AdmittanceController) -> tuple[list[float], list[float]]:
    """The parameters and state rows of a started admittance controller."""
    hw = c.hardware
    params = [float(c.index), float(c._target_index), float(hw.sensor_names.index(c.sensor)), float(c.force_index),
              c.mass, c.stiffness, c.damping, c.attractor, c.max_velocity, c.joint_state_period_s, c.force_period_s]
    state = [c.velocity_reference, c.position, c.velocity, c.force, c._next_joint_state_s, c._next_force_s]
    return params, [float(v) for v in state]


def unpack_admittance(c: AdmittanceController, state) -> None:
    """Put an admittance controller's state row back into the controller."""
    c.velocity_reference = float(state[VELOCITY_REFERENCE])
    c.position = float(state[POSITION])
    c.velocity = float(state[VELOCITY])
    c.force = float(state[FORCE])
    c._next_joint_state_s = float(state[NEXT_JOINT_STATE])
    c._next_force_s = float(state[NEXT_FORCE])


@kernel
def admittance_update(parameters, state, c, time_s, period_s, position, velocity, wrench, velocities):
    """``AdmittanceController.update``: the due samples taken (the others held), ``v_ref`` integrated, clamped
    and written into the velocity controller's reference slot of ``velocities``."""
    i = int(parameters[c, JOINT])
    if time_s + 1e-9 >= state[c, NEXT_JOINT_STATE]:
        state[c, POSITION] = position[i]
        state[c, VELOCITY] = velocity[i]
        state[c, NEXT_JOINT_STATE] += parameters[c, JOINT_STATE_PERIOD]
    if time_s + 1e-9 >= state[c, NEXT_FORCE]:
        state[c, FORCE] = wrench[int(parameters[c, SENSOR]), int(parameters[c, AXIS])]
        state[c, NEXT_FORCE] += parameters[c, FORCE_PERIOD]
    f = (parameters[c, STIFFNESS] * (parameters[c, ATTRACTOR] - state[c, POSITION])
         - parameters[c, DAMPING] * state[c, VELOCITY] + state[c, FORCE])
    v_ref = state[c, VELOCITY_REFERENCE] + f / parameters[c, MASS] * period_s
    limit = parameters[c, MAX_VELOCITY]
    v_ref = limit if v_ref > limit else -limit if v_ref < -limit else v_ref
    state[c, VELOCITY_REFERENCE] = v_ref
    velocities[int(parameters[c, TARGET])] = v_ref

"""The compiled cycle: :func:`run_cycles` runs a stretch of the loop's cycles in machine code, each as
:class:`~jointctl.runtime.loop.ControlLoop` runs it in Python, calling the kernels beside the Python they mirror:

1. inputs: each command source's sample fed to its controller's reference (``sources_kernel``,
   ``joint_controllers_kernel``);
2. ``read`` (``mujoco_kernel``);
3. the controllers' updates in the manager's order, upstream first (``joint_state_kernel``,
   ``joint_controllers_kernel``, ``admittance_controller_kernel``, ``cartesian_admittance_controller_kernel``),
   the model feed-forward among them where the manager runs it (``context_kernel``), a trajectory executor first
   (``executor_kernel``);
4. the check for a non-finite command (the loop's: the sum of the commands is not a number);
5. ``write``;
6. observers: the trace row (``trace_kernel``), a video frame (``video_kernel``), the spawned objects' poses
   (``mcap_record_kernel``);
7. ``advance``: the physics steps in C, and the warning check.

The stretch stops early at a cycle whose commands are not finite (after its updates: the loop fails the
controllers in Python and finishes that cycle there), after a step that raised a warning, or after a cycle whose
trajectory supervision decided the goal's end (``executor_kernel``: the Python ends the goal).
"""

from __future__ import annotations

from jointctl.commands.sources_kernel import source_sample
from jointctl.control.admittance_controller_kernel import admittance_update
from jointctl.control.cartesian_admittance_controller_kernel import cartesian_update
from jointctl.control.context_kernel import feedforward_update
from jointctl.control.joint_controllers_kernel import feed_position, feed_velocity, position_update, velocity_update
from jointctl.control.joint_state_kernel import joint_state_update
from jointctl.hardware.mujoco_kernel import mujoco_advance, mujoco_read, mujoco_write
from jointctl.jit import kernel
from jointctl.recording.mcap_record_kernel import track_poses
from jointctl.recording.trace_kernel import trace_due, trace_row
from jointctl.trajectory.executor_kernel import executor_update
from jointctl.visuals.video_kernel import frame_due

#: Controller kinds (and the manager's own update: the model feed-forward); the natural admittance controllers
#: are chained in front of velocity controllers, a trajectory executor in front of position controllers.
JOINT_STATE, POSITION, VELOCITY, FEEDFORWARD, TRAJECTORY = range(5)
ADMITTANCE, CARTESIAN_ADMITTANCE = 10, 11
#: How a stretch ended (``out[STATUS]``): every cycle ran; a cycle's commands were not finite (the cycle
#: ``out[CYCLE]`` is updated, not written); a step raised a warning (the cycle ``out[CYCLE]`` stepped).
DONE, NOT_FINITE, WARNED = range(3)
#: A stretch also ends when the trajectory executor's supervision decided its goal's end at cycle
#: ``out[CYCLE] - 1`` (that cycle run whole: the Python then ends the goal), or when an update cannot be made in
#: machine code (the Cartesian controller's model inertia not positive definite, where the Python raises): the
#: cycle ``out[CYCLE]`` is handed to Python from its update ``out[UPDATE]`` on (that update run in Python again).
DECIDED, HANDED = 3, 4
#: ``out``: where the stretch ended, how, the trace rows, video frames and object poses it kept, and the update a
#: handed cycle goes on from.
CYCLE, STATUS, ROWS, FRAMES, POSES, UPDATE = range(6)


@kernel
def run_cycles(k0, n, period_s,
               model_address, data_address, nstep, qpos, qvel, actuator_force, ctrl, sensordata, warnings,
               qpos_adr, dof_adr, actuator, reduction, sensors, counters, warnings_seen,
               position, velocity, effort, wrench, command,
               feed_parameters, feed_state, feed_tables, feed_controller,
               kinds, parameters, state, latest, references, reference_positions, reference_velocities,
               reference_accelerations,
               trace_on, trace_state, rows, frames_on, frame_state, frames, frame_times,
               track_on, track_state, poses, pose_times, xpos, xquat, bodies,
               out,
               nac_index, nac_parameters, nac_state, nac_addresses, nac_qpos, nac_qpos_adr, nac_dof_adr, nac_jacp,
               nac_jacr, nac_xpos, nac_xmat, nac_q, nac_jv, nac_jr,
               ff_addresses, ff_qpos, ff_qpos_adr, ff_tau, ff_qdd_full, ff_dof_adr, ff_to_model, ff_q, ff_qdd,
               ff_wants_inertia, ff_model_out, ff_gravity, ff_inertia,
               ex_parameters, ex_state, ex_hw_index, ex_ref, ex_path_tolerance, ex_goal_tolerance, ex_times, ex_knots,
               ex_order, ex_coefficients, ex_ends, ex_feedback):
    """Cycles ``k0`` to ``k0 + n - 1`` at ``period_s`` [s] (see the module docstring); ``out`` says how it ended.

    The ``nac_`` arrays are the Cartesian admittance controller's (at most one; see
    :class:`~jointctl.control.cartesian_admittance_controller_kernel.CartesianArrays`), the ``ff_`` ones the model
    feed-forward's, the ``ex_`` ones a trajectory executor's: placeholders without one."""
    kept = 0
    framed = 0
    posed = 0
    joints = command.shape[0]
    for k in range(k0, k0 + n):
        decided = False
        t = k * period_s
        for f in range(feed_parameters.shape[0]):
            value = source_sample(feed_parameters, feed_state, feed_tables, f, t, k - k0)
            c = feed_controller[f]
            if kinds[c] == POSITION:
                feed_position(parameters, state, c, value, reference_positions, reference_velocities,
                              reference_accelerations)
            else:
                feed_velocity(parameters, state, c, value, reference_velocities)
        mujoco_read(qpos, qvel, actuator_force, sensordata, qpos_adr, dof_adr, actuator, reduction, sensors,
                    position, velocity, effort, wrench)
        for c in range(kinds.shape[0]):
            kind = kinds[c]
            if kind == POSITION:
                position_update(parameters, state, c, reference_positions, reference_velocities, references,
                                position, velocity, command, period_s, ff_gravity, ff_inertia)
            elif kind == VELOCITY:
                velocity_update(parameters, state, c, reference_velocities, references, velocity, command, t,
                                period_s)
            elif kind == ADMITTANCE:
                admittance_update(parameters, state, c, t, period_s, position, velocity, wrench, reference_velocities)
            elif kind == CARTESIAN_ADMITTANCE:
                if not cartesian_update(nac_index, nac_parameters, nac_state, nac_addresses, nac_qpos, nac_qpos_adr,
                                        nac_dof_adr, nac_jacp, nac_jacr, nac_xpos, nac_xmat, nac_q, nac_jv, nac_jr, t,
                                        period_s, position, velocity, wrench, reference_velocities):
                    out[CYCLE], out[STATUS], out[ROWS], out[FRAMES], out[POSES] = k, HANDED, kept, framed, posed
                    out[UPDATE] = c
                    return
            elif kind == JOINT_STATE:
                joint_state_update(parameters, state, c, latest, t, position, velocity, effort)
            elif kind == FEEDFORWARD:
                feedforward_update(ff_addresses, ff_qpos, ff_qpos_adr, ff_tau, ff_qdd_full, ff_dof_adr, ff_to_model,
                                   ff_q, ff_qdd, ff_wants_inertia, ff_model_out, position, reference_accelerations,
                                   ff_gravity, ff_inertia)
            elif kind == TRAJECTORY:
                if executor_update(ex_parameters, ex_state, ex_hw_index, ex_ref, ex_path_tolerance, ex_goal_tolerance,
                                   ex_times, ex_knots, ex_order, ex_coefficients, ex_ends, ex_feedback, position,
                                   velocity, reference_positions, reference_velocities, reference_accelerations,
                                   k, t, period_s):
                    decided = True
        total = 0.0
        for j in range(joints):
            total += command[j]
        if total - total != 0.0:  # NaN: a non-finite command somewhere
            out[CYCLE], out[STATUS], out[ROWS], out[FRAMES], out[POSES] = k, NOT_FINITE, kept, framed, posed
            return
        mujoco_write(ctrl, actuator, reduction, command)
        if trace_on and trace_due(trace_state):
            trace_row(rows, kept, t, references, position, velocity, effort, wrench)
            kept += 1
        if frames_on and frame_due(frame_state, t):
            for q in range(qpos.shape[0]):
                frames[framed, q] = qpos[q]
            frame_times[framed] = t
            framed += 1
        if track_on and trace_due(track_state) and bodies.shape[0] > 0:
            track_poses(poses, posed, xpos, xquat, bodies)
            pose_times[posed] = t
            posed += 1
        if mujoco_advance(model_address, data_address, nstep, warnings, counters, warnings_seen):
            out[CYCLE], out[STATUS], out[ROWS], out[FRAMES], out[POSES] = k, WARNED, kept, framed, posed
            return
        if decided:
            out[CYCLE], out[STATUS], out[ROWS], out[FRAMES], out[POSES] = k + 1, DECIDED, kept, framed, posed
            return
    out[CYCLE], out[STATUS], out[ROWS], out[FRAMES], out[POSES] = k0 + n, DONE, kept, framed, posed

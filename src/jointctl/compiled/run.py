"""The compiled run: one call of ``ControlLoop.run`` on the compiled cycle (:mod:`jointctl.compiled.cycle`).

:class:`CompiledRun` packs the loop's parts into arrays from their Python objects, runs the cycles in stretches of
:data:`STRETCH_CYCLES`, and puts every part's state back into its object at the end (and around what runs in
Python between stretches: an object spawned, a goal sent, an executor's event, a goal's end decided in a
stretch), so runs may alternate between the two paths. :mod:`jointctl.compiled.plan` decides which loops run here.
"""

from __future__ import annotations

import numpy as np

from jointctl.commands.sources import ExpressionSource, SourceFeed
from jointctl.control.admittance_controller import AdmittanceController
from jointctl.control.cartesian_admittance_controller import CartesianAdmittanceController
from jointctl.control.context import ModelFeedforward
from jointctl.control.joint_controllers import JointPositionController, JointVelocityController
from jointctl.recording.mcap_record import ObjectTrack
from jointctl.recording.trace import TraceRecorder
from jointctl.runtime.goal_sender import GoalSender
from jointctl.runtime.spawner import ObjectSpawner
from jointctl.trajectory.executor import TrajectoryExecutor
from jointctl.visuals.video import FrameCapture

#: Cycles per compiled stretch: between two stretches the loop can be stopped, and rows reach the trace.
STRETCH_CYCLES = 2000


class CompiledRun:
    """One call of ``ControlLoop.run`` on the compiled path: the loop's parts as arrays, run in stretches.

    The arrays are made from the Python objects (:meth:`pack`) and put back (:meth:`unpack`) at the end of the
    run, and around each object spawned: the spawner runs in Python at its cycle's start (the world is rebuilt),
    then the parts are packed again from the rebuilt world."""

    def __init__(self, loop) -> None:
        from jointctl.compiled import cycle

        self.loop = loop
        self.cycle = cycle
        self.out = np.zeros(6, dtype=np.int64)
        #: The loop's parts as compiled: an edge that changes them while the run goes (a hook added from its
        #: thread) ends the compiled run at the end of the stretch, and the loop goes on in Python.
        self.parts = (loop.inputs, loop.observers, loop.manager.update_calls)
        self.spawners = [hook for hook in loop.inputs if type(hook) is ObjectSpawner]
        self.senders = [hook for hook in loop.inputs if type(hook) is GoalSender]
        self.pack()

    def pack(self) -> None:
        """Make the arrays from the Python objects as they are now."""
        from jointctl.commands.sources_kernel import PARAMETERS as SOURCE_PARAMETERS
        from jointctl.commands.sources_kernel import STATE as SOURCE_STATE
        from jointctl.commands.sources_kernel import pack_source
        from jointctl.control.admittance_controller_kernel import PARAMETERS as ADMITTANCE_PARAMETERS
        from jointctl.control.admittance_controller_kernel import STATE as ADMITTANCE_STATE
        from jointctl.control.admittance_controller_kernel import pack_admittance
        from jointctl.control.context_kernel import FeedforwardArrays
        from jointctl.control.joint_controllers_kernel import PARAMETERS, STATE, pack_position, pack_velocity
        from jointctl.control.joint_state_kernel import pack_joint_state
        from jointctl.hardware.mujoco_kernel import MujocoArrays
        from jointctl.recording.mcap_record_kernel import pack_track
        from jointctl.recording.trace_kernel import pack_trace
        from jointctl.trajectory.executor_kernel import ExecutorArrays
        from jointctl.visuals.video_kernel import pack_frames

        loop, cycle = self.loop, self.cycle
        manager, hw = loop.manager, loop.hardware
        self.hw = MujocoArrays(hw, loop.period_s)
        joints = len(hw.joint_names)
        self.controllers = [call.__self__ for call in manager.update_calls]
        n = len(self.controllers)
        self.kinds = np.zeros(n, dtype=np.int64)
        self.parameters = np.zeros((n, max(PARAMETERS, ADMITTANCE_PARAMETERS)))
        self.state = np.zeros((n, max(STATE, ADMITTANCE_STATE)))
        self.latest = np.zeros((n, 3, joints))
        self.feedforward = FeedforwardArrays(next((c for c in self.controllers if type(c) is ModelFeedforward),
                                                  None))
        self.executor = None
        for k, c in enumerate(self.controllers):
            if type(c) is ModelFeedforward:
                self.kinds[k] = cycle.FEEDFORWARD
                continue
            if type(c) is TrajectoryExecutor:
                self.kinds[k] = cycle.TRAJECTORY
                self.executor = ExecutorArrays(c, loop.period_s)
                continue
            if type(c) is JointPositionController:
                kind, (params, state) = cycle.POSITION, pack_position(c)
            elif type(c) is JointVelocityController:
                kind, (params, state) = cycle.VELOCITY, pack_velocity(c)
            elif type(c) is AdmittanceController:
                kind, (params, state) = cycle.ADMITTANCE, pack_admittance(c)
            elif type(c) is CartesianAdmittanceController:
                kind, (params, state) = cycle.CARTESIAN_ADMITTANCE, ([], [])
            else:
                kind, (params, state) = cycle.JOINT_STATE, pack_joint_state(c)
            self.kinds[k] = kind
            self.parameters[k, :len(params)] = params
            self.state[k, :len(state)] = state
        context = manager.context
        self.references = np.array(manager.references, dtype=float)
        self.reference_lists = (context.reference_positions, context.reference_velocities,
                                context.reference_accelerations)
        self.reference_arrays = tuple(np.array(r, dtype=float) for r in self.reference_lists)
        feeds = [hook for hook in loop.inputs if type(hook) is SourceFeed]
        self.sources = [f.source for f in feeds]
        self.feed_parameters = np.zeros((len(feeds), SOURCE_PARAMETERS))
        self.feed_state = np.zeros((len(feeds), SOURCE_STATE))
        for f, source in enumerate(self.sources):
            self.feed_parameters[f], self.feed_state[f] = pack_source(source)
        self.feed_controller = np.array([self.controllers.index(f.controller) for f in feeds], dtype=np.int64)
        self.tabled = [(f, source) for f, source in enumerate(self.sources) if type(source) is ExpressionSource]
        self.feed_tables = np.zeros((len(feeds), STRETCH_CYCLES if self.tabled else 1))
        self.recorder = next((o for o in loop.observers if type(o) is TraceRecorder), None)
        self.trace_state = np.array(pack_trace(self.recorder) if self.recorder else [0.0, 1.0])
        width = len(self.recorder.columns) if self.recorder else 1
        self.rows = np.zeros((STRETCH_CYCLES if self.recorder else 1, width))
        self.capture = next((o for o in loop.observers if type(o) is FrameCapture), None)
        self.frame_state = np.array(pack_frames(self.capture) if self.capture else [0.0, 1.0])
        self.frames = np.zeros((STRETCH_CYCLES if self.capture else 1, len(self.hw.qpos)))
        self.frame_times = np.zeros(len(self.frames))
        self.track = next((o for o in loop.observers if type(o) is ObjectTrack), None)
        self.track_state = np.array(pack_track(self.track) if self.track else [0.0, 1.0])
        world = hw.world
        self.specs = tuple(self.track.simulation.spawned) if self.track else ()
        self.bodies = np.array([world.model.body(spec.name).id for spec in self.specs], dtype=np.int64)
        samples = STRETCH_CYCLES if self.specs else 1
        self.poses = np.zeros((samples, len(self.specs), 7))
        self.pose_times = np.zeros(samples)
        self.xpos, self.xquat = world.data.xpos, world.data.xquat
        self._pack_cartesian()

    def _pack_cartesian(self) -> None:
        """The Cartesian admittance controller's arrays (placeholders of the same types without one)."""
        from jointctl.control.cartesian_admittance_controller_kernel import (INDEX_ROWS, PARAMETER_ROWS, STATE_ROWS,
                                                                            CartesianArrays)

        c = next((c for c in self.controllers if type(c) is CartesianAdmittanceController), None)
        self.cartesian = CartesianArrays(c) if c is not None else None
        if self.cartesian is not None:
            a, d = self.cartesian, self.cartesian.dynamics
            self.nac_arrays = (a.index, a.parameters, a.state, d.addresses, d.qpos, d.qpos_adr, d.dof_adr, d.jacp,
                               d.jacr, d.xpos, d.xmat, a.q, a.jv, a.jr)
        else:
            none = np.zeros(0, dtype=np.int64)
            self.nac_arrays = (np.zeros((INDEX_ROWS, 9), dtype=np.int64), np.zeros((PARAMETER_ROWS, 9)),
                               np.zeros((STATE_ROWS, 9)), np.zeros(2, dtype=np.uintp), np.zeros(0), none, none,
                               np.zeros((3, 0)), np.zeros((3, 0)), np.zeros((0, 3)), np.zeros((0, 9)), np.zeros(0),
                               np.zeros((3, 0)), np.zeros((3, 0)))

    def _parts_unchanged(self) -> bool:
        loop = self.loop
        inputs, observers, calls = self.parts
        if loop.inputs is inputs and loop.observers is observers and loop.manager.update_calls is calls:
            return True
        loop.mode, loop.mode_reason = "python", "the loop's parts changed while it ran compiled: it went on in Python"
        return False

    def _next_spawn(self, k: int) -> int | None:
        return self._next_cycle(self.spawners, k)

    def _next_cycle(self, inputs, k: int) -> int | None:
        """The first cycle from ``k`` on at which one of the timed ``inputs`` acts (None: none will)."""
        cycles = [c for c in (hook.next_cycle(k, self.loop.period_s) for hook in inputs) if c is not None]
        return min(cycles) if cycles else None

    def _spawn(self, k: int) -> None:
        """Cycle ``k``'s spawners, in Python, with every part's state in its object; then pack again."""
        self.unpack()
        self.loop.cycle = k  # (listeners of the rebuild read loop time)
        t = k * self.loop.period_s
        for spawner in self.spawners:
            spawner(t)
        self.pack()

    def run(self, k: int, end: int) -> tuple[int, bool]:
        """Run cycles from ``k`` to ``end`` (exclusive; -1: until stopped) in stretches; returns the next cycle
        and whether that cycle is half done (updated, its commands not finite: the loop finishes it in Python
        and goes on there). The loop's ``cycle`` follows each stretch; a warning raises PhysicsError with
        ``cycle`` at the cycle whose step raised it, as in Python."""
        loop, cycle, out = self.loop, self.cycle, self.out
        status = cycle.DONE
        try:
            while k != end and not loop._stop_requested and self._parts_unchanged() and self._no_feedback_callback():
                if self._python_needed(k):
                    k = self._python_cycle(k)
                    continue
                spawn = self._next_spawn(k)
                if spawn == k:
                    self._spawn(k)
                    spawn = self._next_spawn(k + 1)
                n = STRETCH_CYCLES if end < 0 else min(STRETCH_CYCLES, end - k)
                if spawn is not None:
                    n = min(n, spawn - k)
                send = self._next_send(k)
                if send is not None:
                    n = min(n, send - k)
                self._fill_tables(k, n)
                hw = self.hw
                cycle.run_cycles(
                    k, n, loop.period_s,
                    hw.model_address, hw.data_address, hw.nstep, hw.qpos, hw.qvel, hw.actuator_force, hw.ctrl,
                    hw.sensordata, hw.warnings, hw.qpos_adr, hw.dof_adr, hw.actuator, hw.reduction, hw.sensors,
                    hw.counters, hw.warnings_seen, hw.position, hw.velocity, hw.effort, hw.wrench, hw.command,
                    self.feed_parameters, self.feed_state, self.feed_tables, self.feed_controller,
                    self.kinds, self.parameters, self.state, self.latest, self.references, *self.reference_arrays,
                    self.recorder is not None, self.trace_state, self.rows,
                    self.capture is not None, self.frame_state, self.frames, self.frame_times,
                    self.track is not None, self.track_state, self.poses, self.pose_times, self.xpos, self.xquat,
                    self.bodies, out, *self.nac_arrays, *self._feedforward_arguments(), *self._executor_arguments())
                stopped_at, status = int(out[cycle.CYCLE]), int(out[cycle.STATUS])
                self._hand_over(int(out[cycle.ROWS]), int(out[cycle.FRAMES]), int(out[cycle.POSES]))
                k = stopped_at
                loop.cycle = k
                self._finish_supervision()
                if status == cycle.HANDED:  # the cycle goes on in Python from the update that could not be made,
                    k, status = self._python_cycle(k, from_update=int(out[cycle.UPDATE])), cycle.DONE
                    break  # and the run after it (the update's failure changed the loop's parts)
                if status not in (cycle.DONE, cycle.DECIDED):
                    break
        finally:
            self.unpack()
        if status == cycle.WARNED:
            loop.hardware._check_warnings()  # raises the warning, as the Python advance does
        return k, status == cycle.NOT_FINITE

    def _fill_tables(self, k: int, n: int) -> None:
        """The expression sources' values over cycles ``k`` to ``k + n - 1``, sampled in Python."""
        from jointctl.commands.sources_kernel import fill_table

        for f, source in self.tabled:
            fill_table(source, self.feed_tables[f], k, n, self.loop.period_s)

    def _next_send(self, k: int) -> int | None:
        return self._next_cycle(self.senders, k)

    def _no_feedback_callback(self) -> bool:
        """False (and the loop goes on in Python) when the active goal delivers its feedback to a callback."""
        goal = self.executor.executor.goals.active if self.executor is not None else None
        if goal is None or goal.on_feedback is None:
            return True
        self.loop.mode = "python"
        self.loop.mode_reason = "a trajectory goal delivers feedback to a callback: the run went on in Python"
        return False

    def _python_needed(self, k: int) -> bool:
        """Whether cycle ``k`` runs in Python: a goal is sent at it, or the executor has an event to take (a goal
        waiting, a stream, a cancel, a hardware fault)."""
        if self._next_send(k) == k:
            return True
        if self.executor is None:
            return False
        ex = self.executor.executor
        goal, plan = ex.goals.active, ex._plan
        return (ex.goals.pending is not None or ex._streamed is not None or ex.hardware.fault is not None
                or (goal is not None and goal.cancel_requested and plan is not None and not plan.stopping))

    def _python_cycle(self, k: int, from_update: int | None = None) -> int:
        """Run cycle ``k`` in Python (:meth:`~jointctl.runtime.loop.ControlLoop.run_cycle`) with every part's state
        in its object; then pack again. ``from_update``: the cycle ran in machine code up to that update, which
        and what follows run here. Returns the next cycle."""
        self.unpack()
        self.loop.cycle = k
        try:
            self.loop.run_cycle(k, from_update=from_update)
        finally:
            self.pack()  # (what the run's end puts back is then the objects' state, also after an error)
        return k + 1

    def _finish_supervision(self) -> None:
        """The goal's end the executor's kernel decided at a cycle of the stretch, made in Python (the decision
        again, the goal's result, the stop) with the state of that cycle's end."""
        arrays = self.executor
        if arrays is None or arrays.decided_cycle is None:
            return
        k = arrays.decided_cycle
        self.unpack()
        ex = arrays.executor
        ex._supervise(k * self.loop.period_s, ex.goals.active, ex._plan)
        self.pack()

    def _executor_arguments(self) -> tuple:
        ex = self.executor
        if ex is None:
            from jointctl.trajectory.executor_kernel import NoExecutor

            ex = NoExecutor()
        return (ex.parameters, ex.state, ex.hw_index, ex.ref, ex.path_tolerance, ex.goal_tolerance, ex.times,
                ex.knots, ex.order, ex.coefficients, ex.ends, ex.feedback)

    def _feedforward_arguments(self) -> tuple:
        ff = self.feedforward
        return (ff.addresses, ff.qpos, ff.qpos_adr, ff.tau, ff.qdd_full, ff.dof_adr, ff.to_model, ff.q, ff.qdd,
                ff.wants_inertia, ff.model_out, ff.gravity, ff.inertia)

    def _hand_over(self, rows: int, frames: int, poses: int) -> None:
        """Give the observers what a stretch kept: trace rows, video frames, object poses."""
        if self.recorder is not None:
            self.recorder.add_block(self.rows[:rows])
        if self.capture is not None:
            from jointctl.visuals.video_kernel import unpack_frames

            unpack_frames(self.capture, self.frame_state, self.frames[:frames], self.frame_times[:frames],
                          self.hw.hardware.world.model)
        if poses:
            from jointctl.recording.mcap_record_kernel import unpack_track

            unpack_track(self.track, self.track_state, self.specs, self.poses[:poses], self.pose_times[:poses])

    def unpack(self) -> None:
        """Put every part's state back into its Python object."""
        from jointctl.commands.sources_kernel import unpack_source
        from jointctl.control.admittance_controller_kernel import unpack_admittance
        from jointctl.control.joint_controllers_kernel import unpack_position, unpack_velocity
        from jointctl.control.joint_state_kernel import unpack_joint_state
        from jointctl.recording.trace_kernel import unpack_trace

        self.hw.unpack()
        names = self.hw.hardware.joint_names
        for c, kind, state, latest in zip(self.controllers, self.kinds, self.state, self.latest):
            if kind == self.cycle.FEEDFORWARD:
                self.feedforward.unpack()
            elif kind == self.cycle.TRAJECTORY:
                self.executor.unpack()
            elif kind == self.cycle.POSITION:
                unpack_position(c, state)
            elif kind == self.cycle.VELOCITY:
                unpack_velocity(c, state)
            elif kind == self.cycle.ADMITTANCE:
                unpack_admittance(c, state)
            elif kind == self.cycle.CARTESIAN_ADMITTANCE:
                self.cartesian.unpack()
            else:
                unpack_joint_state(c, state, latest, names)
        self.loop.manager.references[:] = self.references.tolist()
        for target, values in zip(self.reference_lists, self.reference_arrays):
            target[:] = values.tolist()
        for source, state in zip(self.sources, self.feed_state):
            unpack_source(source, state)
        if self.recorder is not None:
            unpack_trace(self.recorder, self.trace_state)
        if self.track is not None:
            self.track._countdown = int(self.track_state[0])

"""Which loops run compiled.

:func:`compile_loop` is a :class:`~jointctl.runtime.loop.ControlLoop`'s ``compiler``: given the loop about to
run, it returns a :class:`~jointctl.compiled.run.CompiledRun` when every part of the cycle has a compiled form,
else the reason it stays in Python (the first part without one). Parts with a compiled form:

- the hardware: :class:`~jointctl.hardware.mujoco_hardware.MujocoHardware` (not paced to the wall clock);
- controllers: effort ``JointPositionController`` (with any feed-forward: damping, and the model's gravity and
  inertia, the manager's :class:`~jointctl.control.context.ModelFeedforward` update running compiled too; not
  chained except to the executor), ``JointVelocityController`` (with its command watchdog, or chained to an
  admittance controller updated before it), ``JointStateController`` (without subscribers), the natural admittance
  controllers :class:`~jointctl.control.admittance_controller.AdmittanceController` and
  :class:`~jointctl.control.cartesian_admittance_controller.CartesianAdmittanceController` (one, with H diagonal
  or the model's M(q), ``use_model_inertia``), one :class:`~jointctl.trajectory.executor.TrajectoryExecutor` in
  front of position controllers (its cycle between events: the plan sampled, references written, the goal
  supervised; a cycle with an event of the executor's runs in Python, and a goal's end decided in a stretch is made
  in Python after its cycle);
- inputs: a :class:`~jointctl.commands.sources.SourceFeed` of a constant, step, sine, chirp or expression source
  into one of those (an expression evaluated in Python a stretch ahead, a message at a time);
  the scenario's :class:`~jointctl.runtime.spawner.ObjectSpawner` (run in Python at its cycles, between stretches);
  the scenario's :class:`~jointctl.runtime.goal_sender.GoalSender` (its cycles run in Python);
- observers: the :class:`~jointctl.recording.trace.TraceRecorder`, a :class:`~jointctl.visuals.video.FrameCapture`,
  ``run.mcap``'s :class:`~jointctl.recording.mcap_record.ObjectTrack`.

Everything else (a user's controller, the tuning page, ROS, noisy or late hardware) keeps the Python loop; a
goal that gives its feedback to a callback takes the run on in Python. A compiled run takes the Python objects'
state as it is at the start of ``run`` and puts it back at its end, so runs may alternate between the two paths.
"""

from __future__ import annotations

from jointctl.commands.sources import ChirpSource, ConstantSource, ExpressionSource, SineSource, SourceFeed, StepSource
from jointctl.control.admittance_controller import AdmittanceController
from jointctl.control.cartesian_admittance_controller import CartesianAdmittanceController
from jointctl.control.context import ModelFeedforward
from jointctl.control.joint_controllers import JointPositionController, JointVelocityController
from jointctl.control.joint_state_controller import JointStateController
from jointctl.hardware.mujoco_hardware import MujocoHardware
from jointctl.recording.mcap_record import ObjectTrack
from jointctl.recording.trace import TraceRecorder
from jointctl.runtime.goal_sender import GoalSender
from jointctl.runtime.spawner import ObjectSpawner
from jointctl.trajectory.executor import TrajectoryExecutor
from jointctl.visuals.video import FrameCapture

_CONTROLLERS = (JointPositionController, JointVelocityController, JointStateController)
#: Controllers with a compiled form that write velocity controllers' references (chained in front of them).
_UPSTREAM = (AdmittanceController, CartesianAdmittanceController)
_SOURCES = (ConstantSource, StepSource, SineSource, ChirpSource, ExpressionSource)


def _describe(hook) -> str:
    owner = getattr(hook, "__self__", None)
    if owner is not None:
        return f"{type(owner).__name__}.{getattr(hook, '__name__', 'call')}"
    return getattr(hook, "__qualname__", None) or type(hook).__name__


def controller_reason(controller, running=(), upstreams: tuple[str, ...] = ()) -> str | None:
    """Why ``controller`` has no compiled form (None when it has one); ``running``: the controllers updated before
    it that have one (a chained velocity controller has one when its upstream admittance controller is among
    them); ``upstreams``: the trajectory executors running compiled (a position controller may be chained to one)."""
    kind = type(controller)
    if kind in _UPSTREAM:
        return _upstream_reason(controller)
    if kind is TrajectoryExecutor:
        return _executor_reason(controller)
    if kind is JointVelocityController and controller.upstream is not None and any(
            type(c) in _UPSTREAM and c.name == controller.upstream for c in running):
        return None  # chained: its reference written by the upstream's kernel first, its watchdog off
    if kind not in _CONTROLLERS:
        name = getattr(controller, "name", None)
        if name is None:  # an update of the manager's own (the model feed-forward)
            return f"the update {kind.__name__}.update has no compiled form"
        return f"controller {name!r} ({kind.__name__}) has no compiled form"
    what = f"controller {controller.name!r} ({kind.__name__})"
    if controller.upstream is not None and not (kind is JointPositionController and controller.upstream in upstreams):
        return f"{what} is chained to {controller.upstream!r}"
    if kind is JointStateController and controller._subscribers:
        return f"{what} has subscribers"
    return None


def _upstream_reason(controller) -> str | None:
    if type(controller) is CartesianAdmittanceController:
        from jointctl.control.cartesian_admittance_controller_kernel import cartesian_reason

        return cartesian_reason(controller)
    return None


def _executor_reason(executor: TrajectoryExecutor) -> str | None:
    """Why a trajectory executor has no compiled form (None when it has one)."""
    what = f"trajectory executor {executor.name!r}"
    if not executor.downstream:
        return f"{what} commands the joints' position interfaces itself"
    if executor._hands_over():
        return f"{what} hands its goals to the hardware"
    if executor.upstream is not None:
        return f"{what} is chained to {executor.upstream!r}"
    return None


def python_reason(loop) -> str | None:
    """Why ``loop`` runs in Python (None when every part of its cycle has a compiled form)."""
    hw = loop.hardware
    if type(hw) is not MujocoHardware:
        return f"the hardware ({type(hw).__name__}) has no compiled form"
    if loop.clock.realtime:
        return "the loop is paced to the wall clock"
    if hw.command_buffers != (hw._effort_cmd,):
        return "the hardware has command interfaces other than effort"
    running = []
    executors = [owner for owner in (getattr(c, "__self__", None) for c in loop.manager.update_calls)
                 if type(owner) is TrajectoryExecutor]
    if len(executors) > 1:
        return "the loop runs more than one trajectory executor"
    upstreams = tuple(e.name for e in executors)
    for call in loop.manager.update_calls:
        owner = getattr(call, "__self__", None)
        if owner is None or getattr(call, "__func__", None) is not type(owner).update:
            return f"the update {_describe(call)} has no compiled form"
        if type(owner) is ModelFeedforward and loop.manager.context.has_feedforward \
                and owner is loop.manager.context.feedforward and owner.context.hardware is hw:
            continue
        reason = controller_reason(owner, running, upstreams)
        if reason is not None:
            return reason
        running.append(owner)
    if sum(type(c) is CartesianAdmittanceController for c in running) > 1:
        return "the loop has more than one CartesianAdmittanceController"
    for hook in loop.inputs:
        if type(hook) is ObjectSpawner and hook.simulation is hw.simulation:
            continue
        if type(hook) is GoalSender:  # runs in Python at its cycles
            continue
        if type(hook) is not SourceFeed:
            return f"the loop input {_describe(hook)} has no compiled form"
        if type(hook.source) not in _SOURCES:
            return f"the command source {type(hook.source).__name__} of {hook.controller.name!r} has no compiled form"
        if hook.controller not in running or type(hook.controller) is JointStateController:
            return f"the command source feeds {hook.controller.name!r}, which is not running"
        if type(hook.controller) in _UPSTREAM or hook.controller.upstream is not None:
            return f"the command source feeds {hook.controller.name!r}, which takes no command source"
    kinds = [type(hook) for hook in loop.observers]
    for once in (TraceRecorder, FrameCapture, ObjectTrack):
        if kinds.count(once) > 1:
            return f"the loop has more than one {once.__name__}"
    for hook in loop.observers:
        kind = type(hook)
        if kind is TraceRecorder and hook.hardware is hw and hook._references is loop.manager.references:
            continue
        if kind is FrameCapture and hook.world is hw.world:
            continue
        if kind is ObjectTrack and hook.simulation is hw.simulation and (hook.simulation.spawned or not hook._shown):
            continue
        return f"the loop observer {_describe(hook)} has no compiled form"
    return None


def compile_loop(loop):
    """A :class:`~jointctl.compiled.run.CompiledRun` of ``loop``, or the reason (text) it runs in Python."""
    reason = python_reason(loop)
    if reason is not None:
        return reason
    try:
        from jointctl.compiled import cycle  # noqa: F401  (numba and MuJoCo's library)
    except (ImportError, OSError) as exc:  # the Python loop still runs
        return f"the compiled kernels cannot load ({exc})"
    from jointctl.compiled.run import CompiledRun

    return CompiledRun(loop)

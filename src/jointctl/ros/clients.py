"""The chapter's client nodes over ROS 1: each runs in its own process (one rospy node each).

- :func:`sine_command` (``jointctl sine``): the sine commander. Asks
  ``enter displacement amplitude: `` and ``enter freq (in Hz): ``, then publishes at 100 Hz
  ``x = A·sin(2πft) - 0.5`` to ``/<ns>/<joint>_position_controller/command`` and
  ``v = 2πfA·cos(2πft)`` to ``/<ns>/<joint>_velocity_controller/command`` (std_msgs/Float64)
  until Ctrl-C or SIGTERM. The values come from :class:`~jointctl.commands.sources.SineSource`.
- :func:`traj_client_command` (``jointctl traj-client``): the example trajectory client. Sends
  the coarse, irregularly sampled sine (:func:`~jointctl.commands.sine_trajectory.coarse_sine`,
  mapped as ``-0.5 + 0.4·sin(t)`` like ``scenarios/one_dof_trajectory.yaml``) to the
  ``example_trajectory/TrajAction`` server and waits for the result.
- :class:`~jointctl.ros.arm_client.RosGoalSender`: the prompter and playfile
  over ``arm7dof_traj_as/trajAction``; it uses :func:`require_master` and :func:`init_client_node`.
"""

from __future__ import annotations

import math
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import TextIO

import rosgraph
import rospy

from jointctl.errors import JointCtlError

AMPLITUDE_PROMPT = "enter displacement amplitude: "
FREQUENCY_PROMPT = "enter freq (in Hz): "
SINE_RATE_HZ = 100.0
SINE_OFFSET = -0.5
#: The example client's goal, as scenarios/one_dof_trajectory.yaml maps it into the joint's range.
TRAJ_OFFSET = -0.5
TRAJ_AMPLITUDE = 0.4
SERVER_WAIT_S = 20.0


def require_master() -> None:
    """Fail with one clear line when no master answers at ROS_MASTER_URI (rospy would wait forever)."""
    if not rosgraph.Master("/jointctl_client").is_online():
        raise JointCtlError("no ROS master answers (start one, or run 'jointctl serve ...' first)",
                            field="ROS_MASTER_URI", value=rosgraph.get_master_uri())


def init_client_node(name: str) -> None:
    """Join the graph as an anonymous node; Ctrl-C / SIGTERM are left to the caller."""
    require_master()
    rospy.init_node(name, anonymous=True, disable_signals=True)


def stop_on_signals() -> threading.Event:
    """An event set on SIGINT or SIGTERM (the handlers also shut rospy down)."""
    stop = threading.Event()

    def handler(*_):
        stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, handler)
    return stop


# -- the sine commander -----------------------------------------------------------------------

def _ask_number(ask: Callable[[str], str], prompt: str, out: TextIO, *, what: str,
                non_negative: bool = False) -> float:
    while True:
        answer = ask(prompt).strip()
        try:
            value = float(answer)
        except ValueError:
            print(f"not a number: {answer!r}; enter the {what} as a number", file=out, flush=True)
            continue
        if not math.isfinite(value):
            print(f"the {what} must be a finite number, got {answer}", file=out, flush=True)
            continue
        if non_negative and value < 0:
            print(f"the {what} must be 0 or more, got {answer}", file=out, flush=True)
            continue
        return value


def ask_sine(ask: Callable[[str], str] = input, out: TextIO | None = None) -> tuple[float, float]:
    """The commander's two questions: (amplitude, frequency in Hz); bad answers are asked again."""
    out = out or sys.stdout
    amplitude = _ask_number(ask, AMPLITUDE_PROMPT, out, what="amplitude")
    frequency = _ask_number(ask, FREQUENCY_PROMPT, out, what="frequency (Hz)", non_negative=True)
    return amplitude, frequency


def sine_command(*, namespace: str = "one_DOF_robot", joint: str = "joint1") -> int:
    """``jointctl sine``: ask, then publish until Ctrl-C / SIGTERM. Returns the exit status."""
    from std_msgs.msg import Float64

    from jointctl.commands.sources import SineSource

    require_master()
    try:
        amplitude, frequency = ask_sine()
    except EOFError:
        print("\nend of input: nothing published")
        return 0
    position = SineSource(amplitude=amplitude, frequency_hz=frequency, offset=SINE_OFFSET, rate_hz=SINE_RATE_HZ)
    velocity = SineSource(amplitude=amplitude, frequency_hz=frequency, rate_hz=SINE_RATE_HZ, derivative=True)
    stop = stop_on_signals()
    init_client_node("sine_commander")
    ns = f"/{namespace.strip('/')}" if namespace.strip("/") else ""
    pos_topic = f"{ns}/{joint}_position_controller/command"
    vel_topic = f"{ns}/{joint}_velocity_controller/command"
    pos_pub = rospy.Publisher(pos_topic, Float64, queue_size=1)
    vel_pub = rospy.Publisher(vel_topic, Float64, queue_size=1)
    print(f"publishing x = {amplitude:g}·sin(2π·{frequency:g}·t) {SINE_OFFSET:+g} to {pos_topic} and "
          f"its derivative to {vel_topic} at {SINE_RATE_HZ:g} Hz; Ctrl-C to stop", flush=True)
    period = 1.0 / SINE_RATE_HZ
    start = time.monotonic()
    k = 0
    try:
        while not stop.is_set() and not rospy.is_shutdown():
            t = k * period
            pos_pub.publish(Float64(position.sample(t)))
            vel_pub.publish(Float64(velocity.sample(t)))
            k += 1
            # Paced to the wall clock on message times k/rate (no drift); a late loop catches up.
            stop.wait(max(0.0, start + k * period - time.monotonic()))
    finally:
        rospy.signal_shutdown("sine commander stopped")
    print(f"stopped after {k} messages", flush=True)
    return 0


# -- the example trajectory client ------------------------------------------------------------

def traj_client_command(*, seed: int = 7, server: str = "example_traj_action_server",
                        joint: str = "joint1") -> int:
    """``jointctl traj-client``: 0 when the goal succeeds, 1 otherwise."""
    import actionlib
    from actionlib_msgs.msg import GoalStatus
    from example_trajectory.msg import TrajAction, TrajGoal

    from jointctl.ros.conversions import trajectory_to_ros
    from jointctl.commands.sine_trajectory import coarse_sine

    states = {getattr(GoalStatus, n): n for n in ("PENDING", "ACTIVE", "PREEMPTED", "SUCCEEDED", "ABORTED",
                                                 "REJECTED", "PREEMPTING", "RECALLING", "RECALLED", "LOST")}
    trajectory = coarse_sine(joint=joint, seed=seed, offset=TRAJ_OFFSET, amplitude=TRAJ_AMPLITUDE)
    stop = stop_on_signals()
    init_client_node("example_trajectory_action_client")
    try:
        client = actionlib.SimpleActionClient(server, TrajAction)
        if not client.wait_for_server(rospy.Duration(SERVER_WAIT_S)):
            print(f"no action server {rospy.resolve_name(server)} within {SERVER_WAIT_S:g} s", file=sys.stderr)
            return 1
        end_s = trajectory.points[-1].time_from_start_s
        print(f"sending {len(trajectory.points)} points over {end_s:.2f} s (seed {seed}) to "
              f"{rospy.resolve_name(server)}", flush=True)
        feedback = []
        client.send_goal(TrajGoal(trajectory=trajectory_to_ros(trajectory)),
                         feedback_cb=lambda fb: feedback.append(fb.fdbk))
        deadline = time.monotonic() + end_s + 30.0
        while not client.wait_for_result(rospy.Duration(0.1)):
            if stop.is_set() or time.monotonic() > deadline:
                print("canceling the goal", file=sys.stderr)
                client.cancel_goal()
                client.wait_for_result(rospy.Duration(10.0))
                break
        state = states.get(client.get_state(), "?")
        result = client.get_result()
        status = result.rtn_status if result is not None else None
        text = client.get_goal_status_text()
        print(f"feedback messages: {len(feedback)}")
        print(f"result: {state}, rtn_status {status}" + (f" ({text})" if text else ""), flush=True)
        return 0 if state == "SUCCEEDED" and status == 0 else 1
    finally:
        rospy.signal_shutdown("trajectory client done")


__all__ = ["AMPLITUDE_PROMPT", "FREQUENCY_PROMPT", "ask_sine", "init_client_node", "require_master",
           "sine_command", "stop_on_signals", "traj_client_command"]

"""The simulated industrial controller's STOP, in simulated time: from the arm's full speed on every joint,
the interpolator brakes each joint at its deceleration (a stop within 0.2 s) and the stiff servos
(robots/arm7dof/config/arm7dof_servo_params.yaml: 20 rad/s, damping ratio 1 at the largest inertia, the
braking fed forward) bring the joints to rest within 0.5 s, inside their effort limits: the servos' own
commands (the controller's effort, before the simulator clamps what it applies) stay short of each limit
from STOP on. (Getting to full speed is not part of the claim: joint3, damped 1000 N·m·s/rad, asks its whole
500 N·m for a few cycles as it starts.)"""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.hardware.interface import EFFORT
from jointctl.industrial_controller.interpolator import JointLimits, Point
from jointctl.industrial_controller.program import ControllerProgram
from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot

PRE_POSE = (0.0, 1.0, 0.0, -2.0, 0.0, 1.0, 0.0)
STOP_TIME_S = 0.2  # the controller's: a joint at full speed stops within it
STILL_RAD = 1e-4   # "still": less than this in the next 0.5 s
SATURATION_MARGIN = 0.02  # a command within 2 % of the effort limit counts as saturated (Safety's)


@pytest.mark.slow
def test_from_full_speed_the_arm_is_still_within_half_a_second_of_stop() -> None:
    pose = "{" + ", ".join(f"joint{k}: {q}" for k, q in enumerate(PRE_POSE)) + "}"
    session = Session(scenario_for_robot("arm7dof", "servo", [f"initial_positions={pose}"]))
    hardware, robot = session.hardware, session.robot
    names = [j.name for j in robot.movable_joints]
    servos = [session.manager.commanding(n) for n in names]
    index = [hardware.joint_index(n) for n in names]
    limits = JointLimits.from_model(robot, names, stop_time_s=STOP_TIME_S)
    program = ControllerProgram(limits, [hardware.position[i] for i in index])

    def cycle(_time_s: float) -> None:
        for servo, q, v, a in zip(servos, *program.cycle(session.loop.period_s)):
            servo.set_reference(q, v, a)

    commands = hardware.command_buffer(EFFORT)  # the servos' own efforts, before MuJoCo clamps them
    rows = []
    session.loop.add_input(cycle)
    session.loop.add_observer(lambda _t: rows.append([hardware.position[i] for i in index]
                                                     + [commands[i] for i in index]))
    session.run(0.5)  # settled at the pre-pose
    speeds = np.array([lim.velocity for lim in limits])
    program.interpolator.push(Point(tuple(np.array(PRE_POSE) + 3.0 * speeds), 1.0, 3.0))  # 3 s at full speed
    session.run(1.5)
    velocities = np.array([hardware.velocity[i] for i in index])
    assert velocities == pytest.approx(speeds, rel=0.1)  # every joint at (about) its limit when STOP comes
    stopped = len(rows)
    program.interpolator.stop()
    session.run(1.5)

    positions, efforts = np.array(rows)[:, :7], np.array(rows)[:, 7:]
    window = round(0.5 / session.loop.period_s)
    moved_next = np.abs(positions[window:] - positions[:-window]).max(axis=1)  # over the next 0.5 s
    still_at = np.argmax(moved_next[stopped:] < STILL_RAD) * session.loop.period_s
    assert moved_next[stopped:].min() < STILL_RAD and still_at <= 0.5
    assert (moved_next[stopped + round(still_at / session.loop.period_s):] < STILL_RAD).all()  # and stays
    # Inside the limits: the servos never ask for more than their joint's (a command the controller clamps sits
    # at the limit exactly; the simulator clamps what it applies, so its measured effort could not tell).
    effort_limits = np.array([robot.joint(n).limits.effort for n in names])
    peak_share = np.abs(efforts[stopped:]).max(axis=0) / effort_limits
    assert (peak_share < 1 - SATURATION_MARGIN).all(), peak_share

"""Identification from a ros_control robot's joint_states as a subscriber receives them
(tests/identification/joint_state_stream.py): every cycle of a 1 kHz loop, stamped late by the loop's
jitter (0.33 ms), cycles skipped by a busy publisher and two stalls; and the joint_state_controller's
50 Hz, with the catch-up bursts after a stall.

The motion is the elbow of the planar arm ``jointctl init`` writes a folder for, identified in
simulation under its own position loop with every cycle recorded, its references arriving as over a
command topic (as they reach a served robot): rospy hands each one to the loop from its own thread, so
one that comes just after the top of a cycle waits for the next, which then takes two steps at once,
and the loop's derivative on the error kicks the effort by ``∓d·Δ/period`` in those two cycles. The
states of every cycle explain the kicks (the fit in simulation is exact); a 50 Hz sample that holds
one does not.

Truth (tests/planar_arm.py): the elbow's inertia about its axis, the forearm's ``m·l²/12 + m·(l/2)²``,
plus ``dt·b`` (MuJoCo's implicit damping, see plant_fit's docstring), and its damping 0.5 N·m·s/rad.
"""

from __future__ import annotations

import contextlib
import io
import math

import numpy as np
import pytest

from jointctl.cli import main
from jointctl.identification.identify import fit_states, fit_warnings, identify_in_session
from jointctl.model.loader import load_robot_model
from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot
from jointctl.scenario.targets import robot_files
from tests import planar_arm
from tests.identification.joint_state_stream import Timing, joint_state_stream

PERIOD_S = 0.001
JOINT = "elbow"
DAMPING = planar_arm.DAMPING[JOINT]
INERTIA = planar_arm.elbow_inertia_kg_m2() + PERIOD_S * DAMPING
#: The robot's machine: the loop 0.33 ms late on average (never a whole period), the publishing thread
#: stalled 10 ms at 3 s and 45 ms at 6.5 s (the reference's "10 ms gaps seen").
TIMING = Timing(jitter_s=0.33e-3, stalls=((3.0, 0.010), (6.5, 0.045)))

pytestmark = pytest.mark.slow


class CommandTopic:
    """The served loop's side of a command topic: each reference sent reaches the controller at the top
    of the next cycle, or (a share ``late`` of them) one cycle later, together with the next."""

    def __init__(self, deliver, late: float, rng: np.random.Generator) -> None:
        self.deliver, self.late, self.rng = deliver, late, rng
        self.waiting: float | None = None

    def __call__(self, value: float) -> None:
        if self.waiting is not None:
            self.deliver(self.waiting)
            self.waiting = None
        if self.rng.random() < self.late:
            self.waiting = value
        else:
            self.deliver(value)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("streams")
    planar_arm.write_urdf(root)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["init", str(root / "planar_arm.urdf"), "--out", str(root / "arm")]) == 0
    return root / "arm"


def cycles_of(folder, late: float) -> dict:
    """The elbow's identification in simulation with ``late`` of its references a cycle late: every
    cycle's time, every joint's positions and velocities, the elbow's effort; and the in-process fit."""
    files, _ = robot_files(str(folder))
    session = Session(scenario_for_robot(files, "position"))
    controller = session.manager.commanding(JOINT)
    controller.set_reference = CommandTopic(controller.set_reference, late, np.random.default_rng(7))
    hardware = session.hardware
    rows = []
    session.loop.add_observer(lambda t: rows.append((t, *hardware.position, *hardware.velocity,
                                                     hardware.effort[hardware.joint_index(JOINT)])))
    fit, _ = identify_in_session(session, JOINT)
    table = np.array(rows)
    n = len(hardware.joint_names)
    return {"robot": session.robot, "names": hardware.joint_names, "t": table[:, 0],
            "positions": table[:, 1:1 + n], "velocities": table[:, 1 + n:1 + 2 * n], "effort": table[:, -1],
            "fit": fit}


@pytest.fixture(scope="module")
def kicked(folder):
    """5 % of the references late: a kick in a tenth of the cycles."""
    return cycles_of(folder, 0.05)


def received(cycles: dict, publish_rate_hz: float, seed: int):
    """(published cycles, stamps) of the cycles' joint states at ``publish_rate_hz``, and the fit of them."""
    published, stamps = joint_state_stream(cycles["t"].size, PERIOD_S, publish_rate_hz, TIMING,
                                           np.random.default_rng(seed))
    states = fit_states(cycles["robot"], JOINT, cycles["names"], stamps, cycles["positions"][published],
                        cycles["velocities"][published], cycles["effort"][published], loop_period_s=PERIOD_S)
    return published, stamps, states.fit


def test_the_simulated_cycles_identify_the_elbow_exactly(kicked) -> None:
    fit = kicked["fit"]  # every cycle, kicks and all: what the streams below are measured against
    assert fit.inertia == pytest.approx(INERTIA, rel=1e-6) and fit.damping == pytest.approx(DAMPING, rel=1e-6)


def test_every_cycle_stamped_with_the_loops_jitter_identifies_the_elbow(kicked) -> None:
    published, stamps, fit = received(kicked, 1000.0, seed=1)
    steps = np.diff(stamps)
    # The stream is a real robot's: stamps scattered over a quarter of a period (standard deviation), two
    # now and then nearly together (a late cycle, then one on time), cycles skipped, and the stalls.
    assert np.std(stamps - published * PERIOD_S) > 0.25e-3 and steps.min() < 0.2e-3
    assert 0.01 < np.mean(np.diff(published) > 1) < 0.2 and steps.max() > 0.040
    # The period is the loop's (the median step is 4 % long: a skipped cycle is one whose step would
    # have been short), to what the phases of 12 000 stamps jittered by 0.33 ms can say: 0.33 ms·√12 /
    # (13 s·√12 000) = 1e-6 of it.
    assert np.median(steps) > 1.02 * PERIOD_S
    assert fit.sample_period_s == pytest.approx(PERIOD_S, rel=1e-5)
    assert fit.acceleration == "forward" and fit.effort_shift_cycles == kicked["fit"].effort_shift_cycles
    # The stalls are cut, with every step that may hold a skipped cycle (longer than 1.5 periods).
    long_gaps = [(at, length) for at, length in fit.gaps if length > 0.005]
    assert [round(at, 1) for at, _ in long_gaps] == [3.0, 6.5]
    assert fit.share_used > 0.8
    # Each state keeps its cycle's values: the fit is the simulation's but for the rows that span a
    # skipped cycle hidden in the jitter (a step under 1.5 periods holding two: 7 % of the steps skip,
    # a tenth of those hide), whose doubled acceleration puts them off the fit: left out as outliers,
    # but those whose residual is under 1 % of the effort's spread (OUTLIER_FLOOR). Those are at most
    # 1 % of the rows, each off by at most 1 %: 1e-4; the tolerance is ten times that.
    assert fit.outliers > 0
    assert fit.inertia == pytest.approx(INERTIA, rel=1e-3) and fit.damping == pytest.approx(DAMPING, rel=1e-3)
    assert fit_warnings(fit, PERIOD_S) == []


def sampling_bounds(h: float, f_hz: float) -> tuple[float, float]:
    """(inertia, damping) relative error bounds of a fit of states ``h`` [s] apart on a chirp up to
    ``f_hz``: the central difference reads the acceleration (ωh)²/6 short at ω; and a sample's effort
    is that of its cycle, applied up to a cycle off the motion (the fit cannot shift it by less than a
    sample), which moves ``b·dt`` onto the inertia and ``I·ω²·dt`` off the damping."""
    w = 2 * math.pi * f_hz
    truncation = (w * h) ** 2 / 6
    return truncation + DAMPING * PERIOD_S / INERTIA, truncation + INERTIA * w**2 * PERIOD_S / DAMPING


def test_joint_states_at_50_hz_identify_the_elbow_within_their_sampling_bounds(kicked) -> None:
    published, stamps, fit = received(kicked, 50.0, seed=0)
    steps = np.diff(stamps)
    # joint_state_controller's 50 Hz: 19 to 21 cycles apart, and a burst one cycle apart after a stall.
    assert np.median(steps) == pytest.approx(0.020, abs=0.001) and steps.min() < 0.003
    assert fit.sample_period_s == pytest.approx(0.020, rel=1e-4) and fit.acceleration == "central"
    assert fit.effort_shift_cycles == 0  # a shift of one sample would be twenty cycles
    # A tenth of the samples hold a kick, which their motion does not show: they are left out (with the
    # rows whose differences take their velocity), the rest fit as the model does.
    assert fit.outliers > 0.1 * fit.samples and fit.r_squared > 0.99
    inertia_bound, damping_bound = sampling_bounds(0.020, 3.0)  # 3.3 % and 6.2 %
    assert fit.inertia == pytest.approx(INERTIA, rel=inertia_bound)
    assert fit.damping == pytest.approx(DAMPING, rel=damping_bound)
    assert fit_warnings(fit, PERIOD_S) == []


def test_when_most_50_hz_samples_hold_a_kick_the_fit_says_so(folder) -> None:
    # A fifth of the references late: two cycles in five kicked. Most samples are left out and what is
    # left cannot vouch for the figures: the result carries a warning naming the rate and the parameter.
    _, _, fit = received(cycles_of(folder, 0.2), 50.0, seed=0)
    warnings = fit_warnings(fit, PERIOD_S)
    assert fit.left_out > 0.5 * (fit.samples + fit.left_out)
    assert any("the fit rests on fewer than half" in w for w in warnings)
    assert any("publish_rate: 1000" in w for w in warnings)

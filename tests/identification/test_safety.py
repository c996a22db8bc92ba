"""Safe excitation: amplitudes planned inside the limits on the loop model, saturation measured and acted on,
the user's limits watched (the joint brought back when the measured motion crosses one).

Theory for the 1-DOF piston (m 1.01 kg, b 10 N·s/m, p 400 N/m, no d): a reference sine of amplitude A at ω
moves it by A·|T|, T = p/(m s² + b s + p), and asks A·|p·(m s² + b s)/(m s² + b s + p)| on top of its weight
m·g = 9.908 N (which a P loop holds by a droop m·g/p = 24.77 mm). Those are the continuous loop's; the planned
ones are the 1 kHz sampled loop's, which differ by less than 2 % (near the resonance, 3.17 Hz): the tolerance
below. A copy of the piston damped by 2 N·s/m instead of 10 (ζ 0.05: |T| = 1/(2ζ) = 10 at resonance) planned on
a plant file that says 40 N·s/m (ζ 0.995: |T| = 0.5, and an effort |1 - T|·p ≈ 1.1·p instead of 10·p) swings
and pushes about ten times more than planned near 3.17 Hz: more than the 2x margins absorb.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from jointctl.errors import JointCtlError
from jointctl.hardware.interface import EFFORT
from jointctl.identification.frequency_response import bode, measure, measure_in_session
from jointctl.identification.identify import identify_on_robot
from jointctl.identification.plan import plan_bode
from jointctl.identification.plant_fit import IdentificationError
from jointctl.identification.safety import Safety, SafetyStop, UserLimits, envelope_for, parse_workspace
from jointctl.model.loader import load_robot_model
from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot
from tests.identification.variants import DAMPING, G, KP, MASS_KG, one_dof_variant, plant

CONTROLLER = "joint1_position_controller"
SAMPLED = 0.03  # the 1 kHz hold moves |T| and the effort by less than 2 % from the continuous loop's
WEIGHT = MASS_KG * G
DROOP = WEIGHT / KP
ARM_MODEL_ERROR = 1.15  # the arm's joint 5 moves up to 15 % faster than its model (the coupling of the other joints)


def continuous(frequency_hz: float, damping: float = DAMPING) -> tuple[float, float]:
    """(|T|, effort per unit amplitude [N/m]) of the continuous P loop on the piston at ``frequency_hz``."""
    s = 2j * math.pi * frequency_hz
    plant_ = MASS_KG * s * s + damping * s
    return abs(KP / (plant_ + KP)), abs(KP * plant_ / (plant_ + KP))


@pytest.mark.parametrize(("flags", "field"), [
    (dict(max_effort=-5.0), "--max-effort"), (dict(max_effort=0.0), "--max-effort"),
    (dict(max_velocity=math.nan), "--max-velocity"), (dict(max_velocity=math.inf), "--max-velocity"),
    (dict(workspace=(1.0, 0.0)), "--workspace"), (dict(workspace=(0.0, 0.0)), "--workspace"),
])
def test_malformed_user_limits_are_refused_naming_the_flag(flags, field) -> None:
    with pytest.raises(JointCtlError) as info:
        UserLimits(**flags)
    assert info.value.field == field


@pytest.mark.parametrize("text", ["1:0", "abc", "0.5", "-0.6:x", ":", "nan:1"])
def test_a_workspace_must_be_lower_colon_upper(text) -> None:
    with pytest.raises(JointCtlError) as info:
        parse_workspace(text)
    assert info.value.field == "--workspace"
    assert parse_workspace("-0.6:-0.4") == (-0.6, -0.4)


def test_fractions_outside_zero_to_one_are_refused() -> None:
    with pytest.raises(JointCtlError) as info:
        Safety(effort_fraction=1.5)
    assert info.value.field == "effort_fraction"


def test_the_planned_sines_keep_the_loops_effort_within_half_of_max_effort() -> None:
    """The rule against the model: with --max-effort 40 N, each sine's effort (theory) plus the weight is at
    most half of 40 N, and where the effort binds the safe amplitude is the one that makes it half of 40 N;
    its swing at most 0.3 of the room from where it rests (0.5 m less the droop); and above the resonance the amplitude
    shrinks as the effort grows. The timetable simulated on the model (each change of frequency included)
    peaks at the budget, never above: a sine after the resonance is made smaller than its steady state
    allows (by up to a sixth here) for the ringing the change leaves."""
    frequencies = np.logspace(math.log10(0.5), math.log10(20.0), 20)
    plan = plan_bode(scenario_for_robot("one_dof", "position"), CONTROLLER, frequencies,
                     safety=Safety(limits=UserLimits(max_effort=40.0)))
    budget = 0.5 * 40.0
    binding = []
    for row in plan["rows"]:
        t, effort = continuous(row["frequency_hz"])
        a = row["amplitude"]
        assert a * effort + WEIGHT <= budget * (1 + SAMPLED)
        assert a * max(1.0, t) <= 0.3 * (0.5 - DROOP) * (1 + SAMPLED)  # the room where it really rests
        assert row["predicted"]["effort"]["peak"] <= budget * (1 + 1e-9)  # the model's own prediction
        assert a <= row["safe_amplitude"]
        if row["binds"] == "effort":
            binding.append(row["frequency_hz"])
            assert row["safe_amplitude"] * effort + WEIGHT == pytest.approx(budget, rel=SAMPLED)
            assert row["predicted"]["effort"]["peak"] == pytest.approx(budget, rel=0.02)
    assert len(binding) >= 10 and min(binding) < 3.0 < max(binding)
    amplitudes = {row["frequency_hz"]: row["amplitude"] for row in plan["rows"]}
    assert amplitudes[frequencies[-1]] < 0.25 * amplitudes[frequencies[0]]


def test_a_plan_without_a_user_limit_is_bound_by_the_range_where_the_loop_is_gentle() -> None:
    """No --max-effort: the piston's 1000 N leaves the position budget binding: 0.3 of the room from where the
    piston really rests, the droop m·g/p below its reference, over max(1, |T|)."""
    plan = plan_bode(scenario_for_robot("one_dof", "position"), CONTROLLER, [0.5, 20.0])
    for row in plan["rows"]:
        t, _ = continuous(row["frequency_hz"])
        assert row["binds"] == "position"
        assert row["safe_amplitude"] == pytest.approx(0.3 * (0.5 - DROOP) / max(1.0, t), rel=SAMPLED)


def test_the_robot_swept_inside_the_plan_stays_inside_the_effort_budget_and_does_not_saturate() -> None:
    frequencies = [0.5, 1.0, 2.0, 3.17, 5.0, 10.0, 20.0]
    points, context = measure(scenario_for_robot("one_dof", "position"), CONTROLLER, frequencies,
                              safety=Safety(limits=UserLimits(max_effort=40.0)))
    peaks = context["saturation"]["peak_effort"]
    # MuJoCo's robot against the sampled model: within 1 %; the budget is half of 40 N.
    assert max(peaks) <= 20.0 * 1.01
    assert max(peaks) >= 0.9 * 20.0  # and the budget is used, not wasted
    assert all(p.saturation == 0.0 and not p.saturated for p in points)
    assert context["plan"]["effort_limit"] == 40.0


def test_the_arm_swept_with_its_own_limits_stays_inside_them() -> None:
    """The arm's joint 5 (100 N·m, 0.5 rad/s): at the old amplitude (a third of the 3 rad of room, 1 rad) its
    sweep sat at a limit in 64 to 100 % of the cycles. Planned on its model (the other joints held: the
    coupling makes it lighter at high frequencies than its M55, so it moves up to 15 % faster than
    predicted), its peaks stay within the limits, the 2x margin taking the model's error. The effort is the
    controller's command (MuJoCo clamps the force it applies at the limit, so the measured one could not
    exceed it): no more than the plan predicts, less the model's 15 %, inside half the limit (the budget)."""
    session = Session(scenario_for_robot("arm7dof", "position"))
    commands, index = session.hardware.command_buffer(EFFORT), session.hardware.joint_index("joint5")
    commanded: list[float] = []
    session.loop.add_observer(lambda _t: commanded.append(commands[index]))
    points, context = measure_in_session(session, "joint5_position_controller", [0.5, 2.0, 8.0, 20.0])
    plan = context["plan"]
    assert [row["binds"] for row in plan["points"]] == ["velocity"] * 4
    planned = max(row["peak_effort"] for row in plan["points"])
    peak = float(np.abs(commanded).max())
    assert peak <= ARM_MODEL_ERROR * planned <= ARM_MODEL_ERROR * plan["budgets"]["effort"]
    assert plan["budgets"]["effort"] == 0.5 * 100.0
    assert max(context["saturation"]["peak_velocity"]) <= ARM_MODEL_ERROR * plan["budgets"]["velocity"] < 0.5
    assert all(p.saturation == 0.0 for p in points)


def test_a_loop_that_resonates_more_than_its_plant_says_saturates_and_bode_marks_the_point(tmp_path) -> None:
    scenario = one_dof_variant(tmp_path, damping=2.0, effort=40.0)
    result = bode(scenario, CONTROLLER, [0.5, 1.0, 3.17, 10.0], plant=plant(damping=40.0), out_dir=tmp_path / "out")
    shares = dict(zip(result["frequencies_hz"], result["saturation_share"]))
    assert shares[3.17] > 0.01 and result["saturated"][2]
    assert shares[0.5] == shares[1.0] == 0.0 and not result["saturated"][0]
    assert 3.17 in result["saturated_hz"] and 1.0 not in result["saturated_hz"]  # (10 Hz takes the ringing over)
    assert (tmp_path / "out" / "bode.png").stat().st_size > 10_000
    import json

    written = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert written["saturated"] == result["saturated"] and written["amplitudes"] == pytest.approx(result["amplitudes"])


def test_identify_refuses_to_fit_a_saturated_excitation(tmp_path) -> None:
    scenario = one_dof_variant(tmp_path, damping=2.0, effort=40.0)
    with pytest.raises(IdentificationError) as info:
        identify_on_robot(scenario, "joint1", plant=plant(damping=40.0), f_start_hz=2.5, f_end_hz=3.5)
    assert info.value.field == "saturation" and info.value.value > 0.01
    assert "of the cycles at the effort limit 40 N" in str(info.value)


def test_identify_planned_on_the_right_plant_does_not_saturate_and_fits(tmp_path) -> None:
    """The piston with a 40 N limit: the chirp's effort is planned to half of it and measured there."""
    _, metrics = identify_on_robot(one_dof_variant(tmp_path, effort=40.0), "joint1")
    excitation = metrics["excitation"]
    assert excitation["saturation"]["share"] == 0.0 and excitation["binds"] == "effort"
    assert excitation["predicted"]["effort"]["peak"] == pytest.approx(20.0, rel=1e-9)
    assert excitation["saturation"]["peak_effort"] <= 20.0 * 1.01
    assert metrics["mass_kg"] == pytest.approx(MASS_KG + 0.001 * DAMPING, rel=2e-3)


def test_crossing_the_workspace_stops_the_sweep_and_brings_the_joint_back(tmp_path) -> None:
    scenario = one_dof_variant(tmp_path, damping=2.0)
    session = Session(scenario)
    positions: list[float] = []
    session.loop.add_observer(lambda t: positions.append(session.hardware.position[0]))
    hooks = (session.loop.inputs, session.loop.observers)
    with pytest.raises(SafetyStop) as info:
        measure_in_session(session, CONTROLLER, [0.5, 3.17], plant=plant(damping=40.0),
                           safety=Safety(limits=UserLimits(workspace=(-0.7, -0.3))))
    stop = info.value
    assert stop.field == "--workspace" and stop.value == pytest.approx(-0.7, abs=2e-3)
    assert f"at t = {stop.time_s:.3f} s" in str(stop) and "at rest" in str(stop)
    # The 3.17 Hz sine starts after 0.5 s of rest and the 0.5 Hz sine's 12 s (two settling periods, four
    # measured); it crosses while it settles (1.5 s, five whole periods).
    assert 12.5 < stop.time_s < 12.5 + 5 / 3.17
    controller = session.manager.controller(CONTROLLER)
    assert controller.reference == -0.5  # the reference ramped back to where it was
    assert session.hardware.position[0] == pytest.approx(-0.5 - DROOP, abs=1e-3)  # at rest there, drooping
    assert abs(session.hardware.velocity[0]) <= 0.01 * 0.2  # the guard's "at rest": 1 % of the room a second
    assert -1.0 < min(positions) and max(positions) < 0.0  # never beyond the joint's range
    assert (session.loop.inputs, session.loop.observers) == hooks  # the sweep's hooks are gone


def test_crossing_max_velocity_stops_identify(tmp_path) -> None:
    scenario = one_dof_variant(tmp_path, damping=2.0)
    # Planned on ζ 0.5 (|T| 1.15 at most); the robot's ζ 0.05 at 3.17 Hz moves ten times faster.
    with pytest.raises(SafetyStop) as info:
        identify_on_robot(scenario, "joint1", plant=plant(damping=20.0), f_start_hz=3.17, f_end_hz=3.17,
                          safety=Safety(limits=UserLimits(max_velocity=0.2)))
    assert info.value.field == "--max-velocity" and abs(info.value.value) > 0.2
    assert "the joint's speed reached" in str(info.value)


def test_an_amplitude_beyond_the_safe_one_names_the_binding_limit() -> None:
    scenario = scenario_for_robot("one_dof", "position")
    with pytest.raises(IdentificationError) as info:
        bode(scenario, CONTROLLER, [1.0, 20.0], amplitude=0.1, safety=Safety(limits=UserLimits(max_effort=40.0)))
    assert info.value.field == "amplitude" and "--max-effort binds" in str(info.value)
    _, effort = continuous(20.0)
    named = float(str(info.value).split("at most ")[1].split()[0])
    assert named == pytest.approx((20.0 - WEIGHT) / effort, rel=SAMPLED) and "at 20 Hz" in str(info.value)


def test_a_velocity_loops_way_back_drives_the_joint_to_where_it_started() -> None:
    """A stop in a velocity loop: its reference fades out while 1/s times the position error, capped at the
    speed budget, brings the joint back. Here the joint follows its velocity reference exactly (an ideal
    loop, 1 ms steps): from 0.3 rad off, the capped return (0.1 rad/s, half of 0.2) then the exponential
    one (1/s) come back within 1 % of the room, and the guard calls it at rest once the speed has stayed
    under 1 % of the room a second for 0.5 s."""
    from jointctl.identification.safety import Envelope, Guard

    class Joint:
        position, velocity, effort = [0.0], [0.0], [0.0]

    joint = Joint()
    envelope = Envelope("joint", 0.0, -3.0, 3.0, 0.2, math.inf, Safety(limits=UserLimits(workspace=(-0.25, 0.25))))
    guard = Guard(joint, 0, envelope, loop="velocity", start=0.0)
    dt, t, reference = 0.001, 0.0, 0.1
    while not guard.finished and t < 30.0:
        v = guard.reference(t, reference if guard.trip is None else 0.0)
        joint.velocity[0] = v
        joint.position[0] += v * dt
        guard.observe(t)
        t += dt
    assert guard.trip["field"] == "--workspace" and guard.trip["time_s"] == pytest.approx(2.5, abs=2 * dt)
    assert guard.at_rest and abs(joint.position[0]) <= 0.01 * envelope.room
    # The fade (1 s, drifting out 0.05 rad), 0.2 rad back at the capped 0.1 rad/s (2 s), the exponential
    # tail from 0.1 to 0.03 rad (1.2 s) and the 0.5 s at rest: about 5 s, 6.2 s with the blends.
    assert 4.5 < t - guard.trip["time_s"] < 7.5


def test_the_room_is_read_where_a_soft_loop_really_rests(tmp_path) -> None:
    """The yaw/pitch arm's shoulder (1.77 N·m at home, ±2.5 rad) held at 0 by p = 2 N·m/rad: load/p at the
    reference is 0.88 rad, more than 0.3 of the 2.5 rad of room; but the arm droops to where 2·q = 1.77·cos q
    (the load falls as it droops), 0.66 rad, mid-range: the room is read from there, not refused."""
    from scipy.optimize import brentq

    from tests import user_arms

    robot = load_robot_model(user_arms.write(tmp_path, "yaw_pitch_arm"))
    envelope = envelope_for(robot, "shoulder_pitch", 0.0, pose={"base_yaw": 0.0, "shoulder_pitch": 0.0},
                            droop_gain=2.0)
    rest = brentq(lambda q: 2.0 * q - user_arms.SHOULDER_LOAD_NM * math.cos(q), 0.0, 1.5)
    assert envelope.resting_at == pytest.approx(rest, abs=1e-4) and envelope.droop == pytest.approx(rest, abs=1e-4)
    assert envelope.budgets()["position"] == pytest.approx(0.3 * (2.5 - rest), abs=1e-4)
    envelope.check()  # room to move: no refusal


def test_crossing_max_effort_stops_identify_and_brings_the_joint_back(tmp_path) -> None:
    """Planned on ζ 0.5 with --max-effort 40 N (the sine's effort and the 9.9 N weight within half of it), the
    robot's ζ 0.05 at 3.17 Hz swings about ten times more than planned: its effort crosses 40 N (the URDF's
    1000 N and the range far off), the guard stops the chirp and the piston settles back where it rested."""
    scenario = one_dof_variant(tmp_path, damping=2.0)
    with pytest.raises(SafetyStop) as info:
        identify_on_robot(scenario, "joint1", plant=plant(damping=20.0), f_start_hz=3.17, f_end_hz=3.17,
                          safety=Safety(limits=UserLimits(max_effort=40.0)))
    stop = info.value
    assert stop.field == "--max-effort" and abs(stop.value) > 40.0
    assert "the joint's effort reached" in str(stop) and "beyond --max-effort 40" in str(stop)
    assert "at rest" in str(stop) and "still moving" not in str(stop)


class _Joint:
    """One joint's measured state, as a hardware's arrays (index 0)."""

    def __init__(self) -> None:
        self.position, self.velocity, self.effort = [0.0], [0.0], [0.0]


def test_a_joint_that_never_settles_ends_the_way_back_after_the_longest_it_may_take() -> None:
    """A joint that keeps swinging (0.2·sin(π t) rad, whatever its reference) crosses the ±0.1 rad workspace
    at t = 1/6 s; it never comes to rest, so the guard gives up RETURN_MAX_S (10 s) of loop time after the
    stop and says the joint is still moving."""
    from jointctl.identification.safety import RETURN_MAX_S, Envelope, Guard

    joint = _Joint()
    envelope = Envelope("joint", 0.0, -3.0, 3.0, 2.0, math.inf, Safety(limits=UserLimits(workspace=(-0.1, 0.1))))
    guard = Guard(joint, 0, envelope, loop="position", start=0.0)
    dt, k = 0.001, 0
    while not guard.finished and k * dt < 3 * RETURN_MAX_S:
        t = k * dt
        guard.reference(t, 0.0)
        joint.position[0], joint.velocity[0] = 0.2 * math.sin(math.pi * t), 0.2 * math.pi * math.cos(math.pi * t)
        guard.observe(t)
        k += 1
    assert guard.trip["field"] == "--workspace" and guard.trip["time_s"] == pytest.approx(1 / 6, abs=dt)
    assert guard.finished and not guard.at_rest
    assert (k - 1) * dt - guard.trip["time_s"] == pytest.approx(RETURN_MAX_S, abs=dt / 2)
    assert f"still moving {RETURN_MAX_S:g} s after the stop" in str(guard.error())


def _envelope(rest: float, **kwargs):
    from jointctl.identification.safety import Envelope

    kwargs.setdefault("safety", Safety())
    return Envelope("joint1", rest, -1.0, 0.0, 1.0, 1000.0, unit="m", **kwargs)


@pytest.mark.parametrize(("envelope", "field", "words"), [
    (lambda: _envelope(-0.5, safety=Safety(limits=UserLimits(workspace=(-0.3, -0.1)))), "--workspace",
     "outside the workspace"),
    (lambda: _envelope(0.2), "start", "rests outside its range [-1, 0]"),
    (lambda: _envelope(0.0), "start", "rests at a limit: no room"),
    (lambda: _envelope(-0.3, droop=0.1, resting_at=-0.2, safety=Safety(limits=UserLimits(workspace=(-0.9, -0.2)))),
     "start", "rests at -0.2 m, 0.1 from its reference -0.3"),
    (lambda: _envelope(-0.5, bias=500.0), "effort", "takes all of 0.5 of the effort limit 1000"),
    (lambda: _envelope(-0.5, bias=10.0, safety=Safety(limits=UserLimits(max_effort=20.0))), "--max-effort",
     "takes all of 0.5 of the effort limit 20"),
])
def test_an_envelope_that_leaves_nothing_to_excite_is_refused_naming_why(envelope, field, words) -> None:
    """Each refusal of Envelope.check on its own case: the rest outside the workspace, outside the range, at an
    end of the window (0.3 of no room is none; a droop onto the workspace's end too), and a load at rest that
    takes the whole effort budget (0.5 of the URDF's 1000 N, or of a lower --max-effort)."""
    with pytest.raises(IdentificationError) as info:
        envelope().check()
    assert info.value.field == field and words in str(info.value)


def test_an_envelope_with_room_and_effort_left_is_not_refused() -> None:
    _envelope(-0.5, bias=499.0).check()
    _envelope(-0.5, bias=9.9, safety=Safety(limits=UserLimits(max_effort=20.0, workspace=(-0.6, -0.4)))).check()

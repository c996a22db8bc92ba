"""Tests of joint_state_controller/JointStateController: publish timing and samples."""

from __future__ import annotations

import dataclasses
import math

import pytest

from jointctl.control import JointStateController, JointStateSample, controller_types
from jointctl.control.manager import ControllerManager
from jointctl.control.params import Params
from jointctl.errors import ConfigError

from .conftest import NAMESPACE, POSITION_YAML, FakeHardware

TYPE = "joint_state_controller/JointStateController"
LOOP_PERIOD = 0.001


def build(hardware, robot, **definition) -> JointStateController:
    params = Params({"type": TYPE, **definition}, source="test.yaml",
                    field=f"{NAMESPACE}.joint_state_controller")
    c = JointStateController("joint_state_controller", params)
    c.configure(hardware, robot)
    return c


def run(controller: JointStateController, cycles: int, start_cycle: int = 0) -> list[int]:
    """Update at loop times k * period as the loop computes them; the cycles that published."""
    published = []
    for k in range(start_cycle, start_cycle + cycles):
        before = controller.published
        controller.update(k * LOOP_PERIOD, LOOP_PERIOD)
        if controller.published != before:
            published.append(k)
    return published


def test_chapter_yaml_publish_rate_is_50(hardware, robot) -> None:
    manager = ControllerManager(hardware, robot)
    manager.load_file(POSITION_YAML)
    c = manager.load("joint_state_controller")
    assert isinstance(c, JointStateController)
    assert c.publish_rate_hz == 50.0
    assert c.period_s == pytest.approx(0.02)
    assert c.claimed_interfaces() == ()
    assert c.joints == ()


def test_publish_rate_defaults_to_50(hardware, robot) -> None:
    assert build(hardware, robot).publish_rate_hz == 50.0


def test_50_hz_at_1_ms_publishes_every_20_cycles_from_t0(hardware, robot) -> None:
    c = build(hardware, robot, publish_rate=50)
    c.start(0.0)
    times = []
    c.subscribe(lambda s: times.append(s.time_s))
    cycles = run(c, 1000)  # one second: t = 0 .. 0.999
    assert len(cycles) == 50
    assert c.published == 50
    assert cycles == list(range(0, 1000, 20))
    assert times[0] == 0.0
    assert times == pytest.approx([k * 0.02 for k in range(50)])


def test_publishing_does_not_drift_over_a_long_run(hardware, robot) -> None:
    c = build(hardware, robot, publish_rate=50)
    c.start(0.0)
    cycles = run(c, 100_000)  # 100 s
    assert len(cycles) == 5000
    assert all(b - a == 20 for a, b in zip(cycles, cycles[1:]))


def test_accumulated_float_time_still_publishes_50_per_second(hardware, robot) -> None:
    c = build(hardware, robot, publish_rate=50)
    c.start(0.0)
    t = 0.0
    for _ in range(1000):
        c.update(t, LOOP_PERIOD)
        t += LOOP_PERIOD  # drifts by ~1e-13, well inside the controller's tolerance
    assert c.published == 50


@pytest.mark.parametrize("rate", [1, 10, 100, 250, 300, 500, 1000])
def test_count_over_one_second_equals_the_rate(hardware, robot, rate: int) -> None:
    c = build(hardware, robot, publish_rate=rate)
    c.start(0.0)
    cycles = run(c, 1000)
    assert len(cycles) == rate
    assert cycles[0] == 0


def test_start_later_publishes_from_the_start_time(hardware, robot) -> None:
    c = build(hardware, robot, publish_rate=50)
    c.start(0.5)
    cycles = run(c, 100, start_cycle=500)
    assert cycles == [500, 520, 540, 560, 580]


def test_sample_carries_names_and_tuples_of_the_state(robot) -> None:
    hw = FakeHardware(("joint1", "joint2"))
    c = build(hw, robot, publish_rate=50)
    hw.position[:] = [-0.25, 1.5]
    hw.velocity[:] = [0.1, -2.0]
    hw.effort[:] = [3.0, 0.0]
    c.start(0.0)
    c.update(0.0, LOOP_PERIOD)
    s = c.latest
    assert isinstance(s, JointStateSample)
    assert s == JointStateSample(0.0, ("joint1", "joint2"), (-0.25, 1.5), (0.1, -2.0), (3.0, 0.0))
    assert all(type(x) is tuple for x in (s.name, s.position, s.velocity, s.effort))
    # A snapshot: later state changes do not reach a published sample.
    hw.position[0] = -0.9
    assert s.position == (-0.25, 1.5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.position = (0.0, 0.0)  # type: ignore[misc]


def test_latest_is_kept_between_publications(hardware, robot) -> None:
    c = build(hardware, robot, publish_rate=50)
    assert c.latest is None
    c.start(0.0)
    c.update(0.0, LOOP_PERIOD)
    first = c.latest
    hardware.set_state("joint1", -0.3)
    c.update(0.001, LOOP_PERIOD)
    assert c.latest is first
    run(c, 19, start_cycle=2)  # reaches t = 0.020
    assert c.latest is not first
    assert c.latest.time_s == pytest.approx(0.02)
    assert c.latest.position == (-0.3,)


def test_subscribers_receive_every_sample(hardware, robot) -> None:
    c = build(hardware, robot, publish_rate=100)
    got_a: list[JointStateSample] = []
    got_b: list[float] = []
    c.subscribe(got_a.append)
    c.subscribe(lambda s: got_b.append(s.position[0]))
    c.start(0.0)
    for k in range(100):
        hardware.set_state("joint1", -k / 100)
        c.update(k * LOOP_PERIOD, LOOP_PERIOD)
    assert len(got_a) == 10 and len(got_b) == 10
    assert got_a[-1] is c.latest
    assert got_b == pytest.approx([-k / 10 for k in range(10)])


@pytest.mark.parametrize("rate", [0, 0.0, -50, math.inf, math.nan, "50", "fast", None, True])
def test_bad_publish_rate_is_refused(hardware, robot, rate) -> None:
    with pytest.raises(ConfigError) as info:
        build(hardware, robot, publish_rate=rate)
    assert info.value.field == f"{NAMESPACE}.joint_state_controller.publish_rate"
    assert info.value.source == "test.yaml"
    assert info.value.has_value


def test_unknown_key_is_refused(hardware, robot) -> None:
    with pytest.raises(ConfigError) as info:
        build(hardware, robot, publish_rate=50, publish_rat=100)
    assert info.value.field == f"{NAMESPACE}.joint_state_controller.publish_rat"


def test_the_ros2_broadcaster_is_a_joint_state_controller() -> None:
    types = controller_types()
    assert issubclass(types["joint_state_broadcaster/JointStateBroadcaster"], JointStateController)
    assert types[TYPE] is JointStateController

"""--dry-run's plans: made as the run makes them, from the model and the controller file alone."""

from __future__ import annotations

import math
import re

import pytest

from jointctl.identification.identify import identify_on_robot
from jointctl.identification.plan import configured_loop, format_plan, plan_autotune, plan_bode, plan_identify
from jointctl.identification.safety import Safety, UserLimits
from jointctl.model import load_robot_model
from jointctl.scenario.spec import scenario_for_robot


def test_the_identify_plan_is_the_runs_plan() -> None:
    scenario = scenario_for_robot("one_dof", "position")
    plan = plan_identify(scenario, "joint1", f_end_hz=2.0)
    _, metrics = identify_on_robot(scenario, "joint1", f_end_hz=2.0)
    assert metrics["excitation"]["amplitude"] == pytest.approx(plan["excitation"]["amplitude"], rel=1e-12)
    assert metrics["excitation"]["binds"] == plan["binds"] == "position"
    # The piston rests m·g/p below its reference; the windowed chirp's swing about there (its peak near 2 Hz,
    # |T| 1.6) fills 0.3 of the room it has there.
    droop = 1.01 * 9.81 / 400.0
    assert plan["predicted"]["position"]["peak"] == pytest.approx(droop + 0.3 * (0.5 - droop), rel=1e-9)
    assert metrics["excitation"]["position_min"] >= -0.5 - (droop + 0.3 * (0.5 - droop)) * 1.01


def test_the_plan_reads_the_controller_file_with_its_overrides() -> None:
    controller = "controllers.joint1_position_controller"
    scenario = scenario_for_robot("one_dof", "position",
                                  [f"{controller}.pid.p=800", f"{controller}.derivative=measurement"])
    robot = load_robot_model(scenario.robot.description)
    loop = configured_loop(scenario, robot, joint="joint1")
    assert loop["gains"] == {"p": 800.0, "i": 0.0, "d": 0.0} and loop["derivative"] == "measurement"
    assert loop["name"] == "joint1_position_controller" and loop["droops"]
    arm = scenario_for_robot("arm7dof", "position")
    loop = configured_loop(arm, load_robot_model(arm.robot.description), controller="joint1_position_controller")
    assert loop["gains"]["d"] == 50.0 and not loop["droops"]  # gravity feed-forward and an integral hold it


def test_the_printed_plans_say_where_how_much_how_long_and_what_binds() -> None:
    from jointctl.identification.frequency_response import model_plant
    from jointctl.identification.identify import SETTLE_AFTER_S, SETTLE_S

    scenario = scenario_for_robot("one_dof", "position")
    safety = Safety(limits=UserLimits(max_effort=40.0, workspace=(-0.8, -0.2)))
    f_start, f_end, chirp_s = 0.3, 2.5, 8.0
    text = format_plan(plan_identify(scenario, "joint1", safety=safety, f_start_hz=f_start, f_end_hz=f_end,
                                     duration_s=chirp_s))
    # From the scenario, the robot model and the controller file (p 400 N/m, d 0, no feed-forward): the piston
    # rests m·g below where it starts, droops m·g/p under its P loop, and has the workspace's room below.
    start = scenario.initial_positions["joint1"]
    mass, _ = model_plant(load_robot_model(scenario.robot.description), "joint1", {"joint1": start})
    load = mass * 9.81
    for fragment in ("nothing moves", "Joint joint1", f"starting at {start:g} m",
                     f"Chirp {f_start:g} to {f_end:g} Hz over {chirp_s:g} s",
                     f"{SETTLE_S + chirp_s + SETTLE_AFTER_S:g} s with the rests",
                     "window [-0.8, -0.2] m (the workspace)", "limit 40 N (--max-effort)",
                     f"load at rest {load:.4g} N", f"droop {load / 400.0:.3g} m",
                     "Predicted peaks: swing", "Binding limit:"):
        assert fragment in text, fragment
    plan = plan_bode(scenario, "joint1_position_controller", [0.5, 5.0, 20.0], safety=safety)
    text = format_plan(plan)
    assert "3 stepped sines" in text and text.count("effort") >= 3
    assert [row["binds"] for row in plan["rows"]] == ["position", "effort", "effort"]
    plan = plan_autotune(scenario, "joint1_position_controller", bandwidth_hz=5.0, step=0.1)
    text = format_plan(plan)
    # The plan's gains are autotune's own design for the same step (nothing run): the same numbers.
    from jointctl.identification.autotune import autotune

    designed = autotune(lambda o: scenario_for_robot("one_dof", "position", list(o)), "joint1_position_controller",
                        bandwidth_hz=5.0, step=0.1, check_on_robot=False)
    assert plan["gains"] == pytest.approx(designed["gains"], rel=1e-9)
    assert f"Designed gains p {designed['gains']['p']:.4g}" in text
    # ζ 0.7 (autotune's default): the overshoot of a second-order step, exp(-π·ζ / sqrt(1 - ζ²)) = 4.599 %
    # (the design meets it on the sampled loop, printed to 4 digits).
    overshoot = float(re.search(r"overshoot_pct ([\d.]+)", text).group(1))
    assert overshoot == pytest.approx(100 * math.exp(-math.pi * 0.7 / math.sqrt(1 - 0.7**2)), abs=0.005)
    assert "Check step 0.1 m (asked 0.1)" in text and "Check sweep" in text


def test_a_servo_loop_that_is_not_jointctls_is_planned_on_the_reference_alone() -> None:
    plan = plan_bode(scenario_for_robot("one_dof", "industrial"), None, [1.0, 10.0], joint="joint1")
    assert plan["planned_on"] is None
    for row in plan["rows"]:
        assert math.isnan(row["predicted"]["effort"]["peak"])
        assert row["amplitude"] == pytest.approx(min(0.15, 50.0 / (2 * math.pi * row["frequency_hz"])))
    assert "the reference alone" in format_plan(plan)

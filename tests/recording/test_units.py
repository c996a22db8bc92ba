"""Units from the joint type and the SI prefix a figure shows values in."""

from __future__ import annotations

import pytest

from jointctl.model import load_robot_model
from jointctl.paths import robots_dir
from jointctl.recording.units import display_scale, joint_units, label


def test_a_prismatic_joint_moves_in_metres_and_a_revolute_one_in_radians():
    one_dof = load_robot_model(robots_dir() / "one_dof" / "urdf" / "one_dof_robot.xacro")
    arm = load_robot_model(robots_dir() / "arm7dof" / "urdf" / "arm7dof.xacro")
    prismatic, revolute = joint_units(one_dof.joint("joint1")), joint_units(arm.joint("joint3"))
    assert (prismatic.position, prismatic.velocity, prismatic.acceleration, prismatic.effort) == (
        "m", "m/s", "m/s²", "N")
    assert (revolute.position, revolute.velocity, revolute.acceleration, revolute.effort) == (
        "rad", "rad/s", "rad/s²", "N·m")
    assert joint_units(True) == prismatic and joint_units(False) == revolute


@pytest.mark.parametrize("unit, largest, shown, factor", [
    ("m", 0.5, "m", 1.0),              # [0.1, 1000): no prefix
    ("m", 0.1, "m", 1.0),
    ("m", 0.0999, "mm", 1e3),
    ("m", 0.02, "mm", 1e3),
    ("m", 1e-3, "mm", 1e3),
    ("m", 9.99e-4, "µm", 1e6),
    ("rad", 3.3e-4, "µrad", 1e6),
    ("rad", 5e-5, "µrad", 1e6),
    ("rad", 2e-10, "prad", 1e12),
    ("N", 3e-14, "fN", 1e15),          # a fit's residual at rounding level
    ("N", 2e-17, "fN", 1e15),          # the smallest prefix
    ("rad/s", 0.004, "mrad/s", 1e3),
    ("N", 999.0, "N", 1.0),
    ("N", 4800.0, "kN", 1e-3),
    ("N·m", 2.5e6, "MN·m", 1e-6),
    ("N·m", 0.004, "mN·m", 1e3),
    ("m", 4800.0, "m", 1.0),           # no km or krad: a run gone astray keeps its unit
    ("rad", 1500.0, "rad", 1.0),
    ("", 1e-5, "", 1.0),               # dimensionless
    ("m, rad", 1e-5, "m, rad", 1.0),   # joints of both kinds on one axis
    ("m", 0.0, "m", 1.0),
    ("m", float("nan"), "m", 1.0),
])
def test_the_prefix_puts_the_largest_value_in_a_readable_range(unit, largest, shown, factor):
    scale = display_scale(unit, largest)
    assert (scale.shown, scale.unit) == (shown, unit)
    assert scale.factor == pytest.approx(factor)
    assert scale(2.0) == pytest.approx(2.0 * factor)


def test_labels_carry_their_unit():
    assert label("position", "mrad") == "position [mrad]"
    assert label("ratio", "") == "ratio"

"""The world's visible shapes and poses, as the 3D view gets them."""

from __future__ import annotations

import numpy as np
import pytest

from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot
from jointctl.sim.objects import object_from_config
from jointctl.sim.scene_export import geom_poses, visible_ids, visual_geoms
from jointctl.tuning.scene_view import SceneTap


@pytest.fixture
def one_dof():
    with Session(scenario_for_robot("one_dof", "position")) as session:
        yield session


def test_the_visible_shapes_are_the_visuals_and_the_floor_not_the_collision_copies(one_dof) -> None:
    geoms = visual_geoms(one_dof.world.model)
    assert [(g["type"], g["body"]) for g in geoms] == [("plane", "world"), ("box", "link1"), ("cylinder", "link2"),
                                                       ("cylinder", "ft_sensor_link")]
    assert geoms[2]["size"][:2] == [0.1, 0.5]  # link2: radius 0.1 m, half length 0.5 m (the URDF's 1 m)
    assert all(g["rgba"][3] > 0 for g in geoms)


def test_poses_follow_the_joint(one_dof) -> None:
    model, data = one_dof.world.model, one_dof.world.data
    ids = visible_ids(model)
    assert geom_poses(model, data, ids)[3][2] == pytest.approx(2.0 - 0.5 + 0.0025, abs=1e-6)  # disk at q = -0.5 m
    one_dof.run(3.0)  # settled where the P loop holds it against gravity
    disk = geom_poses(model, data, ids)[3]
    assert disk[3:] == pytest.approx([1, 0, 0, 0])
    one_dof.manager.controller("joint1_position_controller").set_reference(-0.3)
    one_dof.run(3.0)
    moved = geom_poses(model, data, ids)[3]
    assert moved[2] - disk[2] == pytest.approx(0.2, abs=0.002)


def test_the_tap_keeps_snapshots_at_its_rate_and_sees_a_spawned_object(one_dof) -> None:
    tap = SceneTap(one_dof.world, rate_hz=10.0)
    one_dof.loop.add_observer(tap)
    one_dof.run(0.55)
    model, poses, time_s, count = tap.snapshot
    assert count == 6 and time_s == pytest.approx(0.5) and len(poses) == 4
    weight = object_from_config({"name": "weight", "shape": "cylinder", "radius_m": 0.05, "length_m": 0.2,
                                 "mass_kg": 10.0, "xyz": [0, 0, 4.0]}, field="drop", source=None, floor=True)
    one_dof.world.spawn(weight)
    one_dof.run(0.2)
    new_model, poses, _, _ = tap.snapshot
    assert new_model is not model and len(poses) == 5
    assert "weight" in [g["body"] for g in SceneTap.scene_message(new_model, None)["geoms"]]
    assert np.isfinite(np.array(poses)).all()

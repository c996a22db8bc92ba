"""The simulated robot of a run: model fields, the payload, and the controllers keeping the nominal model."""

from __future__ import annotations

import math

import pytest
import yaml

from jointctl.errors import ConfigError
from jointctl.model.loader import load_robot_model
from jointctl.model.robot_model import Inertial, Pose
from jointctl.paths import robots_dir
from jointctl.scenario.plant import model_target, payload_link, varied_plant, with_point_mass
from jointctl.scenario.run import run_scenario
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario, read_robot_manifest
from jointctl.scenario.targets import resolve_target
from tests.conftest import ONE_DOF_XACRO

G = 9.81
KP = 400.0


@pytest.fixture(scope="module")
def one_dof():
    return load_robot_model(ONE_DOF_XACRO)


def test_joint_and_link_fields_change_only_what_they_name(one_dof):
    plant = varied_plant(one_dof, {"model.joint1.damping": 13.0, "model.joint1.friction": 2.0,
                                   "model.link2.izz": 0.02})
    assert plant.joint("joint1").damping == 13.0 and plant.joint("joint1").friction == 2.0
    assert plant.link("link2").inertial.inertia[2] == 0.02
    assert plant.link("link2").inertial.mass_kg == one_dof.link("link2").inertial.mass_kg
    assert one_dof.joint("joint1").damping == 10.0  # the nominal model is untouched
    assert plant.link("link1") == one_dof.link("link1") and plant.name == one_dof.name


def test_a_mass_scales_its_links_inertia_and_an_entry_given_beside_it_wins(one_dof):
    nominal = one_dof.link("link2").inertial
    heavier = varied_plant(one_dof, {"model.link2.mass": 3.0}).link("link2").inertial
    assert heavier.mass_kg == 3.0
    assert heavier.inertia == pytest.approx(tuple(3.0 / nominal.mass_kg * i for i in nominal.inertia))
    both = varied_plant(one_dof, {"model.link2.ixx": 0.5, "model.link2.mass": 3.0}).link("link2").inertial
    assert both.inertia[0] == 0.5 and both.inertia[1] == pytest.approx(heavier.inertia[1])


def test_a_point_mass_joins_a_link_by_the_parallel_axis_theorem():
    # A 2 kg link with its centre 0.3 m along x (rotated 90° about z) and a 1 kg point mass at the link's origin.
    inertial = Inertial(2.0, Pose((0.3, 0.0, 0.0), (0.0, 0.0, math.pi / 2)), (0.01, 0.02, 0.03, 0.0, 0.0, 0.0))
    joined = with_point_mass(inertial, 1.0)
    assert joined.mass_kg == 3.0
    assert joined.origin.xyz == pytest.approx((0.2, 0.0, 0.0))  # (2·0.3 + 1·0)/3
    # About the new centre: the link's own tensor turned into the link frame (ixx <-> iyy), plus each mass's
    # m·d² about the axes it is off: 2·0.1² + 1·0.2² = 0.06 about y and z, nothing about x.
    ixx, iyy, izz, ixy, ixz, iyz = joined.inertia
    assert (ixx, iyy, izz) == pytest.approx((0.02, 0.01 + 0.06, 0.03 + 0.06))
    assert (ixy, ixz, iyz) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    alone = with_point_mass(None, 2.0)
    assert alone.mass_kg == 2.0 and min(alone.inertia[:3]) > 0


def test_the_payload_link_is_the_manifests_or_the_last_link(one_dof, tmp_path):
    assert payload_link(one_dof) == "ft_sensor_link" == one_dof.links[-1].name
    assert payload_link(one_dof, {"payload_link": "link2"}) == "link2"
    with pytest.raises(ConfigError, match="did you mean 'link2'") as caught:
        payload_link(one_dof, {"payload_link": "lnk2"}, "robot.yaml")
    assert caught.value.field == "payload_link" and caught.value.source == "robot.yaml"
    plant = varied_plant(one_dof, {}, payload_kg=2.5, payload_at="ft_sensor_link")
    assert plant.link("ft_sensor_link").inertial.mass_kg == pytest.approx(
        one_dof.link("ft_sensor_link").inertial.mass_kg + 2.5)


def test_model_fields_are_named_with_the_nearest_known(one_dof):
    assert model_target(one_dof, "model.joint1.damping") == ("joint", "joint1", "damping")
    assert model_target(one_dof, "model.link2.mass") == ("link", "link2", "mass")
    for field, nearest in (("model.jont1.damping", "joint1"), ("model.joint1.dampng", "damping"),
                           ("model.link2.mas", "mass")):
        with pytest.raises(ConfigError, match=f"did you mean {nearest!r}"):
            model_target(one_dof, field)
    with pytest.raises(ConfigError, match="model.LINK.FIELD"):
        model_target(one_dof, "model.joint1")


def test_the_feed_forward_holds_the_nominal_mass_so_a_payload_droops_by_its_weight_over_kp(tmp_path):
    # Gravity feed-forward from the controllers' model cancels the nominal weight exactly; a payload the model
    # does not know is held by the P term alone: droop = payload·g/Kp (the plant's model would give 0).
    feedforward = "controllers.joint1_position_controller.feedforward={gravity: true}"
    metrics = {p: run_scenario(load_scenario("one_dof_step", [feedforward, "duration_s=8", f"payload_kg={p}"]),
                               tmp_path / str(p), mcap=False)
               for p in (0.0, 2.0)}
    # The final value is the mean of the last 0.8 s; the ringing has decayed by then to e^(-b/(2m)·7 s) of the
    # 0.3 m step: below 3 µm with m = 3.01 kg (2 kg on board), less without.
    assert metrics[0.0]["steady_state_error_m"] == pytest.approx(0.0, abs=1e-5)
    assert metrics[2.0]["steady_state_error_m"] == pytest.approx(2.0 * G / KP, abs=1e-5)
    # The step theory knows the simulated robot and the controllers' model: it expects the same droop (read as the
    # run's is, over the last 0.8 s, where the 0.3 m step still rings by 0.3·e^(-b/(2m)·7.2 s) < 2 µm), and the
    # run's own final value to the model's accuracy.
    assert metrics[2.0]["expected"]["steady_state_error_m"] == pytest.approx(2.0 * G / KP, abs=2e-6)
    assert metrics[2.0]["expected"]["steady_state_error_m"] == pytest.approx(metrics[2.0]["steady_state_error_m"],
                                                                             abs=1e-9)


def test_a_robot_yaml_names_its_payload_link(tmp_path):
    folder = tmp_path / "one_dof"
    folder.mkdir()
    source = robots_dir() / "one_dof"
    manifest = yaml.safe_load((source / "robot.yaml").read_text())
    manifest["description"] = str(source / manifest["description"])
    manifest["controllers"] = {"position": str(source / manifest["controllers"]["position"])}
    manifest["payload_link"] = "link2"
    (folder / "robot.yaml").write_text(yaml.safe_dump(manifest))
    assert read_robot_manifest(folder / "robot.yaml").extras["payload_link"] == "link2"
    scenario = resolve_target(str(folder), overrides=["payload_kg=1"]).scenario
    with Session(scenario) as session:
        assert session.plant.link("link2").inertial.mass_kg == pytest.approx(
            session.robot.link("link2").inertial.mass_kg + 1.0)
        assert session.plant.link("ft_sensor_link") == session.robot.link("ft_sensor_link")
    manifest["payload_link"] = "link9"
    (folder / "robot.yaml").write_text(yaml.safe_dump(manifest))
    with pytest.raises(ConfigError) as caught:
        Session(resolve_target(str(folder), overrides=["payload_kg=1"]).scenario)
    assert caught.value.field == "payload_link" and caught.value.value == "link9"
    assert caught.value.source == str(folder / "robot.yaml")

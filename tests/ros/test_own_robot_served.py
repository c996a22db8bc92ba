"""A user's own robot served on a real ROS graph and measured through it: ``jointctl serve DIR`` (a folder
``jointctl init`` wrote for the planar arm), then identify with no robot named (the model read from the
served ``/robot_description``, the loops' namespace found on the parameter server) and bode with the
folder named."""

from __future__ import annotations

import json
import sys

import pytest

from jointctl.cli import main
from tests import planar_arm
from tests.ros.conftest import run, served_graph

JOINT_STATES = "/planar_arm/joint_states"


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """The planar arm's folder, served with joint states every cycle: (graph env, folder)."""
    root = tmp_path_factory.mktemp("own_robot")
    planar_arm.write_urdf(root)
    assert main(["init", str(root / "planar_arm.urdf"), "--out", str(root / "arm")]) == 0
    with served_graph(root, str(root / "arm"), "--set", "controllers.joint_state_controller.publish_rate=1000",
                      wait_topic=JOINT_STATES) as (graph, _):
        yield graph.env, root / "arm"


def jointctl(env, *args, check=True):
    return run(env, sys.executable, "-m", "jointctl.cli", *map(str, args), timeout=120.0, check=check)


def test_identify_reads_the_served_model_and_finds_the_namespace(served, tmp_path) -> None:
    env, _ = served
    # A small chirp (0.04 rad, at most 0.75 rad/s against the 3 rad/s limit): states that arrive late on a busy
    # machine must not read as speeds at the limit, which the saturation guard would refuse.
    result = jointctl(env, "identify", "--hardware", "ros", "--joint", "elbow", "--duration-s", "4",
                      "--amplitude", "0.04", "--out", tmp_path)
    assert "took the model on /robot_description; its loops on /planar_arm" in result.stderr
    metrics = json.loads(result.stdout)
    # The elbow's inertia about its axis (+ dt·b) and its damping, the shoulder's motion under the
    # elbow's reaction (all joints' states over the graph) taken out by the served model.
    assert metrics["coupling"] == "model" and metrics["data"]["samples_received"] > 1000
    assert metrics["inertia_kg_m2"] == pytest.approx(planar_arm.elbow_inertia_kg_m2() + 0.001 * 0.5, rel=0.03)
    assert metrics["damping_n_m_s_rad"] == pytest.approx(planar_arm.DAMPING["elbow"], rel=0.1)
    assert metrics["excitation"]["rest_after"] == pytest.approx(metrics["excitation"]["rest_before"], abs=2e-3)


def test_bode_takes_the_folder_and_a_missing_namespace_is_named(served, tmp_path) -> None:
    env, folder = served
    result = jointctl(env, "bode", folder, "--hardware", "ros", "--controller", "elbow_position_controller",
                      "--points", "2", "--f-min-hz", "1", "--f-max-hz", "2", "--amplitude", "0.05",
                      "--out", tmp_path / "bode")
    assert f"took {folder} as a robot folder" in result.stderr
    full = json.loads((tmp_path / "bode" / "metrics.json").read_text())
    for measured, modelled in zip(full["gain_db"], full["model"]["gain_db"]):
        assert measured == pytest.approx(modelled, abs=1.0)
    wrong = jointctl(env, "identify", "--hardware", "ros", "--joint", "elbow", "--namespace", "nobody",
                     "--out", tmp_path / "wrong", check=False)
    assert wrong.returncode == 2 and "/nobody" in wrong.stderr
    assert not (tmp_path / "wrong" / "metrics.json").exists()

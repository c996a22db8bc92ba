"""A user's own robot through the command line, as the README walks through it: a planar arm's URDF
(written here, as a user writes one) -> ``jointctl init`` -> ``run``, ``identify``, ``bode`` and
``autotune`` on the folder, on its robot.yaml and on the bare URDF with its controller file."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from jointctl.cli import main
from jointctl.control.manager import read_yaml
from jointctl.model.dynamics import RobotDynamics
from jointctl.model.loader import load_robot_model
from tests import planar_arm


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> Path:
    """A folder holding planar_arm.urdf and the ``arm`` folder ``jointctl init planar_arm.urdf --out arm``
    writes (once for the module: the gains' design is the slow part), and what init printed."""
    root = tmp_path_factory.mktemp("own_robot")
    planar_arm.write_urdf(root)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.chdir(root), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        assert main(["init", "planar_arm.urdf", "--out", "arm"]) == 0
    (root / "init.out").write_text(out.getvalue())
    (root / "init.err").write_text(err.getvalue())
    return root


@pytest.fixture
def folder(written, tmp_path, monkeypatch):
    """A copy of that folder (cwd: tmp_path), for a test to write into."""
    shutil.copytree(written, tmp_path, dirs_exist_ok=True)
    monkeypatch.chdir(tmp_path)
    return tmp_path / "arm"


def test_init_says_what_it_designed_and_what_it_wrote(folder) -> None:
    out, err = (folder.parent / "init.out").read_text(), (folder.parent / "init.err").read_text()
    assert out.splitlines()[0].split() == ["joint", "home", "inertia", "gravity", "limit", "p", "d", "Hz"]
    assert "wrote arm/robot.yaml" in err and "next: jointctl run arm/scenarios/step_shoulder.yaml" in err


def run_json(capsys, *argv) -> tuple[dict, str]:
    assert main(list(argv)) == 0
    out, err = capsys.readouterr()
    return json.loads(out), err


def test_init_writes_a_robot_folder_and_refuses_to_overwrite_it(folder, capsys) -> None:
    manifest = read_yaml(folder / "robot.yaml")
    assert manifest["description"] == "../planar_arm.urdf" and manifest["serve"]["initial_positions"] == {
        "shoulder": 0, "elbow": 0}
    controllers = read_yaml(folder / "config" / "planar_arm_control.yaml")["planar_arm"]
    assert set(controllers) == {"joint_state_controller", "shoulder_position_controller", "elbow_position_controller"}
    assert controllers["elbow_position_controller"]["type"] == "effort_controllers/JointPositionController"
    assert main(["init", "planar_arm.urdf", "--out", "arm"]) == 2
    assert "exists; pass --force" in capsys.readouterr().err
    assert main(["init", "planar_arm.urdf", "--out", "arm", "--force", "--bandwidth-hz", "12"]) == 0


def test_run_holds_the_folders_robot_where_its_loops_balance_gravity(folder, capsys) -> None:
    metrics, err = run_json(capsys, "run", "arm", "--out", "held", "--set", "duration_s=3")
    assert "jointctl: took arm as a robot folder" in err and metrics["duration_s"] == 3.0
    with open("held/trace.csv") as f:
        last = list(csv.DictReader(f))[-1]
    q = np.array([float(last["shoulder.position"]), float(last["elbow.position"])])
    assert abs(float(last["shoulder.velocity"])) < 1e-4  # at rest
    # A P loop at rest balances the load: p·(home - q) = g(q), the model's holding efforts at q.
    gains = read_yaml(folder / "config" / "planar_arm_control.yaml")["planar_arm"]
    p = np.array([gains[f"{j}_position_controller"]["pid"]["p"] for j in ("shoulder", "elbow")])
    dynamics = RobotDynamics(load_robot_model(folder.parent / "planar_arm.urdf"))
    dynamics.set_pose(q)
    np.testing.assert_allclose(p * (0.0 - q), dynamics.gravity_at_pose(), rtol=0.01)
    # The joints sag (+q turns the +x arm downwards about +y), by less than half the design step.
    assert 0.005 < q[0] < 0.05 and 0.005 < q[1] < 0.05


def test_the_bare_urdf_with_its_controller_file_is_the_same_robot(folder, capsys) -> None:
    metrics, err = run_json(capsys, "run", "planar_arm.urdf", "--controllers", "arm/config/planar_arm_control.yaml",
                            "--out", "bare", "--set", "duration_s=0.5")
    assert "took planar_arm.urdf as a robot description (URDF), controllers planar_arm_control.yaml" in err
    assert metrics["duration_s"] == 0.5
    assert main(["run", "planar_arm.urdf", "--out", "none"]) == 2
    assert "--controllers" in capsys.readouterr().err


def test_identify_bode_and_autotune_take_the_folder(folder, capsys) -> None:
    identified, err = run_json(capsys, "identify", "arm/robot.yaml", "--joint", "elbow", "--duration-s", "6",
                               "--out", "identify")
    assert "took arm/robot.yaml as a robot manifest" in err
    # The elbow's inertia about its axis (+ dt·b, MuJoCo's implicit damping) and its damping, the
    # shoulder's motion under the elbow's reaction taken out by the model (the 3 % and 10 %).
    assert identified["coupling"] == "model"
    assert identified["inertia_kg_m2"] == pytest.approx(planar_arm.elbow_inertia_kg_m2() + 0.001 * 0.5, rel=0.03)
    assert identified["damping_n_m_s_rad"] == pytest.approx(planar_arm.DAMPING["elbow"], rel=0.1)

    # Below the shoulder loop's own resonance (sqrt(p/I) ≈ 3 Hz), where the elbow's reaction on the
    # shoulder stays small and the one-joint model holds.
    bode, _ = run_json(capsys, "bode", "arm", "--controller", "elbow_position_controller", "--points", "3",
                       "--f-min-hz", "0.5", "--f-max-hz", "2", "--amplitude", "0.05", "--out", "bode")
    full = json.loads(open("bode/metrics.json").read())
    for measured, modelled in zip(full["gain_db"], full["model"]["gain_db"]):
        assert measured == pytest.approx(modelled, abs=1.0)
    assert bode["controller"] == "elbow_position_controller"

    tuned, err = run_json(capsys, "autotune", "arm", "--controller", "elbow_position_controller", "--bandwidth-hz", "6",
                        "--zeta", "0.7", "--out", "tuned")
    written = read_yaml(tuned["yaml"])["planar_arm"]["elbow_position_controller"]["pid"]
    assert written["p"] == pytest.approx(tuned["gains"]["p"]) and tuned["derivative"] == "error"
    # The promise is the step's: ζ 0.7's 4.6 % at the 0.1 rad step, whose derivative kick the effort limit clamps
    # (so the gains differ from the small-step design, whose bandwidth is 6 Hz: said in the note).
    assert tuned["model"]["overshoot_pct"] == pytest.approx(4.6, abs=0.1) and "kick" in tuned["note"]
    assert tuned["robot"]["step_overshoot_pct"] == pytest.approx(4.6, abs=3.0)
    # On the arm the shoulder's loop (about 3 Hz) takes up part of the elbow's motion: the one-joint
    # design measures less than it promised there.
    assert 0 < tuned["robot"]["bandwidth_hz"] < 6.0 and math.isfinite(tuned["robot"]["step_zeta"])
    # ... and says so, beyond its margin (5 %).
    missed = [w for w in tuned["warnings"] if "bandwidth" in w]
    assert tuned["robot"]["bandwidth_hz"] < 0.95 * 6.0 and missed and f"jointctl: warning: {missed[0]}" in err


def test_inits_step_scenario_runs_its_analysis_against_the_gravity_theory(folder, capsys) -> None:
    metrics, err = run_json(capsys, "run", "arm/scenarios/step_shoulder.yaml", "--out", "step")
    assert "took arm/scenarios/step_shoulder.yaml as a scenario" in err
    # The P loop rests where p·(r - q) balances the load: the theory's sag, measured to 2 %.
    expected = metrics["expected"]["steady_state_error_rad"]
    assert expected < -0.02 and metrics["steady_state_error_rad"] == pytest.approx(expected, rel=0.02)
    assert metrics["settling_time_s"] > 0 and metrics["rise_time_s"] > 0
    # The step is ramped (a step's derivative kick d·step/period would clamp the effort): nothing saturated.
    assert "ramp_s" in read_yaml(folder / "scenarios" / "step_shoulder.yaml")["commands"][
        "shoulder_position_controller"]
    assert metrics["effort_saturated_share_after_step"] == 0.0
    assert not any("limit" in w for w in metrics["warnings"])

"""A user's first real case, through the command line: init on two small arms of their own (tests/user_arms.py),
every step scenario init writes run as written, and autotune's promise held at the user's own step on a loaded
joint, measured again by running the written gains."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
from pathlib import Path

import pytest

from jointctl.cli import main
from jointctl.control.manager import read_yaml
from tests import user_arms

pytestmark = pytest.mark.slow


def call(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    """A folder with both arms' URDFs and the folders init writes for them (cwd-independent paths)."""
    folder = tmp_path_factory.mktemp("user_arms")
    for name, out in (("vertical_arm", "va"), ("yaw_pitch_arm", "yp")):
        urdf = user_arms.write(folder, name)
        code, _, err = call("init", str(urdf), "--out", str(folder / out))
        assert code == 0, err
    return folder


def test_init_writes_a_working_folder_for_an_arm_whose_yaw_damping_beats_the_spec(root) -> None:
    controllers = read_yaml(root / "va" / "config" / "vertical_arm_control.yaml")["vertical_arm"]
    yaw = controllers["base_yaw_position_controller"]
    text = (root / "va" / "config" / "vertical_arm_control.yaml").read_text()
    # d = 0: the yaw's own 2 N·m·s/rad damps it more than ζ 0.7 at 2 Hz; the resulting ζ = b/(2·√(p·I)) said.
    assert yaw["pid"]["d"] == 0.0 and yaw["pid"]["p"] > 0
    inertia = float(text.split("# base_yaw: inertia ")[1].split()[0])
    zeta = user_arms.YAW_DAMPING / (2 * math.sqrt(yaw["pid"]["p"] * inertia))
    assert zeta > 0.7 and f"(ζ {zeta:.3g})" in text
    scenarios = sorted(p.name for p in (root / "va" / "scenarios").iterdir())
    assert scenarios == ["step_base_yaw.yaml", "step_elbow_pitch.yaml", "step_shoulder_pitch.yaml"]


@pytest.mark.parametrize("folder, joint", [("va", "base_yaw"), ("va", "shoulder_pitch"), ("va", "elbow_pitch"),
                                           ("yp", "base_yaw"), ("yp", "shoulder_pitch")])
def test_every_step_scenario_init_writes_runs_without_clamping_the_effort(root, tmp_path, folder, joint) -> None:
    scenario = root / folder / "scenarios" / f"step_{joint}.yaml"
    code, out, err = call("run", str(scenario), "--out", str(tmp_path / "run"))
    assert code == 0, err
    metrics = json.loads(out)
    assert metrics["moving_at_step"] is False and metrics.get("not_settled") is None
    limits = {name: spec["limit"] for name, spec in _limits(root / folder).items()}
    with open(tmp_path / "run" / "trace.csv") as f:
        rows = list(csv.DictReader(f))
    for name, limit in limits.items():
        peak = max(abs(float(row[f"{name}.effort"])) for row in rows)
        # The simulator holds an actuator at its limit: a command that asked more reads exactly the limit.
        assert peak < 0.999 * limit, (name, peak, limit)
    assert "limit" not in " ".join(metrics["warnings"])


def _limits(folder: Path) -> dict:
    text = (folder / "config").glob("*_control.yaml").__next__().read_text()
    found = {}
    for line in text.splitlines():
        if line.strip().startswith("# ") and ": inertia " in line:
            name = line.strip()[2:].split(":")[0]
            found[name] = {"limit": float(line.split("effort limit ")[1].split()[0])}
    return found


STEP = 0.1
OVERSHOOT_PCT, SETTLING_S = 10.0, 0.4


@pytest.mark.parametrize("remedy", ["integral", "feedforward"])
def test_autotunes_promise_holds_at_the_users_step_on_a_loaded_joint(root, tmp_path, remedy) -> None:
    """The shoulder carries 1.77 N·m at home; its step of 0.1 rad with the derivative on the error kicks beyond
    the 15 N·m limit. autotune designs for that step: run again from the written file, the step lands within 3
    points of the overshoot and 15 % of the settling time asked, and ends within 5 % of the step of its
    reference."""
    out = tmp_path / "tuned"
    code, printed, err = call("autotune", str(root / "yp"), "--controller", "shoulder_pitch_position_controller",
                              "--overshoot-pct", str(OVERSHOOT_PCT), "--settling-s", str(SETTLING_S),
                              "--step", str(STEP), "--remedy", remedy, "--out", str(out))
    assert code == 0, err
    tuned = json.loads(printed)
    assert tuned["binds"] == [] and tuned["check_step"] == STEP
    robot = tuned["robot"]
    assert robot["step_overshoot_pct"] == pytest.approx(OVERSHOOT_PCT, abs=3.0)
    assert robot["step_settling_s"] == pytest.approx(SETTLING_S, rel=0.15)
    assert abs(robot["step_final_error"]) <= 0.05 * STEP
    # The same gains, from the written file, on the user's move: a scenario stepping the shoulder by 0.1 rad.
    # The integral charges while the arm holds home (ten of its time constants p/i), as on a robot at rest;
    # the record after the step holds the last tenth the step analysis reads the final value from.
    at = 10 * tuned["gains"]["p"] / tuned["gains"]["i"] if remedy == "integral" else 2.0
    scenario = tmp_path / "step.yaml"
    scenario.write_text(f"""name: shoulder_step
robot: {root / 'yp'}
controller_file: {tuned['yaml']}
start_controllers: [joint_state_controller, base_yaw_position_controller, shoulder_pitch_position_controller]
initial_positions: {{base_yaw: 0, shoulder_pitch: 0}}
duration_s: {at + max(3.0, at / 8)}
commands:
  shoulder_pitch_position_controller: {{type: step, from: 0, to: {STEP}, at: {at}}}
analysis: {{type: step_response, joint: shoulder_pitch}}
""")
    code, printed, err = call("run", str(scenario), "--out", str(tmp_path / "run"))
    assert code == 0, err
    run = json.loads(printed)
    assert run["overshoot_pct"] == pytest.approx(OVERSHOOT_PCT, abs=3.0)
    assert run["settling_time_s"] == pytest.approx(SETTLING_S, rel=0.15)
    assert abs(run["steady_state_error_rad"]) <= 0.05 * STEP


def test_autotune_says_the_gravity_load_binds_and_what_holds_it(root, tmp_path) -> None:
    code, printed, err = call("autotune", str(root / "yp"), "--controller", "shoulder_pitch_position_controller",
                              "--overshoot-pct", str(OVERSHOOT_PCT), "--settling-s", str(SETTLING_S),
                              "--step", str(STEP), "--out", str(tmp_path / "tuned"))
    assert code == 0, err
    tuned = json.loads(printed)
    # Without a remedy the P loop rests load/p short of its reference (measured), beyond the 2 % band: said.
    sag = tuned["robot"]["step_final_error"]
    assert abs(sag) > 0.02 * STEP and tuned["binds"] == ["gravity"]
    assert f"jointctl: warning: at the step of {STEP:g} the spec is not met; binds: the gravity load" in err
    for remedy in ("feedforward", "integral"):
        assert tuned["alternatives"][remedy]["meets"]
        assert f"jointctl: warning: --remedy {remedy}: overshoot" in err

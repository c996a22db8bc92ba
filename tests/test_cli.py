"""The jointctl command as a user runs it: a real process, its output and exit status."""

from __future__ import annotations

import json
import os
import re
import socket
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import step_scenario

JOINTCTL = [sys.executable, "-m", "jointctl.cli"]


def jointctl(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run([*JOINTCTL, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=300)


def assert_one_line_error(result: subprocess.CompletedProcess, *fragments: str) -> None:
    assert result.returncode == 2, result.stderr
    # The line saying what the target was taken for may come first: the error is one line of its own.
    lines = [line for line in result.stderr.strip().splitlines() if not line.startswith("jointctl: took ")]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("jointctl: error: ")
    assert "Traceback" not in result.stderr
    for fragment in fragments:
        assert fragment in lines[0]


def test_list_names_the_robot_and_scenarios():
    result = jointctl("list")
    assert result.returncode == 0
    for name in ("one_dof", "one_dof_step", "one_dof_sine", "one_dof_velocity_sine"):
        assert name in result.stdout


#: Debian's own packages (ROS 1's rospy and actionlib, and its numpy 1.24, which tf2 pulls in).
DEBIAN_PACKAGES = Path("/usr/lib/python3/dist-packages")


def test_a_ros_users_pythonpath_does_not_shadow_the_environments_packages(tmp_path):
    # A ROS user's shell: a sourced catkin workspace chains to Debian's ROS, so PYTHONPATH holds the
    # workspace's devel space (its messages) and Debian's dist-packages, ahead of the environment's
    # site-packages. The console script must still run on the environment's numpy, and import rospy and the
    # workspace's messages from where PYTHONPATH says.
    if not (DEBIAN_PACKAGES / "numpy").is_dir() or not (DEBIAN_PACKAGES / "rospy").is_dir():
        if os.environ.get("JOINTCTL_REQUIRE_ROS"):
            pytest.fail(f"JOINTCTL_REQUIRE_ROS is set but Debian's numpy or rospy is not in {DEBIAN_PACKAGES}")
        pytest.skip(f"Debian's numpy and rospy are not installed in {DEBIAN_PACKAGES} (make ros)")
    devel = tmp_path / "devel" / "lib" / "python3" / "dist-packages"
    (devel / "my_robot_msgs").mkdir(parents=True)
    (devel / "my_robot_msgs" / "__init__.py").write_text("")
    source = Path(__file__).resolve().parents[1] / "src"  # this checkout's jointctl, first as in a developer's shell
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=f"{source}:{devel}:{DEBIAN_PACKAGES}")
    script = Path(sys.executable).with_name("jointctl")
    result = subprocess.run([str(script), "list"], capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == 0, result.stderr
    assert "one_dof" in result.stdout
    probe = ("import json, jointctl, numpy, rospy, my_robot_msgs; print(json.dumps([m.__file__ for m in "
             "(jointctl, numpy, rospy, my_robot_msgs)]))")
    found = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=120)
    assert found.returncode == 0, found.stderr
    jointctl_file, numpy_file, rospy_file, messages_file = map(Path, json.loads(found.stdout))
    assert jointctl_file.is_relative_to(source)
    assert numpy_file.is_relative_to(sys.prefix) and not numpy_file.is_relative_to(DEBIAN_PACKAGES)
    assert rospy_file.is_relative_to(DEBIAN_PACKAGES)
    assert messages_file.is_relative_to(devel)


def test_run_writes_trace_metrics_and_figures(tmp_path):
    result = jointctl("run", "one_dof_step", "--out", tmp_path / "step", "--set", "duration_s=1.5")
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "step" / "metrics.json").read_text())
    assert json.loads(result.stdout)["natural_frequency_rad_s"] == metrics["natural_frequency_rad_s"]
    assert {"trace.csv", "metrics.json", "position.png", "effort.png", "run.mcap"} <= {
        p.name for p in (tmp_path / "step").iterdir()}


def test_run_with_gravity_and_gain_overrides(tmp_path, write_scenario):
    scenario = write_scenario(step_scenario(duration_s=1.5, analysis={"type": "step_response", "joint": "joint1"}))
    result = jointctl("run", scenario, "--out", tmp_path / "o", "--set", "gravity=-5",
                      "--set", "controllers.joint1_position_controller.pid.p=8e2")  # YAML 1.2's number
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert metrics["steady_state_error_m"] == pytest.approx(1.01 * 5 / 800, rel=0.01)


@pytest.mark.parametrize(("args", "fragments"), [
    (["run", "one_dof_step", "--set", "controllers.joint1_position_controller.pid.p=-5"],
     ["one_dof_pos_ctl_params.yaml", "one_DOF_robot.joint1_position_controller.pid.p", "-5"]),
    (["run", "one_dof_step", "--set", "controllers.joint1_position_controller.pid.d=.nan"],
     ["pid.d", "nan"]),
    (["run", "one_dof_step", "--set", "controllers.joint1_position_controller.type=foo/Bar"],
     ["joint1_position_controller.type", "foo/Bar"]),
    (["run", "one_dof_step", "--set", "controllers.joint1_position_controller.joint=joint7"],
     ["joint1_position_controller.joint", "joint7"]),
    (["run", "one_dof_step", "--set", "gravity=sideways"], ["one_dof_step.yaml", "gravity", "sideways"]),
    (["run", "one_dof_step", "--set", "nonsense"], ["--set", "nonsense"]),
    (["run", "no_such_scenario"], ["no_such_scenario"]),
    (["run", "one_dof_step", "--speed", "0"], ["--speed"]),
])
def test_bad_input_is_one_line_with_exit_code_2(args, fragments, tmp_path):
    assert_one_line_error(jointctl(*args, "--out", tmp_path / "o") if args[0] == "run" and "--out" not in args
                          else jointctl(*args), *fragments)
    assert not (tmp_path / "o" / "trace.csv").exists()


def test_a_good_run_writes_its_trace_where_the_refused_ones_are_checked(tmp_path):
    result = jointctl("run", "one_dof_step", "--set", "duration_s=1.0", "--out", tmp_path / "o")
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "o" / "trace.csv").exists()


def test_unsafe_expression_is_refused(tmp_path, write_scenario):
    cmd = {"type": "expression", "expression": "__import__('os').system('true')", "rate_hz": 100}
    scenario = write_scenario(step_scenario(commands={"joint1_position_controller": cmd}))
    assert_one_line_error(jointctl("run", scenario, "--out", tmp_path / "o"),
                          str(scenario), "commands.joint1_position_controller.expression", "__import__")


def test_missing_and_malformed_files(tmp_path, write_scenario):
    assert_one_line_error(jointctl("run", tmp_path / "absent.yaml"), "absent.yaml")
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("robot: [one_dof\n")
    assert_one_line_error(jointctl("run", bad_yaml), "bad.yaml", "not valid YAML")
    bad_controllers = tmp_path / "gains.yaml"
    bad_controllers.write_text("one_DOF_robot:\n  joint1_position_controller: {type: 3\n")
    scenario = write_scenario(step_scenario(controller_file=str(bad_controllers)))
    assert_one_line_error(jointctl("run", scenario), "gains.yaml", "not valid YAML")
    missing_xacro = write_scenario(step_scenario(robot=str(tmp_path / "nothere.xacro")), "s2.yaml")
    assert_one_line_error(jointctl("run", missing_xacro), "robot", "nothere.xacro")
    bad_xacro = tmp_path / "bad.xacro"
    bad_xacro.write_text('<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                         '<link name="${undefined_property}"/></robot>')
    from tests.conftest import POSITION_YAML
    scenario = write_scenario(step_scenario(robot=str(bad_xacro), controller_file=str(POSITION_YAML)), "s3.yaml")
    assert_one_line_error(jointctl("run", scenario), "bad.xacro", "xacro failed")


#: The built-in experiments (scenarios with an analysis); arm7dof_streamer is a robot to drive.
EXPERIMENTS = ("arm7dof_nac_catch", "arm7dof_pose", "minimal_robot_trajectory", "one_dof_drop_weight",
               "one_dof_nac_drop", "one_dof_sine", "one_dof_step", "one_dof_trajectory", "one_dof_velocity_sine")


def test_demo_runs_every_experiment_with_a_video_and_reports_each(tmp_path, monkeypatch):
    # In-process, with the runs stubbed: which scenarios `jointctl demo` runs, and how. Each experiment
    # is run for real by its own test (tests/scenario), the report of real runs by the next test.
    import jointctl.scenario.run as run_module
    from jointctl.cli import main

    ran = []

    def run_scenario(scenario, out, *, video=None, **kwargs):
        ran.append((scenario.name, video))
        return {"scenario": scenario.name, "a_metric": 1.5, "expected": {"a_metric": 1.5}}

    monkeypatch.setattr(run_module, "run_scenario", run_scenario)
    # The report's sweep, stubbed too (run for real by tests/sweep/test_demo.py): it is the report's last section.
    monkeypatch.setattr("jointctl.sweep.demo.demo_section", lambda out: "## Sweep: stubbed\n")
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 0
    assert sorted(name for name, _ in ran) == sorted(EXPERIMENTS)
    assert all(video is run_module.DEMO_VIDEO for _, video in ran)  # a video of each experiment
    report = (tmp_path / "demo" / "report.md").read_text()
    assert all(f"## {name}\n" in report for name in EXPERIMENTS)
    assert "## arm7dof_streamer" not in report and report.count("| a_metric | 1.5 | 1.5 |") == len(EXPERIMENTS)
    assert report.endswith("## Sweep: stubbed\n")


def test_demo_report_of_two_experiments_links_their_figures_and_videos(tmp_path):
    # Two representative experiments, run for real: both robots and their cameras, a spawned object
    # (frames of two models in one video), metrics with and without expected values.
    from jointctl.scenario.run import run_demo

    experiments = {"one_dof_drop_weight": "position.png", "arm7dof_pose": "uncompensated_droop.png"}
    report = run_demo(tmp_path / "demo", names=list(experiments)).read_text()
    for name, figure in experiments.items():
        assert f"## {name}" in report
        assert f"]({name}/{figure})" in report
        assert f"![{name}: the run]({name}/video.gif)" in report
        assert (tmp_path / "demo" / name / "video.gif").stat().st_size > 10_000
    assert "| metric | measured | expected | difference |" in report
    # (1 + 0.01 + 10) kg at 5 m/s² measured, the same expected beside it, and their difference
    assert re.search(r"\| steady_effort_n \| 55\.0\d \| 55\.05 \| [+-]0\.\d\d % \|", report), report


@pytest.mark.parametrize("args, fragments", [
    (["--host", "0.0.0.0"], ["--host", "needs --allow-remote", "0.0.0.0"]),
    (["--port", "70000"], ["--port", "0 to 65535"]),
    (["--speed", "0"], ["--speed", "must be positive"]),
    (["--controllers", "fast"], ["--controllers", "fast"]),
])
def test_tune_refuses_bad_options_in_one_line(args, fragments):
    assert_one_line_error(jointctl("tune", "one_dof", *args), *fragments)


@pytest.mark.wall_clock
def test_tune_warns_when_listening_beyond_loopback(tmp_path):
    process = subprocess.Popen([*JOINTCTL, "tune", "one_dof", "--host", "0.0.0.0", "--allow-remote", "--port", "0",
                                "--out", str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()
        assert line.startswith("jointctl: tuning one_DOF_robot at http://0.0.0.0:")
    finally:
        process.terminate()
        _, err = process.communicate(timeout=10)
    assert "warning: listening on 0.0.0.0: anyone who can reach it can change gains and move the robot" in err


@pytest.mark.parametrize("args, fragments", [
    (["--motion-port", "70000"], ["motion_port", "70000"]),
    (["--state-rate-hz", "0"], ["state_rate_hz", "0"]),
    (["--controllers", "velocity"], ["joint1", "JointPositionController"]),
    (["--speed", "-1"], ["--speed"]),
])
def test_controller_refuses_bad_options_in_one_line(args, fragments):
    assert_one_line_error(jointctl("controller", "one_dof", "--state-port", "0", *args), *fragments)


@pytest.mark.wall_clock
def test_controller_says_where_it_listens_and_stops_cleanly_on_sigterm():
    process = subprocess.Popen([*JOINTCTL, "controller", "one_dof", "--motion-port", "0", "--state-port", "0",
                                "--big-endian"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()
        assert line.startswith("jointctl controller: one_dof (joints joint1) on 0.0.0.0, motion port ")
        assert line.rstrip().endswith("big-endian")
        state_port = int(line.split("state port ")[1].split(",")[0])
        with socket.create_connection(("127.0.0.1", state_port), timeout=10) as state:
            assert state.recv(4) == struct.pack(">i", 56)  # a JOINT_POSITION's length prefix, big-endian
    finally:
        process.terminate()
        _, err = process.communicate(timeout=10)
    assert process.returncode == 0, err


def test_identify_writes_metrics_and_reads_its_own_trace_back(tmp_path):
    result = jointctl("identify", "one_dof", "--joint", "joint1", "--duration-s", "6", "--out", tmp_path / "a")
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "a" / "metrics.json").read_text())
    assert metrics["mass_kg"] == pytest.approx(1.01, rel=0.02)
    again = jointctl("identify", tmp_path / "a" / "trace.csv", "--joint", "joint1", "--robot", "one_dof",
                     "--out", tmp_path / "b")
    assert again.returncode == 0, again.stderr
    assert json.loads((tmp_path / "b" / "metrics.json").read_text())["mass_kg"] == pytest.approx(metrics["mass_kg"])


def test_identify_reports_a_poor_fit_with_its_warning(tmp_path):
    # A recorded joint whose effort is mostly noise (a torque reading three times noisier than the swing
    # it should explain): the fit is reported, and says it is poor in metrics.json and in the result printed.
    import numpy as np

    rng = np.random.default_rng(2)
    t = np.arange(0.0, 6.0, 0.001)
    qd = 0.3 * 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * t)
    q = 0.3 * np.sin(2 * np.pi * 0.7 * t)
    effort = np.append(np.diff(qd) / 0.001, 0.0) + 10.0 * qd + 9.81
    effort += rng.normal(0.0, 3.0 * np.std(effort), t.size)
    trace = tmp_path / "trace.csv"
    np.savetxt(trace, np.column_stack([t, q, qd, effort]), delimiter=",", comments="",
               header="time_s,joint1.position,joint1.velocity,joint1.effort")
    result = jointctl("identify", trace, "--joint", "joint1", "--joint-type", "prismatic", "--out", tmp_path / "o")
    assert result.returncode == 0, result.stderr
    printed = json.loads(result.stdout)
    assert printed["r_squared"] < 0.95
    assert any(w.startswith("a poor fit") for w in printed["warnings"])
    assert json.loads((tmp_path / "o" / "metrics.json").read_text())["warnings"] == printed["warnings"]
    assert "jointctl: warning: a poor fit" in result.stderr


@pytest.mark.parametrize("args, fragments", [
    (["one_dof", "--joint", "joint1", "--amplitude", "1"], ["amplitude", "at most 0.1101", "range binds", "about where it rests", "1.0"]),
    (["one_dof", "--joint", "joint7"], ["--joint", "joint7"]),
    (["one_dof", "--joint", "joint1", "--controllers", "velocity"], ["JointPositionController"]),
    (["trace.csv", "--joint", "joint1"], ["--joint-type"]),
    (["run.bag", "--joint", "joint1"], ["--joint-type"]),
    (["one_dof", "--joint", "joint1", "--hardware", "industrial"], ["--hardware", "no joint efforts", "bode"]),
    (["my_robot.urdf", "--joint", "joint1", "--hardware", "ros"], ["no such robot description file", "my_robot.urdf"]),
])
def test_identify_refuses_bad_input_in_one_line(args, fragments, tmp_path):
    assert_one_line_error(jointctl("identify", *args, "--out", tmp_path / "o"), *fragments)
    assert not (tmp_path / "o" / "metrics.json").exists()


def test_bode_writes_its_figure_and_metrics(tmp_path):
    result = jointctl("bode", "one_dof", "--controller", "joint1_position_controller", "--points", "6",
                      "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert len(metrics["gain_db"]) == 6 and metrics["model"]["mass"] == pytest.approx(1.01)
    assert (tmp_path / "bode.png").is_file()


@pytest.mark.parametrize("args, fragments", [
    (["--controller", "joint9_position_controller"], ["--controller", "joint9_position_controller"]),
    (["--controller", "joint1_position_controller", "--f-min-hz", "30"], ["--f-min-hz", "30"]),
    (["--controller", "joint1_position_controller", "--points", "1"], ["--points", "1"]),
    (["--controller", "joint1_position_controller", "--plant", "missing.json"], ["--plant", "missing.json"]),
])
def test_bode_refuses_bad_input_in_one_line(args, fragments, tmp_path):
    assert_one_line_error(jointctl("bode", "one_dof", *args, "--out", tmp_path / "o"), *fragments)
    assert not (tmp_path / "o" / "metrics.json").exists()


def test_identify_then_autotune_with_the_identified_plant_writes_the_chapters_yaml(tmp_path):
    assert jointctl("identify", "one_dof", "--joint", "joint1", "--out", tmp_path / "id").returncode == 0
    result = jointctl("autotune", "one_dof", "--controller", "joint1_position_controller", "--zeta", "0.7",
                      "--bandwidth-hz", "5", "--plant", tmp_path / "id" / "metrics.json", "--out", tmp_path / "at")
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "at" / "metrics.json").read_text())
    assert metrics["plant_source"] == "identified" and metrics["mass"] == pytest.approx(1.02, rel=1e-3)
    assert metrics["robot"]["step_overshoot_pct"] == pytest.approx(4.6, abs=1.0)
    import yaml
    written = yaml.safe_load((tmp_path / "at" / "one_dof_pos_ctl_params.yaml").read_text())
    assert written["one_DOF_robot"]["joint1_position_controller"]["pid"]["p"] == pytest.approx(metrics["gains"]["p"])


@pytest.mark.parametrize("args, fragments", [
    (["--bandwidth-hz", "20", "--step", "0.5", "--set", "controllers.joint1_position_controller.derivative=measurement"],
     ["--step", "a step of 0.5 m from -0.5 would reach", "beyond the joint's range [-1, 0]", "0.5"]),
    (["--bandwidth-hz", "5", "--step", "0"], ["step", "other than 0", "0.0"]),
    (["--bandwidth-hz", "5", "--zeta", "1.5"], ["zeta", "1.5"]),
    (["--bandwidth-hz", "5", "--plant", "nowhere.json"], ["--plant", "nowhere.json"]),
    (["--bandwidth-hz", "5", "--hardware", "industrial"], ["--hardware", "gains of its own"]),
    ([], ["--bandwidth-hz", "--overshoot-pct and --settling-s"]),
    (["--overshoot-pct", "10"], ["--settling-s", "is required with --overshoot-pct"]),
    (["--bandwidth-hz", "5", "--overshoot-pct", "10", "--settling-s", "0.3"], ["--bandwidth-hz", "either"]),
    (["--overshoot-pct", "120", "--settling-s", "0.3"], ["overshoot_pct", "120"]),
])
def test_autotune_refuses_bad_input_in_one_line(args, fragments, tmp_path):
    assert_one_line_error(jointctl("autotune", "one_dof", "--controller", "joint1_position_controller", *args,
                                   "--out", tmp_path / "o"), *fragments)
    assert not (tmp_path / "o").exists()


def test_run_video_writes_the_videos_next_to_the_trace(tmp_path):
    result = jointctl("run", "one_dof_step", "--set", "duration_s=1.0", "--video", "--video-fps", "10",
                      "--video-size", "320x240", "--video-camera", "120,-20", "--no-mcap", "--out", tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "video.mp4").is_file() and (tmp_path / "video.gif").is_file()
    assert (tmp_path / "trace.csv").is_file() and not (tmp_path / "run.mcap").exists()  # --no-mcap
    assert json.loads((tmp_path / "metrics.json").read_text())["video"]["frames"] == 10


@pytest.mark.parametrize("args, fragments", [
    (["--video-size", "640"], ["--video-size", "WIDTHxHEIGHT", "640"]),
    (["--video-size", "641x480"], ["--video-size", "even", "641x480"]),
    (["--video-fps", "0"], ["--video-fps", "0"]),
    (["--video-camera", "0,0,1"], ["--video-camera", "AZIMUTH,ELEVATION"]),
    (["--video-camera", "90,95"], ["--video-camera.elevation_deg", "95"]),
    (["--video-camera", "0,0,1,-2,90,0"], ["--video-camera.distance_m", "-2"]),
])
def test_run_video_refuses_bad_options_before_anything_runs(args, fragments, tmp_path):
    assert_one_line_error(jointctl("run", "one_dof_step", "--video", *args, "--out", tmp_path / "o"), *fragments)
    assert not (tmp_path / "o" / "trace.csv").exists()

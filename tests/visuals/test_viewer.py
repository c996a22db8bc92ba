"""``jointctl run --view`` under a virtual display (Xvfb): MuJoCo's window opens beside the run, the
run completes; without a display it is one line and exit 2, before anything runs."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time

import pytest

from tests.test_cli import assert_one_line_error, jointctl


@pytest.fixture
def display():
    missing = [tool for tool in ("Xvfb", "xdotool") if shutil.which(tool) is None]
    if missing:
        if os.environ.get("JOINTCTL_REQUIRE_BROWSER"):
            pytest.fail(f"JOINTCTL_REQUIRE_BROWSER is set but {', '.join(missing)} is missing (make render)")
        pytest.skip(f"{', '.join(missing)} missing (make render installs them)")
    number = f":{90 + os.getpid() % 100}"
    server = subprocess.Popen(["Xvfb", number, "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(1.0)
    assert server.poll() is None, "Xvfb did not start"
    yield number
    server.terminate()
    server.wait(10)


def windows(display: str, name: str) -> list[str]:
    found = subprocess.run(["xdotool", "search", "--name", name], env=dict(os.environ, DISPLAY=display),
                           capture_output=True, text=True)
    return found.stdout.split()


def test_the_viewer_opens_beside_the_run_and_the_run_completes(display, tmp_path) -> None:
    env = dict(os.environ, DISPLAY=display, MPLBACKEND="Agg")
    run = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "run", "one_dof_step", "--view",
                            "--set", "duration_s=5", "--out", str(tmp_path)], env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen = []
    while run.poll() is None and not seen:
        seen = windows(display, "MuJoCo")
        time.sleep(0.2)
    out, err = run.communicate(timeout=120)
    assert seen, "no MuJoCo window appeared while the run went on"
    assert run.returncode == 0, err
    assert (tmp_path / "metrics.json").is_file() and (tmp_path / "trace.csv").is_file()
    assert windows(display, "MuJoCo") == []  # closed with the run


def test_without_a_display_the_viewer_is_one_line_and_nothing_runs(tmp_path, monkeypatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert_one_line_error(jointctl("run", "one_dof_step", "--view", "--out", tmp_path / "o"),
                          "--view", "no display")
    assert not (tmp_path / "o" / "trace.csv").exists()


def test_the_tuning_page_can_have_the_viewer_beside_it(display, tmp_path) -> None:
    env = dict(os.environ, DISPLAY=display)
    tune = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "tune", "one_dof", "--view", "--port", "0",
                             "--out", str(tmp_path)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        assert tune.stdout.readline().startswith("jointctl: tuning one_DOF_robot at http://")
        deadline = time.monotonic() + 30
        while not windows(display, "MuJoCo"):
            assert time.monotonic() < deadline and tune.poll() is None, "no MuJoCo window beside the page"
            time.sleep(0.2)
    finally:
        tune.terminate()
        _, err = tune.communicate(timeout=20)  # the window's thread ends before GLFW is torn down
    assert tune.returncode == 0, err

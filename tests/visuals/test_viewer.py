"""``jointctl run --view`` under a virtual display (Xvfb): MuJoCo's window opens beside the run, the
run completes; without a display it is one line and exit 2, before anything runs."""

from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import sys
import time

import pytest

from tests.test_cli import assert_one_line_error, jointctl

# Generous deadlines for a loaded machine: they bound a hang, they do not time anything.
XVFB_START_S = 30.0
WINDOW_S = 60.0


def poll(predicate, deadline_s: float, what: str, every_s: float = 0.05):
    """Call ``predicate`` until it returns something truthy (that value), or fail after ``deadline_s``."""
    deadline = time.monotonic() + deadline_s
    while True:
        value = predicate()
        if value:
            return value
        assert time.monotonic() < deadline, f"timed out after {deadline_s} s waiting for {what}"
        time.sleep(every_s)


@pytest.fixture
def display():
    missing = [tool for tool in ("Xvfb", "xdotool") if shutil.which(tool) is None]
    if missing:
        if os.environ.get("JOINTCTL_REQUIRE_BROWSER"):
            pytest.fail(f"JOINTCTL_REQUIRE_BROWSER is set but {', '.join(missing)} is missing (make render)")
        pytest.skip(f"{', '.join(missing)} missing (make render installs them)")
    # -displayfd: the server picks a free display itself and writes its number once it accepts
    # connections (no guessed number that another test run may hold, no fixed sleep).
    read_end, write_end = os.pipe()
    server = subprocess.Popen(["Xvfb", "-displayfd", str(write_end), "-screen", "0", "1280x1024x24",
                               "-nolisten", "tcp"], pass_fds=(write_end,),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_end)
    try:
        with os.fdopen(read_end) as reported:
            ready, _, _ = select.select([reported], [], [], XVFB_START_S)
            number = reported.readline().strip() if ready else ""
        assert number.isdigit(), f"Xvfb reported no display (exit status {server.poll()})"
        display = f":{number}"
        poll(lambda: subprocess.run(["xdotool", "getdisplaygeometry"], env=dict(os.environ, DISPLAY=display),
                                    capture_output=True).returncode == 0, XVFB_START_S, f"display {display} to answer")
        yield display
    finally:
        server.terminate()
        server.wait(10)


def windows(display: str, name: str) -> list[str]:
    found = subprocess.run(["xdotool", "search", "--name", name], env=dict(os.environ, DISPLAY=display),
                           capture_output=True, text=True)
    return found.stdout.split()


# `jointctl run` in a child that watches its own window. When the viewer opens, the child waits (the
# loop waits with it) until the X server lists a MuJoCo window: the window is seen while the run goes
# on, however slowly this machine opens it. When the viewer's close() returns, the child looks again
# at once, while its own X connection is open (an unclosed window would still be listed), and for
# the window's thread (close() must have joined it: a thread still drawing can hang the exit).
# After the process exits the X server removes its windows anyway: only a look from inside can tell
# a closed window from a dead one.
RUN_AND_LOOK = """
import json, subprocess, sys, threading, time
import mujoco.viewer
from jointctl.cli import main
from jointctl.visuals.viewer import LiveViewer

def windows():
    found = subprocess.run(["xdotool", "search", "--name", "MuJoCo"], capture_output=True, text=True)
    return found.stdout.split()

opened, closed, launch, close = [], [], mujoco.viewer.launch_passive, LiveViewer.close

def launch_and_wait(*args, **kwargs):
    handle, deadline = launch(*args, **kwargs), time.monotonic() + %(deadline)r
    while not windows() and time.monotonic() < deadline:
        time.sleep(0.05)
    opened.append(windows())
    return handle

def close_and_look(self, *args, **kwargs):
    close(self, *args, **kwargs)
    threads = [t.name for t in threading.enumerate()
               if getattr(t, "_target", None) is mujoco.viewer._launch_internal and t.is_alive()]
    closed.append({"viewer_threads": threads, "windows": windows()})

mujoco.viewer.launch_passive, LiveViewer.close = launch_and_wait, close_and_look
code = main(sys.argv[1:])
print(json.dumps({"opened": opened, "closed": closed}), flush=True)
sys.exit(code)  # and the interpreter's own teardown must not hang on the window (communicate's timeout)
""" % {"deadline": WINDOW_S}


def test_the_viewer_opens_beside_the_run_and_closes_with_it(display, tmp_path) -> None:
    env = dict(os.environ, DISPLAY=display, MPLBACKEND="Agg")
    run = subprocess.run([sys.executable, "-c", RUN_AND_LOOK, "run", "one_dof_step", "--view",
                          "--set", "duration_s=1", "--out", str(tmp_path)], env=env,
                         capture_output=True, text=True, timeout=120 + WINDOW_S)
    assert run.stdout.strip(), f"no report (exit status {run.returncode}): {run.stderr}"
    report = json.loads(run.stdout.strip().splitlines()[-1])
    assert len(report["opened"]) == 1 and report["opened"][0], "no MuJoCo window while the run went on"
    assert len(report["closed"]) == 1, "the viewer was not closed when the run ended"
    assert report["closed"][0]["viewer_threads"] == [], "close() returned with the window's thread running"
    assert report["closed"][0]["windows"] == [], "close() returned with the window still open"
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "metrics.json").is_file() and (tmp_path / "trace.csv").is_file()


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
        poll(lambda: windows(display, "MuJoCo") or tune.poll() is not None, WINDOW_S, "the MuJoCo window")
        assert tune.poll() is None, "the tuning session ended before its MuJoCo window appeared"
    finally:
        tune.terminate()
        _, err = tune.communicate(timeout=20)  # the window's thread ends before GLFW is torn down
    assert tune.returncode == 0, err

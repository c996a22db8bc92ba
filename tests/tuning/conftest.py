"""Fixtures for the tuning page: a real ``jointctl tune`` process and a real headless Chromium.

Browser tests skip when Debian's chromium or chromedriver (or selenium) is missing, unless
JOINTCTL_REQUIRE_BROWSER is set (CI sets it, and ``make test`` installs them), in which case
they fail instead.
"""

from __future__ import annotations

import functools
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.waiting import wait_until

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
ARTIFACTS = Path(__file__).resolve().parents[2] / "out" / "test-artifacts"
# Flags for a root, headless Chromium on a machine without a display or outside network.
CHROMIUM_FLAGS = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage", "--window-size=1400,1000")


def _browser_missing() -> str | None:
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e .[test])"
    for path in (CHROMIUM, CHROMEDRIVER):
        if not os.access(path, os.X_OK):
            return f"{path} is missing (make browser installs Debian's chromium and chromium-driver)"
    return None


@pytest.fixture(scope="session")
def browser(tmp_path_factory):
    """A headless Chromium driven by Selenium through Debian's chromedriver."""
    missing = _browser_missing()
    if missing:
        if os.environ.get("JOINTCTL_REQUIRE_BROWSER"):
            pytest.fail(f"JOINTCTL_REQUIRE_BROWSER is set but {missing}")
        pytest.skip(missing)
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    options = Options()
    options.binary_location = CHROMIUM
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}")
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_script_timeout(30)
    yield driver
    driver.quit()


class TuneProcess:
    """``jointctl tune`` running in a child process; ``url`` is the address it printed."""

    def __init__(self, args: list[str], out_dir: Path) -> None:
        command = [sys.executable, "-m", "jointctl.cli", "tune", *args, "--port", "0", "--out", str(out_dir)]
        out_dir.mkdir(parents=True, exist_ok=True)
        # stderr to a file: a pipe nobody reads would block the server once it filled up.
        self.stderr_path = out_dir / f"tune-stderr-{time.monotonic_ns()}.txt"
        self._stderr = self.stderr_path.open("w")
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=self._stderr, text=True)
        line = self.process.stdout.readline()
        match = re.search(r"(http://\S+/)", line)
        if not match:
            self.process.kill()
            self.process.wait()
            raise RuntimeError(f"jointctl tune did not start: {line}{self.stderr_path.read_text()}")
        self.url = match.group(1)
        self.ws_url = self.url.replace("http://", "ws://") + "ws"

    def hello(self) -> dict:
        """What a new connection is told now: the live gains and controllers, read from the loop."""
        from websockets.sync.client import connect

        with connect(self.ws_url) as ws:
            return json.loads(ws.recv())

    def stop(self) -> tuple[int, str]:
        """Stop it as Ctrl-C or a service manager would (SIGTERM); (exit status, its stderr)."""
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process.stdout.close()
        self._stderr.close()
        return self.process.returncode, self.stderr_path.read_text()


@pytest.fixture
def tune(tmp_path):
    """Start ``jointctl tune ARGS...``; stopped after the test."""
    started: list[TuneProcess] = []

    def start(*args: str) -> TuneProcess:
        process = TuneProcess(list(args), tmp_path / "tune-out")
        started.append(process)
        return process

    yield start
    for process in started:
        process.stop()


wait_for = functools.partial(wait_until, timeout_s=10.0, every_s=0.05)


def save_artifact(driver, name: str) -> Path:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / name
    driver.save_screenshot(str(path))
    return path


def record_metrics(**figures) -> None:
    """Merge measured figures into out/test-artifacts/tuning_page_metrics.json."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / "tuning_page_metrics.json"
    metrics = json.loads(path.read_text()) if path.is_file() else {}
    metrics.update(figures)
    path.write_text(json.dumps(metrics, indent=2, sort_keys=True) + "\n")


__all__ = ["TuneProcess", "record_metrics", "save_artifact", "wait_for"]

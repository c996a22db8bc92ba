"""The tuning page's 3D view: what it costs the page, in a real headless Chromium.

``jointctl tune one_dof`` with a sine command; the page opened twice, with its 3D view and without
(``?view3d=0``), 6 s each: the plots' redraws per second and the 3D view's frames per second (it
draws when new poses arrive, 30 times a second of loop time). Reported: both rates, and the plot
redraw rate with the view over the rate without it. Needs Debian's chromium and chromedriver
(make browser); without them, no rows.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time

from benchmarks.common import Result

SECONDS = 6.0


def _rates(driver, url: str) -> tuple[float, float]:
    driver.get(url)
    deadline = time.monotonic() + 30
    while not driver.execute_script("return window.jointctlPage && window.jointctlPage.hello !== null;"):
        if time.monotonic() > deadline:
            raise RuntimeError("the page did not connect")
        time.sleep(0.1)
    time.sleep(2.0)
    read = ("return [window.jointctlPage.draws, window.jointctl3d ? window.jointctl3d.frames : 0];")
    draws0, frames0 = driver.execute_script(read)
    t0 = time.monotonic()
    time.sleep(SECONDS)
    draws1, frames1 = driver.execute_script(read)
    wall = time.monotonic() - t0
    return (draws1 - draws0) / wall, (frames1 - frames0) / wall


def run() -> list[Result]:
    if not (os.access("/usr/bin/chromium", os.X_OK) and os.access("/usr/bin/chromedriver", os.X_OK)):
        return []
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    from tests.tuning.conftest import CHROMIUM_FLAGS

    with tempfile.TemporaryDirectory() as out:
        tune = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "tune", "one_dof", "--port", "0", "--out", out],
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            url = re.search(r"(http://\S+/)", tune.stdout.readline()).group(1)
            options = Options()
            options.binary_location = "/usr/bin/chromium"
            for flag in CHROMIUM_FLAGS:
                options.add_argument(flag)
            options.add_argument(f"--user-data-dir={out}/profile")
            driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
            try:
                plots_with, frames_3d = _rates(driver, url)
                plots_without, _ = _rates(driver, url + "?view3d=0")
            finally:
                driver.quit()
        finally:
            tune.terminate()
            tune.wait(10)
    return [
        Result("page3d", "3D view frames per second", frames_3d, "/s"),
        Result("page3d", "plot redraws per second, without the 3D view (baseline)", plots_without, "/s"),
        Result("page3d", "plot redraws per second, with the 3D view", plots_with, "/s"),
        Result("page3d", "plot redraws with / without the 3D view", plots_with / plots_without, "x"),
    ]


if __name__ == "__main__":
    for row in run():
        print(row)

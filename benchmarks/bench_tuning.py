"""What the tuning page costs the loop.

*Per cycle*: the tuner's door (queued changes, feeding the source) and its live buffer (a row
per cycle) against the plain session feeding the same sine, both on simulated time, interleaved.
*Paced with a page attached*: the loop at 1 kHz on the wall clock while a websocket client in
another process receives the page's data (60 messages a second) and status; how late each cycle
ends against its due time (jitter), against the same paced loop with no server, in the same run.
"""

from __future__ import annotations

import dataclasses
import statistics
import subprocess
import sys
import tempfile
import threading
import time

from benchmarks.common import Result
from jointctl.runtime.clock import WallClockPacer
from jointctl.scenario.session import Session
from jointctl.scenario.spec import scenario_for_robot
from jointctl.tuning.tuner import Tuner

SIM_SECONDS = 10.0
REPEATS = 5
PACED_SECONDS = 10.0
SINE = {"type": "sine", "amplitude": 0.1, "frequency_hz": 2.0, "offset": -0.5, "rate_hz": 100}
CONTROLLER = "joint1_position_controller"


def _scenario(with_command: bool):
    scenario = scenario_for_robot("one_dof", "position")
    return dataclasses.replace(scenario, commands={CONTROLLER: SINE} if with_command else {})


def _session_speed() -> float:
    session = Session(_scenario(True))
    start = time.perf_counter()
    session.loop.run(SIM_SECONDS)
    return SIM_SECONDS / (time.perf_counter() - start)


def _tuner_speed(out: str) -> float:
    tuner = Tuner(_scenario(True), out_dir=out)
    start = time.perf_counter()
    tuner.loop.run(SIM_SECONDS)
    return SIM_SECONDS / (time.perf_counter() - start)


def _lateness(loop, speed: float = 1.0):
    late: list[float] = []

    def measure(t: float) -> None:
        late.append(time.perf_counter() - loop.clock.origin_s - t / speed)

    loop.add_observer(measure)
    return late


def _percentiles(late: list[float]) -> tuple[float, float]:
    ordered = sorted(late[1000:])  # the first second: imports and connections settling
    return 1e3 * ordered[len(ordered) // 2], 1e3 * ordered[int(0.99 * len(ordered))]


_CLIENT = """
import json, sys, time
from websockets.sync.client import connect
count = 0
with connect(sys.argv[1], max_size=None) as ws:
    ws.send(json.dumps({"type": "source", "controller": "joint1_position_controller",
                        "source": %r}))
    end = time.monotonic() + float(sys.argv[2])
    while time.monotonic() < end:
        if json.loads(ws.recv())["type"] == "data":
            count += 1
print(count)
"""


def _paced_without_page(out: str) -> list[float]:
    tuner = Tuner(_scenario(True), out_dir=out)
    tuner.loop.clock = WallClockPacer(1.0)
    late = _lateness(tuner.loop)
    tuner.loop.run(PACED_SECONDS)
    return late


def _paced_with_page(out: str) -> tuple[list[float], int]:
    import uvicorn

    from jointctl.tuning.runner import LiveRunner
    from jointctl.tuning.server import TuningApp, bind

    tuner = Tuner(_scenario(False), out_dir=out)
    late = _lateness(tuner.loop)
    runner = LiveRunner(tuner)
    app = TuningApp(tuner, runner)
    sock = bind("127.0.0.1", 0)
    server = uvicorn.Server(uvicorn.Config(app, ws="websockets-sansio", lifespan="off", log_level="warning"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    runner.start()
    url = f"ws://127.0.0.1:{sock.getsockname()[1]}/ws"
    client = subprocess.run([sys.executable, "-c", _CLIENT % (SINE,), url, str(PACED_SECONDS)],
                            capture_output=True, text=True, check=True)
    runner.stop()
    server.should_exit = True
    thread.join(5)
    return late, int(client.stdout.strip())


def run() -> list[Result]:
    with tempfile.TemporaryDirectory() as out:
        plain, tuned = [], []
        for _ in range(REPEATS):
            plain.append(_session_speed())
            tuned.append(_tuner_speed(out))
        plain_rtf, tuned_rtf = statistics.median(plain), statistics.median(tuned)
        base50, base99 = _percentiles(_paced_without_page(out))
        late, messages = _paced_with_page(out)
        page50, page99 = _percentiles(late)
    name = "tuning"
    rate = messages / PACED_SECONDS
    return [
        Result(name, "session feeding a sine, real-time factor", plain_rtf, "x"),
        Result(name, "tuner (door + live buffer) feeding the same sine", tuned_rtf, "x"),
        Result(name, "tuner / session", tuned_rtf / plain_rtf, "ratio", ">= 0.7", tuned_rtf / plain_rtf >= 0.7),
        Result(name, "paced 1 kHz, cycle lateness p99, no page", base99, "ms p99", f"(p50 {base50:.3f} ms)"),
        Result(name, "paced 1 kHz, cycle lateness p99, page attached", page99, "ms p99",
               f"<= 1 (p50 {page50:.3f} ms)", page99 <= 1.0),
        Result(name, "data messages received by the page", rate, "per s", ">= 30", rate >= 30),
    ]

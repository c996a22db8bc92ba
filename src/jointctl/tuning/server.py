"""The tuning page's server: a small ASGI application run by uvicorn.

``GET /`` serves the page, ``GET /static/<file>`` its script, style and the plotting library
(uPlot, built into the package from the npm registry; nothing comes from a CDN), and ``/ws`` is
the one websocket a page talks through. Per connection the server sends:

- ``hello`` once: the robot, its joints and sensors, the commandable controllers and every gain;
- ``data`` at :data:`STREAM_HZ`: every row since the last message for the page's joint, thinned to
  :data:`DISPLAY_HZ` (the rows are picked by their cycle number, so no row is skipped twice or sent twice);
- ``status`` at :data:`STATUS_HZ` and ``measure`` at :data:`MEASURE_HZ`;
- for the 3D view (simulated robots): ``scene`` (the visible shapes, again when an object is spawned
  or removed) and ``poses`` (their poses, 30 times a second of loop time: see
  :mod:`jointctl.tuning.scene_view`);
- a reply to every request: ``ok``, ``saved``, ``analysis`` (Identify, Bode, Auto-tune: see
  :mod:`jointctl.tuning.analyses`) or ``error`` (with ``field`` and ``message``).

Websocket connections from a page of another origin are refused: only the tuning page itself
(or a client sending no Origin header) may move the robot.
"""

from __future__ import annotations

import asyncio
import json
import math
import signal
import socket
import sys
from importlib import resources
from pathlib import Path
from typing import Any

from jointctl.errors import JointCtlError
from jointctl.tuning.analyses import run_analysis
from jointctl.tuning.requests import MAX_REQUEST_CHARS, Analyse, SelectJoint, parse_request
from jointctl.tuning.runner import LiveRunner
from jointctl.tuning.tuner import Tuner, stream_columns

STREAM_HZ = 60.0  # data messages per second (the page redraws on each: a screen's rate)
DISPLAY_HZ = 250.0  # plotted samples per second of loop time
STATUS_HZ = 4.0
MEASURE_HZ = 2.0

_STATIC = {
    "index.html": "text/html; charset=utf-8",
    "app.js": "text/javascript; charset=utf-8",
    "analysis.js": "text/javascript; charset=utf-8",
    "style.css": "text/css; charset=utf-8",
    "view3d.js": "text/javascript; charset=utf-8",
    "vendor/uPlot.iife.min.js": "text/javascript; charset=utf-8",
    "vendor/three.module.js": "text/javascript; charset=utf-8",
    "vendor/three.core.js": "text/javascript; charset=utf-8",
    "vendor/uPlot.min.css": "text/css; charset=utf-8",
}
_HEADERS = [
    (b"cache-control", b"no-store"),
    (b"x-content-type-options", b"nosniff"),
    (b"content-security-policy", b"default-src 'self'; img-src 'self' data: blob:; object-src 'none'; "
                                 b"base-uri 'none'; frame-ancestors 'none'"),
]


def static_dir() -> Path:
    return Path(str(resources.files("jointctl.tuning") / "static"))


def check_static_files(folder: Path | None = None) -> None:
    folder = folder or static_dir()
    missing = [name for name in _STATIC if not (folder / name).is_file()]
    if missing:
        raise JointCtlError("the tuning page's files are missing; build them with 'make web' "
                            "(scripts/build_web.sh fetches uPlot and three.js from the npm registry)", field="static",
                            value=", ".join(missing))


class TuningApp:
    """The ASGI application of one tuning session."""

    def __init__(self, tuner: Tuner, runner: LiveRunner | None = None, folder: Path | None = None) -> None:
        self.tuner = tuner
        self.runner = runner
        self.folder = folder or static_dir()
        check_static_files(self.folder)
        self.every = max(1, round(1.0 / (DISPLAY_HZ * tuner.period_s)))

    async def __call__(self, scope, receive, send) -> None:
        if scope["type"] == "http":
            await self._http(scope, send)
        elif scope["type"] == "websocket":
            await self._websocket(scope, receive, send)

    # -- files ----------------------------------------------------------------------------------------
    async def _http(self, scope, send) -> None:
        path = scope["path"]
        name = "index.html" if path == "/" else path.removeprefix("/static/") if path.startswith("/static/") else None
        if path == "/favicon.ico":
            await self._respond(send, 204, b"", "image/x-icon")
        elif scope["method"] not in ("GET", "HEAD"):
            await self._respond(send, 405, b"method not allowed\n", "text/plain")
        elif name not in _STATIC:  # a fixed list of files: no path from the client reaches the disk
            await self._respond(send, 404, b"not found\n", "text/plain")
        else:
            body = (self.folder / name).read_bytes()
            await self._respond(send, 200, b"" if scope["method"] == "HEAD" else body, _STATIC[name],
                                length=len(body))

    @staticmethod
    async def _respond(send, status: int, body: bytes, content_type: str, length: int | None = None) -> None:
        headers = [(b"content-type", content_type.encode()),
                   (b"content-length", str(len(body) if length is None else length).encode()), *_HEADERS]
        await send({"type": "http.response.start", "status": status, "headers": headers})
        await send({"type": "http.response.body", "body": body})

    # -- the page's connection ----------------------------------------------------------------------
    @staticmethod
    def _same_origin(scope) -> bool:
        headers = dict(scope.get("headers") or [])
        origin = headers.get(b"origin")
        if origin is None:
            return True  # not a browser page (a script, a test client)
        host = headers.get(b"host", b"")
        return origin in (b"http://" + host, b"https://" + host)

    async def _websocket(self, scope, receive, send) -> None:
        event = await receive()
        if event["type"] != "websocket.connect":
            return
        if scope["path"] != "/ws" or not self._same_origin(scope):
            await send({"type": "websocket.close", "code": 1008})
            return
        await send({"type": "websocket.accept"})
        connection = _Connection(self, send)
        sender = asyncio.create_task(connection.stream())
        try:
            while True:
                event = await receive()
                if event["type"] == "websocket.disconnect":
                    break
                text = event.get("text")
                if text is None and event.get("bytes") is not None:
                    text = event["bytes"]  # refused below: requests are JSON text
                await connection.request(text)
        finally:
            sender.cancel()


class _Connection:
    """One page: its joint, how far its plot has been sent, the last measurement, the 3D view's state."""

    def __init__(self, app: TuningApp, send) -> None:
        self.app = app
        self.tuner = app.tuner
        self._scene_model = None  # the model whose shapes this page has
        self._poses_sent = 0
        self._send = send
        self._lock = asyncio.Lock()
        self.joint = self.tuner.default_joint
        self.epoch = self.tuner.epoch
        self.cursor = self.tuner.buffer.readable_from()

    async def send(self, message: dict[str, Any]) -> None:
        try:
            text = json.dumps(message, allow_nan=False)
        except ValueError:  # a NaN or infinity somewhere: JSON has none, the page shows null
            text = json.dumps(_finite(message), allow_nan=False)
        async with self._lock:
            await self._send({"type": "websocket.send", "text": text})

    async def request(self, text: Any) -> None:
        kind = None
        try:
            request = parse_request(text)
            kind = request.kind
            if isinstance(request, Analyse):  # seconds of simulation: off the event loop, the stream goes on
                reply = await asyncio.to_thread(run_analysis, self.tuner, request)
            else:
                reply = self.tuner.handle(request)
            if isinstance(request, SelectJoint):
                self.joint = request.joint
                self.cursor = self.tuner.buffer.readable_from()  # the new joint's whole window
        except JointCtlError as exc:
            reply = {"type": "error", "request": kind, "field": exc.field, "message": str(exc)}
        await self.send(reply)

    async def _scene(self) -> None:
        """The 3D view: the shapes when the world's model changed, the poses when newer (SceneTap)."""
        tap = self.tuner.scene
        snapshot = tap.snapshot if tap is not None else None
        if snapshot is None:
            return
        model, poses, time_s, count = snapshot
        if model is not self._scene_model:
            self._scene_model = model
            await self.send(tap.scene_message(model, tap.camera))
        if count != self._poses_sent:
            self._poses_sent = count
            await self.send({"type": "poses", "t": time_s, "poses": poses})

    async def stream(self) -> None:
        tuner = self.tuner
        await self.send({"type": "hello", **tuner.describe(), "stream_hz": STREAM_HZ,
                         "display_hz": 1.0 / (self.app.every * tuner.period_s)})
        tick = 0
        per_status = max(1, round(STREAM_HZ / STATUS_HZ))
        per_measure = max(1, round(STREAM_HZ / MEASURE_HZ))
        measured_key = None
        clock = asyncio.get_running_loop().time
        due = clock()
        while True:
            # On a fixed schedule (late ticks are not made up): the rate does not drop by the work done.
            due = max(due + 1.0 / STREAM_HZ, clock())
            await asyncio.sleep(due - clock())
            await self._data()
            await self._scene()
            if tick % per_status == 0:
                status = tuner.status()
                runner = self.app.runner
                if runner is not None and runner.error is not None:
                    status["error"] = f"the loop stopped: {runner.error}"
                await self.send({"type": "status", **status})
            if tick % per_measure == 0:
                key = (tuner.epoch, tuner.last_commanded,
                       tuner.runs[tuner.last_commanded].started_s if tuner.last_commanded else None)
                if key != measured_key:
                    try:
                        result = await asyncio.to_thread(tuner.measurement)
                    except Exception as exc:  # noqa: BLE001  (the page keeps streaming and says why)
                        result = {"kind": None, "complete": False, "values": {},
                                  "note": f"measurement failed: {type(exc).__name__}: {exc}"}
                    if result.get("complete"):
                        measured_key = key  # nothing more to learn from this run
                    await self.send({"type": "measure", **result})
            tick += 1

    async def _data(self) -> None:
        tuner = self.tuner
        if tuner.epoch != self.epoch:
            self.epoch = tuner.epoch
            self.cursor = 0
            await self.send({"type": "reset", "epoch": self.epoch})
        columns = stream_columns(tuner.buffer, self.joint)
        rows, _, stop = tuner.buffer.rows(self.cursor, None, [c for _, c in [("time", 0), *columns]],
                                          every=self.app.every)
        self.cursor = stop
        if not len(rows):
            return
        series = {name: _finite(rows[:, k + 1].tolist()) for k, (name, _) in enumerate(columns)}
        await self.send({"type": "data", "epoch": self.epoch, "joint": self.joint, "t": rows[:, 0].tolist(),
                         "series": series})


def _finite(value: Any) -> Any:
    """JSON-ready: NaN and infinities (a joint no controller commands has a NaN reference) become null."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: any free port)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        raise JointCtlError(f"cannot listen there: {exc.strerror}", field="--port", value=f"{host}:{port}") from None
    sock.listen(64)
    return sock


def serve_tuning(tuner: Tuner, *, host: str = "127.0.0.1", port: int = 8765, speed: float = 1.0,
                 announce=print) -> None:
    """Run the loop paced to the wall clock and serve the page until interrupted (Ctrl-C)."""
    import uvicorn  # imported here: the rest of jointctl runs without a web server installed

    app = TuningApp(tuner)
    sock = bind(host, port)
    runner = LiveRunner(tuner, speed)
    app.runner = runner
    config = uvicorn.Config(app, ws="websockets-sansio", ws_max_size=MAX_REQUEST_CHARS + 1024, lifespan="off",
                            log_level="warning", access_log=False, ws_per_message_deflate=False)
    server = uvicorn.Server(config)
    # A stop by signal is a clean exit (status 0), whenever it comes: before uvicorn listens, this
    # handler asks the server to exit; after, uvicorn shuts down gracefully and raises the signal
    # again for the handler that was there before it, this one.
    previous = {sig: signal.signal(sig, lambda *_: setattr(server, "should_exit", True))
                for sig in (signal.SIGINT, signal.SIGTERM)}
    address_host = f"[{host}]" if ":" in host else host
    announce(f"jointctl: tuning {tuner.session.robot.name} at http://{address_host}:{sock.getsockname()[1]}/ "
             f"(speed {speed:g}; Ctrl-C stops)")
    sys.stdout.flush()
    runner.start()
    try:
        server.run(sockets=[sock])
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        runner.stop()
        sock.close()
        tuner.close()
    if runner.error is not None:
        raise JointCtlError(f"the control loop stopped: {runner.error}", field="loop")

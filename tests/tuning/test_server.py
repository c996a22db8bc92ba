"""The tuning server as a client meets it: a real ``jointctl tune`` process, HTTP and a websocket."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request

import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from jointctl.errors import JointCtlError
from jointctl.tuning.server import bind, check_static_files


def get(url: str, method: str = "GET"):
    request = urllib.request.Request(url, method=method)
    try:
        with urllib.request.urlopen(request, timeout=5) as response:
            return response.status, {k.lower(): v for k, v in response.headers.items()}, response.read()
    except urllib.error.HTTPError as exc:
        return exc.code, {k.lower(): v for k, v in exc.headers.items()}, exc.read()


def test_the_page_and_its_files_are_served_locally_and_nothing_else(tune):
    server = tune("one_dof")
    status, headers, body = get(server.url)
    assert status == 200 and b"<title>jointctl tune</title>" in body
    assert headers["content-type"].startswith("text/html")
    assert "default-src 'self'" in headers["content-security-policy"]
    assert b"http://" not in body and b"https://" not in body  # no CDN
    status, headers, body = get(server.url + "static/vendor/uPlot.iife.min.js")
    assert status == 200 and b"uPlot" in body and headers["content-type"].startswith("text/javascript")
    for path in ("static/../pyproject.toml", "static/%2e%2e/README.md", "static/app.py", "etc/passwd"):
        assert get(server.url + path)[0] == 404, path
    assert get(server.url, method="POST")[0] == 405


def test_the_websocket_sends_hello_then_every_thinned_row_once(tune):
    server = tune("one_dof")
    with connect(server.ws_url) as ws:
        hello = json.loads(ws.recv())
        assert hello["type"] == "hello" and hello["robot"] == "one_DOF_robot"
        assert hello["display_hz"] == 250.0 and hello["can_drop"] is True
        times, kinds = [], set()
        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline:
            message = json.loads(ws.recv())
            kinds.add(message["type"])
            if message["type"] == "data":
                assert set(message["series"]) == {"reference", "position", "velocity", "effort", "force:ft_sensor"}
                times += message["t"]
    assert {"data", "status", "measure"} <= kinds
    steps = [round((b - a) * 1000) for a, b in zip(times, times[1:])]
    assert set(steps) == {4}  # every 4 ms of loop time, none missing, none twice
    assert all(round(t * 1000) % 4 == 0 for t in times)


def test_a_page_of_another_origin_cannot_connect(tune):
    server = tune("one_dof")
    with pytest.raises(InvalidStatus):
        connect(server.ws_url, origin="http://evil.example")
    host = server.url.removeprefix("http://").rstrip("/")
    with connect(server.ws_url, origin=f"http://{host}") as ws:
        assert json.loads(ws.recv())["type"] == "hello"


def test_binary_and_malformed_messages_get_an_error_reply_and_the_connection_stays(tune):
    server = tune("one_dof")
    with connect(server.ws_url) as ws:
        json.loads(ws.recv())
        for message in (b"\x00\x01", "{not json", json.dumps({"type": "gain", "controller": "x", "name": "p",
                                                                "value": 1})):
            ws.send(message)
            while (reply := json.loads(ws.recv()))["type"] not in ("ok", "error"):
                pass
            assert reply["type"] == "error" and reply["message"]
        ws.send(json.dumps({"type": "pause"}))
        while (reply := json.loads(ws.recv()))["type"] not in ("ok", "error"):
            pass
        assert reply == {"type": "ok", "request": "pause"}


def test_stopping_the_command_ends_it_cleanly(tune):
    server = tune("one_dof")
    code, err = server.stop()
    assert code == 0, err  # SIGTERM, as a service manager stops it: a clean exit
    assert "Traceback" not in err


def test_missing_page_files_and_a_taken_port_are_clear_errors(tmp_path):
    with pytest.raises(JointCtlError, match="make web") as caught:
        check_static_files(tmp_path)
    assert "vendor/uPlot.iife.min.js" in caught.value.value and "vendor/three.module.js" in caught.value.value
    first = bind("127.0.0.1", 0)
    try:
        with pytest.raises(JointCtlError, match="cannot listen") as caught:
            bind("127.0.0.1", first.getsockname()[1])
        assert caught.value.field == "--port"
    finally:
        first.close()

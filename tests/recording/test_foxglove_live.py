"""The live Foxglove server checked by a WebSocket client speaking Foxglove's protocol: it subscribes to the joint
states of a robot stepping up and receives them, every 4 ms of loop time, equal to a simulated-time run's."""

from __future__ import annotations

import asyncio
import json
import socket
import struct
import subprocess
import sys
import threading

import numpy as np
import pytest
import websockets

from jointctl.recording import foxglove_messages as fm
from jointctl.recording.foxglove_live import FoxgloveLive, check_port, live_for_session
from jointctl.recording.trace import load_trace
from jointctl.scenario.session import Session
from jointctl.scenario.spec import load_scenario
from tests.conftest import step_scenario

SUBPROTOCOL = "foxglove.sdk.v1"  # the SDK server's protocol (Foxglove's WebSocket protocol)
STEP_AT_S = 0.1
RUN_S = 0.4


async def _subscribe_and_collect(url: str, topics: list[str], started: threading.Event, until_s: float,
                                 origin) -> dict[str, list[tuple[int, dict]]]:
    """Subscribe to ``topics``, then to ``/robot_description``; once its URDF has come (the server sends
    it to a new subscriber at once), tell the loop to start, and collect messages until one is stamped
    past ``until_s`` of loop time (``origin()`` maps stamps to loop time).

    The server handles one client's requests in order: the URDF, sent when the second subscribe is
    handled, shows that the first one was handled before it. So every message the loop logs reaches
    this client however late the server's threads ran (no fixed wait)."""
    received: dict[str, list[tuple[int, dict]]] = {t: [] for t in [*topics, fm.ROBOT_DESCRIPTION]}
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], open_timeout=10) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        channels: dict[str, int] = {}
        while not {*topics, fm.ROBOT_DESCRIPTION} <= set(channels):
            message = json.loads(await asyncio.wait_for(ws.recv(), 10))
            if message["op"] == "advertise":
                channels.update({c["topic"]: c["id"] for c in message["channels"]})
        subscriptions = dict(enumerate([*topics, fm.ROBOT_DESCRIPTION]))
        for group in (topics, [fm.ROBOT_DESCRIPTION]):  # two requests, the description's last
            await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": k, "channelId": channels[topic]} for k, topic in subscriptions.items() if topic in group]}))
        while True:
            try:
                data = await asyncio.wait_for(ws.recv(), 10)
            except TimeoutError:
                raise AssertionError("no message in 10 s" if started.is_set() else
                                     "the server sent no /robot_description to its new subscriber") from None
            if not isinstance(data, bytes):
                continue
            opcode, subscription, stamp = struct.unpack_from("<BIQ", data)
            assert opcode == 1  # message data
            topic = subscriptions[subscription]
            received[topic].append((stamp, json.loads(data[13:])))
            if topic == fm.ROBOT_DESCRIPTION and not started.is_set():
                assert not received[fm.JOINT_STATES]  # nothing was streamed before the loop started
                started.set()
            if topic == fm.JOINT_STATES and origin() is not None and (stamp - origin()) * 1e-9 >= until_s:
                return received


@pytest.mark.wall_clock
def test_a_client_receives_the_joint_states_of_a_robot_stepping_up(tmp_path, write_scenario):
    path = write_scenario(step_scenario(duration_s=RUN_S, initial_positions={"joint1": -0.5}, commands={
        "joint1_position_controller": {"type": "step", "from": -0.5, "to": -0.2, "at": STEP_AT_S}}))
    offline = tmp_path / "offline"
    with Session(load_scenario(path), out_dir=offline) as session:
        session.run()
    trace = load_trace(offline / "trace.csv")

    session = Session(load_scenario(path), realtime=True)
    live = live_for_session(session, port=0)
    started = threading.Event()

    def run():
        started.wait(30)
        session.run(RUN_S + 0.1)

    loop = threading.Thread(target=run, daemon=True)
    loop.start()
    try:
        received = asyncio.run(_subscribe_and_collect(live.url, [fm.JOINT_STATES, fm.TF], started, RUN_S - 0.01,
                                                      lambda: live.origin_ns))
    finally:
        started.set()
        loop.join(30)
        live.stop()
    assert "<robot" in received[fm.ROBOT_DESCRIPTION][0][1]["data"]  # sent to the new subscriber
    states = received[fm.JOINT_STATES]
    loop_ns = [stamp - live.origin_ns for stamp, _ in states]
    assert loop_ns == sorted(set(loop_ns))  # strictly increasing
    assert all(ns % 4_000_000 == 0 for ns in loop_ns)  # 250 Hz of loop time
    assert loop_ns[0] == 0 and len(states) >= 95  # from the first cycle, none lost
    times = np.array(loop_ns) * 1e-9
    positions = np.array([m["joints"][0]["position"] for _, m in states])
    rows = np.searchsorted(trace.time_s, times - 1e-9)
    assert np.array_equal(positions, trace.joint("joint1", "position")[rows])  # the same numbers
    rising = positions[(times > STEP_AT_S) & (times < STEP_AT_S + 0.15)]
    assert len(rising) > 30 and np.all(np.diff(rising) > 0)  # the piston goes up
    assert positions[-1] > positions[0] + 0.2
    assert len(received[fm.TF]) >= 30  # the frames at 100 Hz too


def test_ports_are_checked():
    assert check_port("8766") == 8766 and check_port(0) == 0
    for bad in ("70000", "-1", "abc", "8.5"):
        with pytest.raises(Exception, match="--foxglove: must be a TCP port, 0 to 65535"):
            check_port(bad)


@pytest.mark.wall_clock
def test_a_port_in_use_is_one_line(write_scenario):
    session = Session(load_scenario(write_scenario(step_scenario())))
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(Exception, match=f"--foxglove: cannot listen for Foxglove on 127.0.0.1:{port}"):
            FoxgloveLive(robot=session.robot, hardware=session.hardware, manager=session.manager, loop=session.loop,
                         urdf="<robot/>", port=port)
    assert not any(isinstance(o, FoxgloveLive) for o in session.loop.observers)  # nothing left behind


@pytest.mark.parametrize("command", ["tune", "serve"])
def test_a_bad_port_on_the_command_line_is_one_line_exit_2(command):
    result = subprocess.run([sys.executable, "-m", "jointctl.cli", command, "one_dof", "--foxglove", "70000"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    lines = [line for line in result.stderr.strip().splitlines() if not line.startswith("jointctl: took ")]
    assert lines == ["jointctl: error: --foxglove: must be a TCP port, 0 to 65535 (got '70000')"]


async def _fetch_assets(url: str, uris: list[str]) -> dict[str, tuple[int, bytes]]:
    """Fetch each of ``uris`` with the protocol's ``fetchAsset``: {uri: (status, data or error text)}
    (status 0: served, 1: refused)."""
    replies: dict[str, tuple[int, bytes]] = {}
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], open_timeout=10) as ws:
        while True:  # the server says it serves assets before any is asked for
            message = await asyncio.wait_for(ws.recv(), 10)
            if isinstance(message, str) and json.loads(message)["op"] == "serverInfo":
                assert "assets" in json.loads(message)["capabilities"]
                break
        for request_id, uri in enumerate(uris):
            await ws.send(json.dumps({"op": "fetchAsset", "uri": uri, "requestId": request_id}))
            while True:
                data = await asyncio.wait_for(ws.recv(), 10)
                if isinstance(data, bytes) and data[0] == 4:  # fetch asset response
                    answered, status, length = struct.unpack_from("<IBI", data, 1)
                    assert answered == request_id
                    replies[uri] = (status, data[10 + length:] if status == 0 else data[10:10 + length])
                    break
    return replies


@pytest.mark.wall_clock
def test_only_the_meshes_the_urdf_names_are_served(tmp_path, write_scenario):
    package = tmp_path / "packages" / "meshes_pkg"
    (package / "meshes").mkdir(parents=True)
    (package / "package.xml").write_text("<package><name>meshes_pkg</name></package>")
    named, other = package / "meshes" / "link.stl", package / "meshes" / "other.stl"
    named.write_bytes(b"solid link\nendsolid link\n")
    other.write_bytes(b"solid other\nendsolid other\n")
    urdf = ('<robot name="r"><link name="a"><visual><geometry>'
            '<mesh filename="package://meshes_pkg/meshes/link.stl" scale="1 1 1"/></geometry></visual></link></robot>')
    session = Session(load_scenario(write_scenario(step_scenario())))
    live = FoxgloveLive(robot=session.robot, hardware=session.hardware, manager=session.manager, loop=session.loop,
                        urdf=urdf, port=0, package_path=(str(tmp_path / "packages"),))
    asked = ["package://meshes_pkg/meshes/link.stl",  # named by the URDF
             "package://meshes_pkg/meshes/other.stl",  # in the same package, not named
             f"file://{other}",  # the same file by its path
             "package://meshes_pkg/package.xml", "package://meshes_pkg/meshes/missing.stl"]
    try:
        replies = asyncio.run(_fetch_assets(live.url, asked))
    finally:
        live.stop()
    assert replies[asked[0]] == (0, named.read_bytes())
    for uri in asked[1:]:
        assert replies[uri][0] == 1, uri  # refused, nothing of the file sent
        assert b"other" not in replies[uri][1] and b"<package>" not in replies[uri][1]


def test_the_objects_and_events_channels_follow_spawns_removals_and_failures(tmp_path, write_scenario):
    """A weight spawned at 0.2 s falls freely from 2.5 m, is removed at 0.5 s, and a controller fails at 0.6 s:
    the objects channel (read from an MCAP sink on the server's context) shows it at the free-fall height at
    every scene tick from its spawn, deletes it once, then sends nothing;
    the events channel has the three events in order, stamped at their loop times."""
    import foxglove
    from tests.recording.test_mcap_record import WEIGHT, read_mcap

    path = write_scenario(step_scenario(duration_s=1.0, objects=[WEIGHT]))
    session = Session(load_scenario(path))
    context = foxglove.Context()
    writer = foxglove.open_mcap(tmp_path / "live.mcap", allow_overwrite=True, context=context)
    live = FoxgloveLive(robot=session.robot, hardware=session.hardware, manager=session.manager, loop=session.loop,
                        urdf=session.robot.name, port=0, context=context)
    try:
        session.run(0.5)
        session.world.remove("weight")
        session.run(0.1)
        controller = session.manager.controller("joint1_position_controller")
        session.manager.fail(controller, "deliberate", session.loop.time_s)
        session.run(0.1)
    finally:
        live.stop()
        writer.close()
        session.close()
    _, by_topic, _, _, _ = read_mcap(tmp_path / "live.mcap")

    def loop_s(log_time):
        return (log_time - live.origin_ns) * 1e-9

    events = [(round(loop_s(t), 3), m["message"], m["level"]) for t, _, m in by_topic[fm.EVENTS]]
    assert [e[1] for e in events[:2]] == ["spawned weight", "removed weight"]
    assert events[0][0] == pytest.approx(WEIGHT["spawn_at_s"], abs=0.0011) and events[1][0] == pytest.approx(0.5)
    assert events[0][2] == events[1][2] == fm.INFO
    (at, text, level), = events[2:]
    assert at == pytest.approx(0.6) and level == fm.ERROR
    assert text.startswith("controller joint1_position_controller failed at t = 0.600 s: deliberate")

    scene = [(loop_s(t), m) for t, _, m in by_topic[fm.OBJECTS]]
    shown = [(s, m) for s, m in scene if m["entities"]]
    deleted = [(s, m) for s, m in scene if m["deletions"]]
    period = 1.0 / fm.SCENE_RATE_HZ
    assert len(shown) == round((0.5 - WEIGHT["spawn_at_s"]) / period)  # every scene tick while it is there
    g = 9.81
    for s, m in shown:
        entity, = m["entities"]
        assert entity["id"] == "weight" and not m["deletions"]
        z = entity["cylinders"][0]["pose"]["position"]["z"]
        fall_s = s - WEIGHT["spawn_at_s"]
        assert z == pytest.approx(WEIGHT["xyz"][2] - 0.5 * g * fall_s ** 2, abs=0.01)
    (s, m), = deleted
    assert [d["id"] for d in m["deletions"]] == ["weight"] and not m["entities"]
    assert 0.5 <= s < 0.5 + period + 1e-9
    assert scene[-1][0] == s  # nothing after the deletion

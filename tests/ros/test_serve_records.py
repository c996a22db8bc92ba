"""``jointctl serve --record DIR --foxglove 0``: the served robot streamed to a Foxglove WebSocket client while it
is commanded over ROS, and recorded into trace.csv and run.mcap (one message per trace row) when it stops."""

from __future__ import annotations

import asyncio
import json
import signal
import struct
import subprocess
import sys

import websockets
from mcap.reader import make_reader

from jointctl.recording import foxglove_messages as fm
from jointctl.recording.trace import load_trace
from tests.ros.conftest import run, wait_for_topic

COMMAND = "/one_DOF_robot/joint1_position_controller/command"


async def _positions(url: str, count: int) -> list[tuple[int, float]]:
    """(stamp, position) of ``count`` joint-state messages received over Foxglove's protocol."""
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"], open_timeout=10) as ws:
        channel = None
        while channel is None:
            message = json.loads(await asyncio.wait_for(ws.recv(), 10))
            if message["op"] == "advertise":
                channel = next((c["id"] for c in message["channels"] if c["topic"] == fm.JOINT_STATES), None)
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel}]}))
        out = []
        while len(out) < count:
            data = await asyncio.wait_for(ws.recv(), 10)
            if isinstance(data, bytes):
                _, _, stamp = struct.unpack_from("<BIQ", data)
                out.append((stamp, json.loads(data[13:])["joints"][0]["position"]))
        return out


def test_serve_records_and_streams_to_foxglove(ros_env, tmp_path):
    out = tmp_path / "served"
    process = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--controllers", "position",
                                "--record", str(out), "--foxglove", "0"], env=ros_env, stderr=subprocess.PIPE,
                               stdout=subprocess.DEVNULL, text=True)
    try:
        url = None
        for line in process.stderr:
            if line.startswith("jointctl: Foxglove: "):
                url = line.split()[2]
                break
        assert url is not None and url.startswith("ws://127.0.0.1:")
        wait_for_topic(ros_env, "/one_DOF_robot/joint_states")
        run(ros_env, "rostopic", "pub", "-1", COMMAND, "std_msgs/Float64", "--", "-0.3", timeout=30)
        received = asyncio.run(_positions(url, 200))
        stamps = [s for s, _ in received]
        assert stamps == sorted(set(stamps))
        assert received[-1][1] > -0.36  # the piston came up towards the command
    finally:
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=60)
    assert process.returncode == 0, err
    assert f"wrote {out}/trace.csv and run.mcap" in err
    trace = load_trace(out / "trace.csv")
    with open(out / "run.mcap", "rb") as f:
        reader = make_reader(f)
        counts = reader.get_summary().statistics.channel_message_counts
        topics = {c.id: c.topic for c in reader.get_summary().channels.values()}
        stamps = [m.log_time for _, _, m in reader.iter_messages(topics=[fm.JOINT_STATES])]
    per_topic = {topics[k]: n for k, n in counts.items()}
    assert len(trace.time_s) > 1000
    assert all(per_topic[t] == len(trace.time_s) for t in fm.PER_CYCLE)
    assert stamps == sorted(stamps) and per_topic[fm.ROBOT_DESCRIPTION] == 1

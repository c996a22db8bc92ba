"""``jointctl serve --record DIR --foxglove 0``: the served robot streamed to a Foxglove WebSocket client while it
is commanded over ROS (a FollowJointTrajectory goal from actionlib), and recorded into trace.csv and run.mcap (one
message per trace row, and the ROS clients' goals as events: the one that moved it, and one refused) when it
stops."""

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
from pathlib import Path

from tests.ros.conftest import wait_for_topic

CLIENT = str(Path(__file__).with_name("action_client.py"))
SERVER = "/one_DOF_robot/joint1_trajectory_controller/follow_joint_trajectory"


def _follow(ros_env, goal: dict) -> dict:
    """An actionlib client's final state and result for ``goal`` (action_client.py's JSON)."""
    result = subprocess.run([sys.executable, CLIENT, "follow", SERVER, json.dumps(goal)], env=ros_env,
                            capture_output=True, text=True, timeout=90)
    return json.loads(result.stdout.strip().splitlines()[-1])


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
    process = subprocess.Popen([sys.executable, "-m", "jointctl.cli", "serve", "one_dof", "--controllers", "trajectory",
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
        moved = _follow(ros_env, {"joint_names": ["joint1"], "points": [[0.5, [-0.4]], [1.0, [-0.3]]]})
        assert moved["state"] == "SUCCEEDED", moved
        refused = _follow(ros_env, {"joint_names": ["joint1"], "points": [[1.0, [5.0]]]})  # above the 0 m limit
        assert refused["state"] == "REJECTED", refused
        received = asyncio.run(_positions(url, 200))
        stamps = [s for s, _ in received]
        assert stamps == sorted(set(stamps))
        assert abs(received[-1][1] + 0.3) < 0.01  # the piston came up to the goal's -0.3 m and held
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
        events = [json.loads(m.data)["message"] for _, _, m in reader.iter_messages(topics=[fm.EVENTS])]
    per_topic = {topics[k]: n for k, n in counts.items()}
    assert len(trace.time_s) > 1000
    assert all(per_topic[t] == len(trace.time_s) for t in fm.PER_CYCLE)
    assert stamps == sorted(stamps) and per_topic[fm.ROBOT_DESCRIPTION] == 1
    goal_events = [e for e in events if e.startswith("joint1_trajectory_controller: goal ")]
    assert [e.split(" ")[2:4] for e in goal_events] == [["1", "starts"], ["1", "succeeded"], ["2", "rejected:"]]
    assert "upper limit" in goal_events[2] and "5.0" in goal_events[2]

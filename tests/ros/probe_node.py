"""A long-lived rospy node that the tests ask for what is on the graph (rospy: one node per process).

    python probe_node.py        (against ROS_MASTER_URI)

Instead of a ``rostopic`` process per look (each costs about a second of Python start-up), the
tests keep this node up for a module and ask it over stdin, one JSON object per line; it answers
each with one JSON line on stdout: ``{"ok": true, ...}`` or ``{"ok": false, "error": "..."}``.

- ``{"op": "messages", "topic": T, "count": n, "timeout": s}``: the first ``n`` messages of ``T``
  that arrive after the request (after the subscription is up, for a new topic: so the first one
  only, as ``rostopic echo -n 1`` would; the subscription ends with the answer unless a cursor
  keeps it), each as ``{"text": what rostopic echo prints, "msg": the
  message as plain JSON}``. The type is the publisher's, asked of the master (as rostopic does);
  waits for a publisher to appear.
- ``{"op": "cursor", "topic": T, "timeout": s}``: subscribes (once a publisher is there) and answers
  ``"cursor"``, the number of messages of ``T`` received so far; from then on every message is kept
  (up to the last 100 000). ``{"op": "messages", ..., "after": cursor}`` then answers the first
  ``count`` messages received after that cursor (``count`` 0: all received so far), waiting for
  them; ``"cursor"`` in the answer is where the answer ends.
- ``{"op": "publish", "topic": T, "type": "std_msgs/Float64", "msg": {...}, "timeout": s}``: once
  some subscriber is connected (as ``rostopic pub -1`` does, without its 3 s linger), publishes.
  ``"connections"`` answers how many subscribers it reached.
- ``{"op": "param", "name": N}``: the parameter (``"missing": true`` when absent).
- ``{"op": "forget"}``: leave every topic, subscribed or published (the cursors end).
- ``{"op": "ping"}``: the node is up.
"""

import json
import math
import sys
import threading
import time

import genpy
import rosgraph
import rospy
from roslib.message import get_message_class

lock = threading.Condition()
#: topic -> (its subscriber, its messages received so far (count), the last few kept)
topics: dict = {}
publishers: dict = {}


def plain(value):
    """A message as JSON: fields by name; times and durations in seconds (and nanoseconds)."""
    if isinstance(value, (genpy.Time, genpy.Duration)):
        return {"secs": value.secs, "nsecs": value.nsecs, "s": value.to_sec(), "ns": value.to_nsec()}
    if isinstance(value, genpy.Message):
        return {name: plain(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, bytes):
        return list(value)
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)  # JSON has no nan or inf: "nan", "inf", "-inf"
    return value


def topic_type(topic: str, deadline: float) -> str | None:
    """The type a publisher of ``topic`` registered, once one has (rostopic's way)."""
    master = rosgraph.Master(rospy.get_name())
    while True:
        publishers_now = {t for t, nodes in master.getSystemState()[0] if nodes}
        if topic in publishers_now:
            types = dict(master.getTopicTypes())
            if topic in types:
                return types[topic]
        if time.monotonic() > deadline:
            return None
        time.sleep(0.05)


def subscribe(topic: str, deadline: float):
    with lock:
        entry = topics.get(topic)
    if entry is not None:
        return entry
    kind = topic_type(topic, deadline)
    if kind is None:
        return None
    entry = {"count": 0, "kept": [], "type": kind, "keep": False}

    def on_message(msg):
        with lock:
            entry["count"] += 1
            entry["kept"].append((entry["count"], msg))
            del entry["kept"][:-100_000]
            lock.notify_all()

    entry["subscriber"] = rospy.Subscriber(topic, get_message_class(kind), on_message, queue_size=2000,
                                           tcp_nodelay=True)
    with lock:
        topics[topic] = entry
    return entry


def messages(request: dict) -> dict:
    topic, count = request["topic"], int(request.get("count", 1))
    deadline = time.monotonic() + float(request.get("timeout", 30.0))
    entry = subscribe(topic, deadline)
    if entry is None:
        return {"ok": False, "error": f"no publisher of {topic} appeared"}
    with lock:
        after = entry["count"] if request.get("after") is None else int(request["after"])
        if count == 0:
            count = entry["count"] - after
        while entry["count"] < after + count:
            left = deadline - time.monotonic()
            if left <= 0:
                return {"ok": False, "error": f"{entry['count'] - after} of {count} messages on {topic} "
                                              f"within the timeout"}
            lock.wait(left)
        got = [msg for k, msg in entry["kept"] if after < k <= after + count]
    if not entry["keep"]:  # a look, not a record: leave the topic (a 1 kHz one costs this node's CPU)
        with lock:
            topics.pop(topic, None)
        entry["subscriber"].unregister()
    text = request.get("text", True)
    return {"ok": True, "type": entry["type"], "cursor": after + count,
            "messages": [{"text": genpy.message.strify_message(m) if text else None, "msg": plain(m)}
                         for m in got]}


def cursor(request: dict) -> dict:
    entry = subscribe(request["topic"], time.monotonic() + float(request.get("timeout", 30.0)))
    if entry is None:
        return {"ok": False, "error": f"no publisher of {request['topic']} appeared"}
    with lock:
        entry["keep"] = True
        return {"ok": True, "cursor": entry["count"]}


def fill(msg, data):
    """Set ``msg``'s fields from plain JSON (nested dicts for nested messages; "nan"/"inf" strings)."""
    for name, value in data.items():
        current = getattr(msg, name)
        if isinstance(current, genpy.Message):
            fill(current, value)
        else:
            if isinstance(value, str) and value in ("nan", "inf", "-inf"):
                value = float(value)
            setattr(msg, name, value)
    return msg


def publish(request: dict) -> dict:
    topic, kind = request["topic"], request["type"]
    key = (topic, kind)
    if key not in publishers:
        publishers[key] = rospy.Publisher(topic, get_message_class(kind), queue_size=100, tcp_nodelay=True)
    publisher = publishers[key]
    deadline = time.monotonic() + float(request.get("timeout", 30.0))
    while publisher.get_num_connections() == 0:
        if time.monotonic() > deadline:
            return {"ok": False, "error": f"no subscriber of {topic} connected"}
        time.sleep(0.01)
    publisher.publish(fill(get_message_class(kind)(), request.get("msg", {})))
    return {"ok": True, "connections": publisher.get_num_connections()}


def param(request: dict) -> dict:
    try:
        return {"ok": True, "value": plain(rospy.get_param(request["name"]))}
    except KeyError:
        return {"ok": True, "missing": True}


def forget(request: dict) -> dict:
    """Leave every topic (the cursors end), subscribed or published."""
    with lock:
        entries = list(topics.values())
        topics.clear()
    for entry in entries:
        entry["subscriber"].unregister()
    for publisher in publishers.values():
        publisher.unregister()
    publishers.clear()
    return {"ok": True}


def main() -> None:
    rospy.init_node("jointctl_test_probe", anonymous=True, disable_signals=True)
    operations = {"messages": messages, "cursor": cursor, "publish": publish, "param": param, "forget": forget,
                  "ping": lambda _: {"ok": True}}
    print(json.dumps({"ok": True, "ready": rospy.get_name()}), flush=True)
    for line in sys.stdin:
        if not line.strip():
            continue
        try:
            request = json.loads(line)
            answer = operations[request["op"]](request)
        except Exception as exc:  # noqa: BLE001 (told to the test, which fails with it)
            answer = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        print(json.dumps(answer), flush=True)
    rospy.signal_shutdown("stdin closed")


if __name__ == "__main__":
    main()

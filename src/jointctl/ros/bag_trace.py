"""One joint's motion read from a rosbag: the joint states a run recorded (``rosbag record``).

A bag of a jointctl run, or of any robot that publishes sensor_msgs/JointState with positions,
velocities and efforts, identifies a joint as a trace.csv does. The joint states are taken from
the topic given, or else from the one JointState topic that names the joint (a bag with several
is refused, naming them). Times are the messages' header stamps (the publisher's clock), or the
time the bag recorded them when a stamp is zero.
"""

from __future__ import annotations

from pathlib import Path

from jointctl.errors import ConfigError

JOINT_STATE_TYPE = "sensor_msgs/JointState"


def read_joint(path: str | Path, joint: str, topic: str | None = None) -> tuple[str, list, list, list, list]:
    """(topic, stamps [s], position, velocity, effort) of ``joint`` in the bag at ``path``."""
    import rosbag

    source = str(path)
    try:
        bag = rosbag.Bag(source)
    except (OSError, rosbag.ROSBagException, ValueError) as exc:
        raise ConfigError(f"cannot read the bag ({exc})", source=source) from None
    with bag:
        topics = {name: info.msg_type for name, info in bag.get_type_and_topic_info().topics.items()}
        if topic is not None:
            if topics.get(topic) != JOINT_STATE_TYPE:
                states = sorted(t for t, kind in topics.items() if kind == JOINT_STATE_TYPE)
                raise ConfigError(f"no {JOINT_STATE_TYPE} topic of that name in the bag (it has: "
                                  f"{', '.join(states) or 'none'})", source=source, field="--topic", value=topic)
            candidates = [topic]
        else:
            candidates = sorted(t for t, kind in topics.items() if kind == JOINT_STATE_TYPE)
        columns: dict[str, tuple[list, list, list, list]] = {}
        for name, msg, recorded in bag.read_messages(topics=candidates):
            if joint not in msg.name:
                continue
            k = list(msg.name).index(joint)
            n = len(msg.name)
            stamp = msg.header.stamp.to_sec() or recorded.to_sec()
            rows = columns.setdefault(name, ([], [], [], []))
            rows[0].append(stamp)
            rows[1].append(msg.position[k])
            rows[2].append(msg.velocity[k] if len(msg.velocity) == n else float("nan"))
            rows[3].append(msg.effort[k] if len(msg.effort) == n else float("nan"))
    if not columns:
        raise ConfigError(f"no {JOINT_STATE_TYPE} message in the bag names the joint (JointState topics: "
                          f"{', '.join(candidates) or 'none'})", source=source, field="--joint", value=joint)
    if len(columns) > 1:
        raise ConfigError(f"several JointState topics name the joint ({', '.join(sorted(columns))}): choose one",
                          source=source, field="--topic", value=None)
    (found, (stamps, q, qd, u)), = columns.items()
    for quantity, values in (("velocity", qd), ("effort", u)):
        if any(v != v for v in values):
            raise ConfigError(f"the joint states on {found} carry no {quantity} for every joint: the fit needs "
                              "position, velocity and effort", source=source, field=quantity, value=None)
    return found, stamps, q, qd, u


__all__ = ["JOINT_STATE_TYPE", "read_joint"]

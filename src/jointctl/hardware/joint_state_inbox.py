"""The joint states another node publishes, as a served robot's hardware takes them: whatever the middleware.

A served robot (``--hardware ros`` or ``ros2``) learns its joints from ``sensor_msgs/JointState`` messages
that may name the joints in any order, leave velocity or effort out (an empty array) or mark an interface the
joint lacks with NaN. :class:`JointStateInbox` is fed each message from the middleware's callback thread
(:meth:`JointStateInbox.take`) and answers the hardware's loop:

- :meth:`JointStateInbox.read_into`: the newest state into the hardware's position, velocity and effort [m or
  rad, per s, N or N·m] in its joints' order (a missing value leaves the last, NaN reads 0), and the fault text
  while none came for ``stale_after_s``;
- :meth:`JointStateInbox.start_recording` / :meth:`JointStateInbox.recorded_all`: every message kept, stamped
  by its publisher [s], for identification (which needs the publisher's full rate, whatever the loop does).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence

from jointctl.errors import JointCtlError

#: A recorded state: stamp [s], then positions, velocities and efforts in the hardware's joint order (None:
#: the message did not carry that value).
Row = tuple[float, tuple, tuple, tuple]


def _column(values: Sequence[float], order: tuple[int, ...], n: int) -> tuple:
    """``values`` in ``order``, None for a missing one (a short array, or NaN: an interface the joint lacks)."""
    if len(values) != n:
        return (None,) * len(order)
    return tuple(values[k] if values[k] == values[k] else None for k in order)


class JointStateInbox:
    """The joint states of ``joint_names`` published on ``topic`` (named in messages and errors)."""

    def __init__(self, joint_names: Sequence[str], topic: str) -> None:
        self.joint_names = tuple(joint_names)
        self.topic = topic
        self._lock = threading.Lock()
        self._latest: tuple[tuple, tuple, tuple, int] | None = None  # position, velocity, effort, names
        self._latest_at = -math.inf
        self._recording: list[Row] | None = None
        self._order: tuple[int, ...] | None = None
        self._names_seen: tuple[str, ...] = ()

    def take(self, names: Sequence[str], stamp_s: float, position: Sequence[float], velocity: Sequence[float],
             effort: Sequence[float]) -> None:
        """One message: the joints it names, its stamp [s] and its arrays (from the callback thread)."""
        names = tuple(names)
        with self._lock:
            if names != self._names_seen:
                self._names_seen = names
                where = {name: k for k, name in enumerate(names)}
                missing = [j for j in self.joint_names if j not in where]
                self._order = None if missing else tuple(where[j] for j in self.joint_names)
            self._latest, self._latest_at = (tuple(position), tuple(velocity), tuple(effort), len(names)), \
                time.monotonic()
            order = self._order
            if self._recording is not None and order is not None:
                n = len(names)
                self._recording.append((stamp_s, tuple(position[k] for k in order), _column(velocity, order, n),
                                        _column(effort, order, n)))

    def complete(self) -> bool:
        """Whether a state naming every joint has arrived."""
        with self._lock:
            return self._latest is not None and self._order is not None

    def missing_error(self, timeout_s: float, hint: str) -> JointCtlError:
        """The error of a wait for a complete state that lasted ``timeout_s`` [s] in vain (``hint``: what to
        check when nothing came at all)."""
        with self._lock:
            seen = self._names_seen
        if seen:
            return JointCtlError(f"the joint states name {', '.join(seen)}, not every joint of the robot "
                                 f"({', '.join(self.joint_names)})", field=self.topic, value=list(seen))
        return JointCtlError(f"no joint state within {timeout_s:g} s ({hint})", field=self.topic, value=None)

    def effort_of(self, k: int) -> float | None:
        """Joint ``k``'s effort in the newest state, or None (none yet, or not carried)."""
        with self._lock:
            latest, order = self._latest, self._order
        if latest is None or order is None or len(latest[2]) != latest[3]:
            return None
        return latest[2][order[k]]

    def read_into(self, position: list[float], velocity: list[float], effort: list[float],
                  stale_after_s: float) -> str | None:
        """The newest state into the lists (the joints' order); returns the hardware's fault text, or None."""
        with self._lock:
            latest, at, order = self._latest, self._latest_at, self._order
        if latest is None or order is None:
            return "no joint state yet"
        positions, velocities, efforts, n = latest
        position[:] = [positions[k] for k in order]
        for target, values in ((velocity, velocities), (effort, efforts)):
            if len(values) == n:
                target[:] = [values[k] if values[k] == values[k] else 0.0 for k in order]
        age = time.monotonic() - at
        return f"no joint state on {self.topic} for {age:.1f} s" if age > stale_after_s else None

    def start_recording(self) -> None:
        """Keep every joint state from now on (see :meth:`recorded_all`)."""
        with self._lock:
            self._recording = []

    def recorded_all(self, k: int) -> tuple[list[float], list[tuple], list[tuple], list[tuple]]:
        """(stamp [s], positions, velocities, efforts) of every state kept since :meth:`start_recording`, each a
        row in the joints' order; recording stops. Refused when a state lacks the joints' velocities or joint
        ``k``'s effort (identification needs them)."""
        with self._lock:
            rows, self._recording = self._recording or [], None
        for quantity, missing in (("velocity", lambda r: any(v is None for v in r[2])),
                                  ("effort", lambda r: r[3][k] is None)):
            if any(missing(r) for r in rows):
                raise JointCtlError(f"the joint states carry no {quantity} for every joint: identification "
                                    "needs position, velocity and the effort applied", field=self.topic,
                                    value=quantity)
        return [r[0] for r in rows], [r[1] for r in rows], [r[2] for r in rows], [r[3] for r in rows]

"""A ros_control robot's ``joint_states`` as a subscriber receives them: a test double of
joint_state_controller/JointStateController over realtime_tools' RealtimePublisher, built from the
upstream sources (ros_controllers noetic-devel ``joint_state_controller.cpp``, realtime_tools
``realtime_publisher.h``) and /work's reference on a real robot's timing:

- the hardware loop runs cycle ``k`` at ``k·period`` of its own clock (the state it reads and the
  effort it writes are cycle ``k``'s) and calls ``update(time, period)`` with ``time`` the wall clock
  at the top of the cycle (``ros::Time::now()``): a cycle cannot start before it is due
  (``ros::Rate::sleep``), so ``time`` is late by a one-sided jitter;
- ``update`` publishes when ``last_publish_time + 1/publish_rate < time`` and the publisher's
  ``trylock`` succeeds, then advances ``last_publish_time`` by ``1/publish_rate`` (not to ``time``),
  and stamps the message with ``time``, carrying cycle ``k``'s positions, velocities and efforts;
- ``trylock`` fails while the publisher's own thread still holds the previous message: the thread
  polls every 500 µs (``publishingLoop``), so it wakes up to half a millisecond after the message,
  later still on a busy machine, and not at all while it is stalled. A cycle whose ``trylock`` fails
  publishes nothing; at a publish rate below the loop's the next cycles catch up, one message per
  cycle, until ``last_publish_time`` is due again (a burst).

Every published message arrives (TCP, in order): what a subscriber sees is the published cycles and
their stamps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: realtime_tools' publishing thread polls for a new message every 500 µs.
POLL_S = 500e-6


@dataclass(frozen=True)
class Timing:
    """How the robot's machine behaves: the loop's lateness (exponential, mean = standard deviation =
    ``jitter_s``, less than a period), the publishing thread's extra delay after its poll
    (exponential, mean ``busy_s``), and ``stalls``: ``(at_s, length_s)`` during which the publishing
    thread does not run at all."""

    jitter_s: float = 0.33e-3
    busy_s: float = 0.1e-3
    stalls: tuple[tuple[float, float], ...] = ()


def joint_state_stream(cycles: int, period_s: float, publish_rate_hz: float, timing: Timing,
                       rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(the published cycles' indices, their stamps [s]) of a loop of ``cycles`` cycles at ``period_s``
    publishing joint states at ``publish_rate_hz`` on a machine timed by ``timing``."""
    lateness = np.minimum(rng.exponential(timing.jitter_s, cycles), 0.95 * period_s)
    wall = np.arange(cycles) * period_s + lateness
    interval = 1.0 / publish_rate_hz
    last_publish = wall[0]
    free_at = -np.inf  # when the publishing thread has handed the previous message out
    published, stamps = [], []
    for k in range(cycles):
        time = wall[k]
        if not last_publish + interval < time:
            continue
        if time < free_at:  # trylock fails: the thread still holds the previous message
            continue
        last_publish += interval
        published.append(k)
        stamps.append(time)
        free_at = time + rng.uniform(0.0, POLL_S) + rng.exponential(timing.busy_s)
        for at, length in timing.stalls:
            if at <= free_at < at + length:
                free_at = at + length
    return np.asarray(published), np.asarray(stamps)

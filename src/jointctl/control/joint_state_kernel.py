"""The compiled form of :class:`~jointctl.control.joint_state_controller.JointStateController` (without
subscribers): its samples at its rate, the latest kept as rows of floats that :func:`unpack_joint_state` turns
back into the controller's :class:`~jointctl.control.joint_state_controller.JointStateSample`."""

from __future__ import annotations

from jointctl.control.joint_state_controller import JointStateController, JointStateSample
from jointctl.jit import kernel

#: The parameters row: the publication period [s].
PERIOD = 0
#: The state row: the next publication's number (a whole number), publications so far, the latest one's time [s].
NEXT_K, PUBLISHED, LATEST_TIME = range(3)
STATE = 3


def pack_joint_state(c: JointStateController) -> tuple[list[float], list[float]]:
    """The parameters and state rows of a joint state controller."""
    latest = c.latest.time_s if c.latest is not None else 0.0
    return [c.period_s], [float(c._next_k), float(c.published), latest]


def unpack_joint_state(c: JointStateController, state, latest, joint_names: tuple[str, ...]) -> None:
    """Put the state row back; ``latest`` (3 x joints: position, velocity, effort) becomes the latest sample when
    the kernel published."""
    published = int(state[PUBLISHED])
    if published != c.published:
        position, velocity, effort = (tuple(row) for row in latest.tolist())
        c.latest = JointStateSample(float(state[LATEST_TIME]), joint_names, position, velocity, effort)
    c.published = published
    c._next_k = int(state[NEXT_K])


@kernel
def joint_state_update(parameters, state, c, latest, time_s, position, velocity, effort):
    """``JointStateController.update`` of row ``c``: a sample on each multiple of the period, kept in
    ``latest[c]``."""
    if time_s + 1e-9 < state[c, NEXT_K] * parameters[c, PERIOD]:
        return
    state[c, NEXT_K] += 1.0
    for j in range(position.shape[0]):
        latest[c, 0, j] = position[j]
        latest[c, 1, j] = velocity[j]
        latest[c, 2, j] = effort[j]
    state[c, LATEST_TIME] = time_s
    state[c, PUBLISHED] += 1.0

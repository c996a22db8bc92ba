"""The compiled form of :class:`~jointctl.control.context.ModelFeedforward`: its ``update`` on arrays, with the
robot's dynamics queried by :mod:`~jointctl.model.dynamics_kernel` (the same MuJoCo functions on the same private
``MjData``), so gravity ``g(q)`` and inertia ``M(q)·q̈_ref`` [N or N·m] are those of the Python, bit for bit.

:class:`FeedforwardArrays` holds one feed-forward's arrays: the dynamics' (:class:`DynamicsArrays`), the map from
hardware joints to the model's, the pose and acceleration buffers in the model's order, whether ``M(q)`` is
wanted, and the ``gravity`` and ``inertia`` outputs per hardware joint, which the position controllers' kernel
reads. :meth:`FeedforwardArrays.unpack` puts the outputs back into the Python object.
"""

from __future__ import annotations

import numpy as np

from jointctl.control.context import ModelFeedforward
from jointctl.jit import kernel
from jointctl.model.dynamics_kernel import DynamicsArrays, dynamics_gravity, dynamics_inertia, dynamics_set_pose


class FeedforwardArrays:
    """What :func:`feedforward_update` needs of ``feedforward`` (None: an empty stand-in, nothing computed)."""

    def __init__(self, feedforward: ModelFeedforward | None) -> None:
        self.feedforward = feedforward
        if feedforward is None:
            self.addresses = np.zeros(2, dtype=np.uintp)
            self.qpos = self.tau = self.qdd_full = self.q = self.qdd = np.zeros(1)
            self.qpos_adr = self.dof_adr = self.to_model = np.zeros(0, dtype=np.int64)
            self.wants_inertia = False
            self.gravity = self.inertia = np.zeros(1)
            self.model_out = np.zeros(1)
            return
        arrays = self._dynamics = DynamicsArrays(feedforward.dynamics)
        self.addresses, self.qpos, self.qpos_adr, self.dof_adr = (arrays.addresses, arrays.qpos, arrays.qpos_adr,
                                                                  arrays.dof_adr)
        self.tau, self.qdd_full = arrays.tau, arrays.qdd
        self.to_model = np.asarray(feedforward._to_model, dtype=np.int64)
        self.q = np.array(feedforward._q, dtype=float)  # joints of the model the hardware lacks keep their value
        self.qdd = np.array(feedforward._qdd, dtype=float)
        self.wants_inertia = bool(feedforward.wants_inertia)
        self.gravity = np.array(feedforward.gravity, dtype=float)
        self.inertia = np.array(feedforward.inertia, dtype=float)
        self.model_out = np.zeros(len(self.q))

    def unpack(self) -> None:
        """Put the buffers and the last cycle's efforts back into the feed-forward."""
        ff = self.feedforward
        if ff is None:
            return
        ff._q[:] = self.q
        ff._qdd[:] = self.qdd
        ff.gravity = self.gravity.tolist()
        ff.inertia = self.inertia.tolist()


@kernel
def feedforward_update(addresses, qpos, qpos_adr, tau, qdd_full, dof_adr, to_model, q, qdd, wants_inertia,
                       model_out, position, reference_accelerations, gravity, inertia):
    """``ModelFeedforward.update``: the pose at the measured ``position`` (hardware order), ``g(q)`` into
    ``gravity`` and, when wanted, ``M(q)·q̈_ref`` into ``inertia`` (hardware order)."""
    for i in range(to_model.shape[0]):
        q[to_model[i]] = position[i]
    dynamics_set_pose(addresses, qpos, qpos_adr, q, wants_inertia)
    dynamics_gravity(addresses, tau, dof_adr, model_out)
    for i in range(to_model.shape[0]):
        gravity[i] = model_out[to_model[i]]
    if wants_inertia:
        for i in range(to_model.shape[0]):
            qdd[to_model[i]] = reference_accelerations[i]
        dynamics_inertia(addresses, tau, qdd_full, dof_adr, qdd, model_out)
        for i in range(to_model.shape[0]):
            inertia[i] = model_out[to_model[i]]

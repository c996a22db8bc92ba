"""What the tuning page's 3D view draws: the world's visible shapes, and their poses as the loop runs.

:class:`SceneTap` is a loop observer: every ``1 / rate_hz`` of loop time it keeps the world's model
and the poses of its visible geoms (see :mod:`jointctl.sim.scene_export`) in one snapshot, replaced
whole, which the server's thread reads: the shapes (a ``scene`` message) when the model changed (an
object spawned or removed), the poses (a ``poses`` message) when they are newer than the last sent.
"""

from __future__ import annotations

from typing import Any

from jointctl.sim.scene_export import geom_poses, visible_ids, visual_geoms


class SceneTap:
    """Snapshots of ``world``'s visible geoms every ``1 / rate_hz`` of loop time."""

    def __init__(self, world, *, rate_hz: float = 30.0, camera: dict | None = None) -> None:
        self.world = world
        self.period_s = 1.0 / rate_hz
        self.camera = camera
        self._next_s = 0.0
        self._ids_of: tuple[Any, list[int]] | None = None
        #: (model, poses, loop time [s], count), or None before the first cycle.
        self.snapshot: tuple[Any, list[list[float]], float, int] | None = None
        self._count = 0

    def __call__(self, time_s: float) -> None:
        last = self.snapshot
        if last is not None and last[2] <= time_s and time_s + 1e-9 < self._next_s:
            return  # (loop time going back, a reset, takes one at once)
        self._next_s = time_s + self.period_s
        model = self.world.model
        if self._ids_of is None or self._ids_of[0] is not model:
            self._ids_of = (model, visible_ids(model))
        self._count += 1
        self.snapshot = (model, geom_poses(model, self.world.data, self._ids_of[1]), time_s, self._count)

    @staticmethod
    def scene_message(model, camera: dict | None) -> dict[str, Any]:
        """The ``scene`` message for ``model``."""
        return {"type": "scene", "geoms": visual_geoms(model), "camera": camera}


__all__ = ["SceneTap"]

"""The compiled form of ``run.mcap``'s :class:`~jointctl.recording.mcap_record.ObjectTrack`: its decimation is the
trace's (:func:`~jointctl.recording.trace_kernel.trace_due`), and on a kept cycle :func:`track_poses` copies each
spawned object's pose (position [m], orientation quaternion w x y z) as the simulation door's ``body_state`` reads
it; :func:`unpack_track` makes the track's samples of them."""

from __future__ import annotations

import numpy as np

from jointctl.jit import kernel
from jointctl.recording.mcap_record import ObjectTrack


def pack_track(track: ObjectTrack) -> list[float]:
    """The track's decimation row (as the trace's: cycles still to skip, and ``every``)."""
    return [float(track._countdown), float(track.every)]


def unpack_track(track: ObjectTrack, state, specs, poses, times) -> None:
    """Keep the samples a compiled stretch took (``poses``: samples x objects x 7) of the objects ``specs``."""
    track._countdown = int(state[0])
    for pose, time_s in zip(poses, times.tolist()):
        track.samples.append((time_s, tuple((spec, np.array(p[:3]), np.array(p[3:])) for spec, p in zip(specs, pose))))
        track._shown = bool(specs)


@kernel
def track_poses(poses, sample, xpos, xquat, bodies):
    """Copy each body's pose (``bodies``: MuJoCo body ids) into ``poses[sample]``."""
    for b in range(bodies.shape[0]):
        body = bodies[b]
        for axis in range(3):
            poses[sample, b, axis] = xpos[body, axis]
        for axis in range(4):
            poses[sample, b, 3 + axis] = xquat[body, axis]

"""A desktop window on a run: MuJoCo's interactive viewer beside the loop, paced to the wall clock.

``jointctl run SCENARIO --view`` (and ``jointctl tune ... --view``) open MuJoCo's passive viewer on
the simulated world: orbit, zoom and pick with the mouse while the loop runs. :class:`LiveViewer`
is a loop observer that hands the world's state to the window about ``refresh_hz`` times a second
of loop time; when an object is spawned the world's model changes and the window is opened again on
the new one. Closing the window ends a run (a tuning session goes on). It needs a display (X11's
``DISPLAY`` or Wayland's ``WAYLAND_DISPLAY``); without one, :func:`check_display` says so in one
line before anything runs.
"""

from __future__ import annotations

import os
import threading
import time

from jointctl.errors import JointCtlError


class ViewerUnavailable(JointCtlError):
    """No display to open the viewer on, or the viewer cannot open."""

    code = "viewer"


def check_display() -> None:
    """Raise :class:`ViewerUnavailable` when there is no display to open a window on."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ViewerUnavailable("no display to open the viewer on (DISPLAY is not set); run it on a desktop, "
                                "or through xvfb-run, or draw a video instead with --video", field="--view")


class LiveViewer:
    """A loop observer syncing MuJoCo's passive viewer with ``world`` (see the module docstring)."""

    def __init__(self, world, loop, *, refresh_hz: float = 60.0, stop_when_closed: bool = True) -> None:
        check_display()
        self.world, self.loop = world, loop
        self.stop_when_closed = stop_when_closed
        self.period_s = 1.0 / refresh_hz
        self._next_s = 0.0
        self._handle = None
        self._model = None
        #: Windows opened so far (one more each time the world's model changes).
        self.opened = 0

    def _open(self) -> None:
        import mujoco.viewer

        if self._handle is not None:
            self._handle.close()
        try:
            self._handle = mujoco.viewer.launch_passive(self.world.model, self.world.data)
        except Exception as exc:  # noqa: BLE001  (no GLFW, a display refusing: one clear error)
            raise ViewerUnavailable(f"the viewer cannot open ({type(exc).__name__}: {exc})", field="--view") from None
        self._model = self.world.model
        self.opened += 1

    def __call__(self, time_s: float) -> None:
        if time_s + 1e-9 < self._next_s:
            return
        self._next_s += self.period_s
        if self._model is not self.world.model:
            self._open()
        if not self._handle.is_running():  # the window was closed
            if self.stop_when_closed:  # a run ends with it; a tuning session goes on without it
                self.loop.request_stop()
            return
        self._handle.sync()

    def close(self, timeout_s: float = 3.0) -> None:
        """Close the window and wait (up to ``timeout_s``) for its thread to let go: a window still
        drawing while the interpreter exits can hang it (GLFW is torn down at exit)."""
        if self._handle is None:
            return
        import mujoco.viewer

        handle, self._handle = self._handle, None
        handle.close()
        # The window's thread runs mujoco.viewer's _launch_internal; it must end before GLFW is
        # terminated at exit, or the interpreter hangs in glfw.terminate.
        deadline = time.monotonic() + timeout_s
        for thread in threading.enumerate():
            if getattr(thread, "_target", None) is mujoco.viewer._launch_internal:
                thread.join(max(0.0, deadline - time.monotonic()))


__all__ = ["LiveViewer", "ViewerUnavailable", "check_display"]

"""Stopping the processes a test started: asked first (SIGTERM), killed if it does not end in time."""

from __future__ import annotations

import subprocess


def stop_process(process: subprocess.Popen, timeout_s: float = 10.0) -> None:
    """Terminate ``process`` unless it has ended, wait ``timeout_s`` [s] for it, then kill it and reap it."""
    if process.poll() is None:
        process.terminate()
    try:
        process.wait(timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(5)


__all__ = ["stop_process"]

"""The kernels' cache: a folder per digest of the kernel sources, or the one given."""

from __future__ import annotations

from jointctl import jit


def test_the_cache_folder_is_named_after_the_kernel_sources(monkeypatch, tmp_path):
    monkeypatch.delenv("JOINTCTL_KERNEL_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    jit.cache_dir.cache_clear()
    try:
        folder = jit.cache_dir()
        assert folder.parent == tmp_path / "jointctl" / "kernels" and len(folder.name) == 16
        names = {p.name for p in jit.kernel_sources()}
        assert {"pid_kernel.py", "cycle.py", "jit.py", "mujoco_kernel.py"} <= names
        monkeypatch.setenv("JOINTCTL_KERNEL_CACHE", str(tmp_path / "given"))
        jit.cache_dir.cache_clear()
        assert jit.cache_dir() == tmp_path / "given"
    finally:
        jit.cache_dir.cache_clear()

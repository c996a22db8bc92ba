"""The compiled cycle: the loop's per-cycle work of the built-in parts in machine code (numba), a stretch of
cycles per call, with the same numbers as the Python loop. :mod:`~jointctl.compiled.plan` chooses it,
:mod:`~jointctl.compiled.run` runs it;
:mod:`~jointctl.compiled.cycle` is the cycle, made of the ``*_kernel`` modules beside the Python they mirror."""

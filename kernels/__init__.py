"""Numba kernels of osmap, installed as `osmap_kernels`: pure functions, arrays in, arrays out.

Every `@njit(cache=True)` kernel here that a command's default run calls is compiled ahead of
its first run, with no list to keep: an installed package carries them compiled for the generic
CPU of its kind in `portable-cache/` (the build step runs each command once and keeps what
Numba compiled), and this CPU's are compiled in the background after the first run
(osmap_cli.kernelwarm).
"""

import os as _os

if _os.environ.get("OSMAP_QUICK_LOADS") == "1":
    from osmap_kernels.cacheload import quick_loads as _quick_loads

    _quick_loads()

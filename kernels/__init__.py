"""Numba kernels of osmap, installed as `osmap_kernels`: pure functions, arrays in, arrays out.

Every `@njit(cache=True)` kernel here that a command's default run calls is compiled ahead of
its first run, with no list to keep: an installed package carries them compiled for the generic
CPU of its kind in `portable-cache/` (the build step runs each command once and keeps what
Numba compiled), and this CPU's are compiled in the background after the first run
(osmap_cli.kernelwarm).
"""

"""Numba kernels of osmap, installed as `osmap_kernels`: pure functions, arrays in, arrays out.

Every `@njit(cache=True)` kernel in a module here is compiled ahead of its first run without any
registration: an installed package carries them compiled for the generic CPU of its kind in
`portable-cache/` (made by the build step from the commands' warm-up runs), and this CPU's are
compiled in the background after the first run (osmap_cli.kernelwarm).
"""

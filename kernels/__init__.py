"""Numba kernels of osmap, installed as `osmap_kernels`: pure functions, arrays in, arrays out."""

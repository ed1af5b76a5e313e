"""From one pyramid level of the volume to the next finer one: exemplar positions and colours.

A volume dimension is halved from one level to the next coarser one, or kept when it is too
short to halve (a thin volume's pyramid, osmap_cli.solid.pipeline.plan_levels): a fine voxel v
then comes from coarse voxel v // 2 (halved) or v (kept). The exemplar is halved in both cases,
so positions double: along a kept side they step two exemplar pixels a voxel until the finer
level's search matches them again (kept sides are under 32 voxels).
"""

from __future__ import annotations

import numpy as np

from osmap_kernels.solid import PLANE


def coarse_index(n: int, m: int):
    """(index, offset) int64 (n,): the coarse voxel (of m) of each of n fine voxels along one
    dimension, and the fine voxel's offset from twice it (halved; 0 where kept: m == n)."""
    factor = 2 if m < n else 1
    idx = np.minimum(np.arange(n) // factor, m - 1)
    return idx, np.arange(n) - factor * idx


def upsample_positions(pos: np.ndarray, shape, lo, hi, ex_of_axis) -> np.ndarray:
    """Each axis' positions at the finer level: 2 S[coarse voxel] + in-plane offset."""
    idx, off = zip(*(coarse_index(n, pos.shape[1 + d]) for d, n in enumerate(shape)))
    coarse = pos[:, idx[0]][:, :, idx[1]][:, :, :, idx[2]].astype(np.int64)
    fine = 2 * coarse
    for a in range(3):
        e = ex_of_axis[a]
        for j in range(2):
            d = PLANE[a, j]
            o = off[d].reshape([-1 if i == d else 1 for i in range(3)])
            fine[a, ..., j] = np.clip(fine[a, ..., j] + o, lo[e, j], hi[e, j])
    return np.ascontiguousarray(fine.astype(np.int32))


def upsample_source(source: np.ndarray, shape, ex_shapes, ex_of_axis) -> np.ndarray:
    """Sources at the finer level: the same axis, 2 (row, col) + in-plane offset."""
    idx, off = zip(*(coarse_index(n, source.shape[d]) for d, n in enumerate(shape)))
    coarse = source[idx[0]][:, idx[1]][:, :, idx[2]].astype(np.int64)
    axis = coarse[..., 0]
    grids = np.meshgrid(*off, indexing="ij")
    fine = np.empty_like(coarse)
    fine[..., 0] = axis
    for j in range(2):
        dims = PLANE[axis, j]  # volume dim of this exemplar coordinate, per voxel
        o = np.choose(dims, grids)
        limit = np.array([ex_shapes[ex_of_axis[a]][j] - 1 for a in range(3)])[axis]
        fine[..., 1 + j] = np.clip(2 * coarse[..., 1 + j] + o, 0, limit)
    return np.ascontiguousarray(fine.astype(np.int32))


def upsample_linear(vol: np.ndarray, shape, wrap: bool) -> np.ndarray:
    """vol (z, y, x, C) resampled to shape (Z, Y, X) by separable linear interpolation, each fine
    voxel at its centre's position in the coarse grid."""
    out = vol.astype(np.float32)
    for d, n in enumerate(shape):
        m = out.shape[d]
        t = (np.arange(n) + 0.5) * (m / n) - 0.5
        i0 = np.floor(t).astype(np.int64)
        f = (t - i0).astype(np.float32)
        i1 = i0 + 1
        if wrap:
            i0, i1 = i0 % m, i1 % m
        else:
            i0, i1 = np.clip(i0, 0, m - 1), np.clip(i1, 0, m - 1)
        f = f.reshape([-1 if k == d else 1 for k in range(out.ndim)])
        out = np.take(out, i0, axis=d) * (1 - f) + np.take(out, i1, axis=d) * f
    return np.ascontiguousarray(out)

"""Cuts through a volume: the axis-aligned slices of the three families (the orientation
osmap uses everywhere: normal to x: rows z, cols y; normal to y: rows z, cols x; normal to z:
rows y, cols x) and oblique planes (what a carved object shows)."""

from __future__ import annotations

import numpy as np

DIAGONALS = ((1.0, 1.0, 1.0), (1.0, -1.0, 1.0), (1.0, 1.0, 0.0), (0.0, 1.0, -1.0))


def axis_slices(volume: np.ndarray, count: int):
    """[(family, index, slice)]: `count` evenly spaced slices per family (0, 1, 2 = normal to
    x, y, z), each (rows, cols, ...)."""
    out = []
    for family, dim in ((0, 2), (1, 1), (2, 0)):
        n = volume.shape[dim]
        for i in np.unique(np.linspace(0, n - 1, min(count, n) + 2)[1:-1].astype(int)):
            out.append((family, int(i), np.take(volume, i, axis=dim)))
    return out


def plane_basis(normal):
    """Two unit vectors (z, y, x) spanning the plane normal to `normal`."""
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    return u, v


def oblique_slice(volume: np.ndarray, normal, side: int | None = None, wrap: bool = False,
                  nearest: bool = False, offset: float = 0.0) -> np.ndarray:
    """The plane through the volume's centre (shifted `offset` voxels along the normal) with
    the given normal (z, y, x), sampled on a side x side grid of unit spacing: trilinear, or
    nearest (labels). Without wrap the grid is kept inside the volume (side: at most 0.55 of
    the shortest side, so a diagonal plane's square fits). An offset of magnitude below 1 is a
    share of the shortest side."""
    shape = np.array(volume.shape[:3], np.float64)
    if side is None:
        side = int(shape.min()) if wrap else max(4, int(0.55 * shape.min()))
    u, v = plane_basis(normal)
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    t = np.arange(side) - (side - 1) / 2.0
    if abs(offset) < 1:
        offset *= shape.min()
    centre = shape / 2.0 - 0.5 + offset * n
    pts = centre + t[:, None, None] * u + t[None, :, None] * v  # (side, side, 3)
    if nearest:
        idx = np.rint(pts).astype(np.int64)
        for d in range(3):
            n_d = volume.shape[d]
            idx[..., d] = idx[..., d] % n_d if wrap else np.clip(idx[..., d], 0, n_d - 1)
        return volume[idx[..., 0], idx[..., 1], idx[..., 2]]
    base = np.floor(pts).astype(np.int64)
    frac = pts - base
    out = 0.0
    for corner in range(8):
        bits = [(corner >> d) & 1 for d in range(3)]
        idx = base + np.array(bits)
        weight = np.ones(pts.shape[:2])
        for d in range(3):
            n_d = volume.shape[d]
            idx[..., d] = idx[..., d] % n_d if wrap else np.clip(idx[..., d], 0, n_d - 1)
            weight = weight * (frac[..., d] if bits[d] else 1.0 - frac[..., d])
        sample = volume[idx[..., 0], idx[..., 1], idx[..., 2]]
        if sample.ndim == 3:
            weight = weight[..., None]
        out = out + weight * sample
    return np.asarray(out, np.float32)

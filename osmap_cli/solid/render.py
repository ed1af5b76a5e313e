"""Re-render a volume from its exemplar positions (`osmap solid --uv-out`) on other maps
aligned with the exemplars (normal, roughness, height ... maps of the same material)."""

from __future__ import annotations

import numpy as np

from osmap_cli.errors import OsmapError


def render_volume(uv: np.ndarray, maps) -> np.ndarray:
    """float32 (Z, Y, X, C): each voxel takes maps[index] at (row v, column u).

    uv: (Z, Y, X, 3) = (u column, v row, index 0/1/2 of the x/y/z exemplar), as written by
    --uv-out. maps: one (h, w, C) image used for every index, or a sequence of three (x, y, z),
    each the size of its exemplar, with equal channel counts. Fractional positions are sampled
    bilinearly (osmap solid writes whole pixels: exact copies).
    """
    uv = np.asarray(uv, np.float32)
    if uv.ndim != 4 or uv.shape[3] != 3:
        raise OsmapError(f"uv: expected shape (Z, Y, X, 3), got {uv.shape}")
    if isinstance(maps, np.ndarray):
        maps = [maps]
    maps = [np.asarray(m, np.float32) for m in maps]
    maps = [m[..., None] if m.ndim == 2 else m for m in maps]
    if len(maps) not in (1, 3) or len({m.shape[2] for m in maps}) != 1:
        raise OsmapError("maps: give one map or three (x, y, z) with the same channel count")
    index = np.rint(uv[..., 2]).astype(np.int64)
    if index.min() < 0 or index.max() > 2:
        raise OsmapError("uv: exemplar index outside 0..2")
    out = np.empty((*uv.shape[:3], maps[0].shape[2]), np.float32)
    for i in range(3):
        mask = index == i
        if not mask.any():
            continue
        image = maps[i if len(maps) == 3 else 0]
        h, w = image.shape[:2]
        u = np.clip(uv[..., 0][mask], 0, w - 1)
        v = np.clip(uv[..., 1][mask], 0, h - 1)
        u0 = np.minimum(np.floor(u).astype(np.int64), w - 1)
        v0 = np.minimum(np.floor(v).astype(np.int64), h - 1)
        u1, v1 = np.minimum(u0 + 1, w - 1), np.minimum(v0 + 1, h - 1)
        fu, fv = (u - u0)[:, None], (v - v0)[:, None]
        out[mask] = ((1 - fv) * ((1 - fu) * image[v0, u0] + fu * image[v0, u1])
                     + fv * ((1 - fu) * image[v1, u0] + fu * image[v1, u1]))
    return out

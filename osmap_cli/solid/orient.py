"""A volume whose material is turned (`osmap solid --orientation RX,RY,RZ`): the material is
synthesized axis-aligned in a box large enough to hold the turned output, then sampled at the
output's voxels turned back (trilinear for colours, nearest for the exemplar positions).

Angles are degrees about the volume's x, then y, then z axis (the material's grain along the
exemplar's x turns as the point (1, 0, 0) does under R = Rz Ry Rx).

>>> rotation_matrix((0, 0, 90)).round(6) @ (1, 0, 0)
array([0., 1., 0.])
>>> enclosing_shape((8, 8, 8), (0, 0, 0))
(8, 8, 8)
"""

from __future__ import annotations

import math

import numpy as np


def rotation_matrix(angles) -> np.ndarray:
    """float64 (3, 3) in (x, y, z) coordinates: Rz @ Ry @ Rx for angles (rx, ry, rz) degrees."""
    rx, ry, rz = (math.radians(a) for a in angles)
    cx, sx, cy, sy, cz, sz = (math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry),
                              math.cos(rz), math.sin(rz))
    mx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    my = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    mz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return mz @ my @ mx


def is_turned(angles) -> bool:
    """Whether the angles turn the material at all."""
    return any(a % 360.0 != 0.0 for a in angles)


def enclosing_shape(shape, angles) -> tuple[int, int, int]:
    """(Z, Y, X) of the axis-aligned material box that covers a `shape` (Z, Y, X) output turned
    by `angles`, with one voxel to spare on every side for the interpolation."""
    if not is_turned(angles):
        return tuple(shape)
    half = (np.array(shape[::-1], np.float64) - 1.0) / 2.0  # (x, y, z)
    back = rotation_matrix(angles).T  # output (x, y, z) -> material (x, y, z)
    reach = np.abs(back) @ half
    x, y, z = (int(math.ceil(2.0 * r + 1e-9)) + 3 for r in reach)
    return (z, y, x)


def _material_coordinates(shape, material_shape, angles) -> np.ndarray:
    """float64 (3, Z, Y, X): for every output voxel, the (x, y, z) index in the material box."""
    zs, ys, xs = (np.arange(n, dtype=np.float64) - (n - 1) / 2.0 for n in shape)
    gz, gy, gx = np.meshgrid(zs, ys, xs, indexing="ij")
    out = np.stack([gx, gy, gz], 0)  # (3, Z, Y, X): x, y, z about the output's centre
    back = rotation_matrix(angles).T
    q = np.tensordot(back, out, axes=1)
    centre = (np.array(material_shape[::-1], np.float64) - 1.0) / 2.0
    return q + centre[:, None, None, None]


def turn_volume(voxels: np.ndarray, source: np.ndarray, shape, angles):
    """(voxels float32 (Z, Y, X, C), source int32 (Z, Y, X, 3)) of the `shape` output sampled
    from the axis-aligned material (`voxels`, `source` of enclosing_shape(shape, angles))."""
    q = _material_coordinates(shape, voxels.shape[:3], angles)
    limits = np.array(voxels.shape[2::-1])  # (X, Y, Z)
    base = np.floor(q).astype(np.int64)
    frac = q - base
    base = np.clip(base, 0, (limits - 2)[:, None, None, None])
    frac = np.clip(frac, 0.0, 1.0)
    bx, by, bz = base
    fx, fy, fz = (f[..., None] for f in frac)
    out = np.zeros((*shape, voxels.shape[3]), np.float64)
    for dz in (0, 1):
        wz = fz if dz else 1.0 - fz
        for dy in (0, 1):
            wy = fy if dy else 1.0 - fy
            for dx in (0, 1):
                wx = fx if dx else 1.0 - fx
                out += wz * wy * wx * voxels[bz + dz, by + dy, bx + dx]
    near = np.clip(np.rint(q).astype(np.int64), 0, (limits - 1)[:, None, None, None])
    turned_source = source[near[2], near[1], near[0]]
    return (np.ascontiguousarray(out, np.float32), np.ascontiguousarray(turned_source, np.int32))

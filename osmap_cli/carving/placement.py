"""Where the material sits on the object: object coordinates -> volume coordinates (voxels).

The object's bounding box centre goes to the volume's centre (moved by --offset), the material
is turned by --rotate (degrees about x, then y, then z: R = Rz Ry Rx turns the material's axes,
so a point's material coordinates are s R^T (p - centre)), and --scale sets s: `fit` makes the
turned object fill the volume along its tightest axis, N is N voxels per object unit, Nx repeats
the volume N times across the object's longest side.

>>> import numpy as np
>>> A, b = material_transform(np.array([[0., 0, 0], [2, 1, 1]]), (32, 32, 64),
...                           "fit", 1.0, (0, 0, 0), (0, 0, 0))
>>> A @ [2., 1, 1] + b
array([64., 32., 32.])
"""

from __future__ import annotations

import math

import numpy as np

from osmap_cli.errors import OsmapError

__all__ = ["material_transform", "overrun", "turn"]


def turn(angles) -> np.ndarray:
    """(3, 3) Rz @ Ry @ Rx for ANGLES (rx, ry, rz) in degrees, in (x, y, z) coordinates."""
    matrix = np.eye(3)
    for axis, degrees in enumerate(angles):
        c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
        i, j = [k for k in range(3) if k != axis]
        step = np.eye(3)
        step[i, i], step[i, j], step[j, i], step[j, j] = c, -s, s, c
        matrix = step @ matrix
    return matrix


def material_transform(vertices, shape, mode: str, scale: float, offset, angles):
    """(A (3, 3), b (3,)): q = A p + b takes an object point p to voxel coordinates q = (x, y, z)
    of a volume of SHAPE (Z, Y, X)."""
    size = np.array(tuple(shape)[2::-1], np.float64)  # (X, Y, Z)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre = (lo + hi) / 2.0
    back = turn(angles).T
    extent = np.ptp((vertices - centre) @ back.T, axis=0)
    used = extent > 1e-12 * max(1.0, float(np.abs(vertices).max()))
    if not used.any():
        raise OsmapError("the object has no extent to place the volume on")
    if mode == "fit":
        s = float(np.min(size[used] / extent[used]))
    elif mode == "repeats":
        k = int(np.argmax(extent))
        s = scale * size[k] / extent[k]
    else:
        s = float(scale)
    A = s * back
    b = size / 2.0 + np.asarray(offset, np.float64) - A @ centre
    return A, b


def overrun(points_q, shape) -> float:
    """The fraction of the points (voxel coordinates) outside the volume (beyond rounding)."""
    size = np.array(tuple(shape)[2::-1], np.float64)
    slack = 1e-6 * size
    outside = np.any((points_q < -slack) | (points_q > size + slack), axis=1)
    return float(outside.mean()) if len(outside) else 0.0

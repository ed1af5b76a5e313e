"""Occupancy: how much each exemplar pixel is used, blurred and relative to uniform use (the
search's penalty on over-used exemplar regions)."""

from __future__ import annotations

import numpy as np


def occupancy(counts: np.ndarray, samples: int, radius: int = 2) -> np.ndarray:
    """float32 (..., h, w): counts (..., h, w), how many of the `samples` output pixels or voxels
    use each exemplar pixel, box-blurred over (2 radius + 1)^2 pixels and divided by what
    uniform use would give there: 1 where use is uniform."""
    counts = np.asarray(counts, np.float64)
    size = 2 * radius + 1
    lead = [(0, 0)] * (counts.ndim - 2)
    padded = np.pad(counts, lead + [(radius, radius), (radius, radius)])
    csum = np.pad(padded.cumsum(-2).cumsum(-1), lead + [(1, 0), (1, 0)])
    box = (csum[..., size:, size:] - csum[..., :-size, size:] - csum[..., size:, :-size]
           + csum[..., :-size, :-size])
    expected = samples / float(counts.size) * size * size
    return np.ascontiguousarray((box / expected).astype(np.float32))

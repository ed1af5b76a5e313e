"""The refinement kernel's shortcut for settled pixels (kernels/coherence.py) makes the same
decision as the full candidate search, pixel for pixel."""

from __future__ import annotations

import numpy as np
import pytest

from osmap_kernels.coherence import KnnParams, RefineParams, knn_table, refine_pass
from osmap_kernels.regions import copy_region_areas

# a lattice table of one region without a lattice: the same candidates as none, but the kernel
# then searches every pixel in full (the shortcut needs no table)
_FULL_SEARCH = np.zeros((1, 18), np.float64)


def _copies(shape, source, radius, block, rng):
    """A position field of square copies of the exemplar (float32, integral), each block of
    `block` pixels continuing one random offset, kept inside the valid box."""
    H, W = shape
    ys, xs = np.mgrid[0:H, 0:W]
    pos = np.empty((H, W, 2), np.float32)
    for by in range(0, H, block):
        for bx in range(0, W, block):
            oy = rng.integers(radius, source[0] - radius - block)
            ox = rng.integers(radius, source[1] - radius - block)
            sl = np.s_[by:by + block, bx:bx + block]
            pos[sl + (0,)] = oy + ys[sl] - by
            pos[sl + (1,)] = ox + xs[sl] - bx
    return pos


@pytest.mark.parametrize("wrap, guided, max_area, seam", [
    (False, False, 40.0, 1.5), (True, False, 60.0, 1.5), (False, True, 40.0, 0.7),
    (True, True, 200.0, 0.0)])
def test_settled_pixels_keep_what_the_full_search_gives(wrap, guided, max_area, seam):
    rng = np.random.default_rng(7)
    h, w, radius = 40, 44, 2
    feat = rng.standard_normal((h, w, 6)).astype(np.float32)
    # faint features: matching costs little beside the seam terms, so the seam decides, and a
    # shortcut taken a little too often would keep positions the full search moves
    feat = (0.02 * (feat + np.roll(feat, 1, 0) + np.roll(feat, 1, 1))).astype(np.float32)
    src = _copies((36, 40), (h, w), radius, 9, rng)
    jac = np.broadcast_to(np.eye(2, dtype=np.float32), (36, 40, 2, 2)).copy()
    knn = knn_table(feat, KnnParams((radius, radius), (h - 1 - radius, w - 1 - radius), 3, 2, 2))
    occ = rng.random((h, w)).astype(np.float32)
    area = copy_region_areas(src, jac, wrap)
    gex = rng.random((h, w)).astype(np.float32) if guided else np.zeros((1, 1), np.float32)
    gout = rng.random((36, 40)).astype(np.float32) if guided else np.zeros((1, 1), np.float32)
    moved = 0
    for parity in (0, 1):
        p = RefineParams(radius=radius, lam=0.5, wrap=wrap, lo=(2.0, 2.0),
                         hi=(h - 3.0, w - 3.0), n_random=3, seed=np.uint64(5),
                         salt=np.uint64(11 + parity), parity=parity, seam=seam,
                         max_area=max_area, guide=0.4 if guided else 0.0)
        fast = src.copy()
        refine_pass(src, fast, feat, jac, knn, occ, area, gex, gout, p)
        full = src.copy()
        refine_pass(src, full, feat, jac, knn, occ, area, gex, gout, p, table=_FULL_SEARCH,
                    regions=np.zeros((h, w), np.int32))
        assert fast.tobytes() == full.tobytes()
        moved += int((fast != src).any(axis=2).sum())
    assert moved > 0, "the search moved no pixel: nothing was compared"

"""Under one integral lattice the refinement kernel's shortcut for settled pixels
(kernels/coherence.py) keeps the decisions of the full search: the same lattice given as a table
of one region (which the kernel searches in full) gives the same field, byte for byte."""

from __future__ import annotations

import numpy as np
import pytest

from osmap_kernels.coherence import KnnParams, RefineParams, knn_table, refine_pass
from osmap_kernels.lattice import LatticeParams
from osmap_kernels.regions import copy_region_areas

PERIOD = 4


def lattice_copies(shape, source, radius, block, rng):
    """Square copies of the exemplar whose offsets are whole periods: consistent with the
    lattice of period PERIOD on both axes (float32, integral positions)."""
    H, W = shape
    ys, xs = np.mgrid[0:H, 0:W]
    pos = np.empty((H, W, 2), np.float32)
    for by in range(0, H, block):
        for bx in range(0, W, block):
            oy = PERIOD * rng.integers(1, (source[0] - radius - block - by % PERIOD) // PERIOD)
            ox = PERIOD * rng.integers(1, (source[1] - radius - block - bx % PERIOD) // PERIOD)
            sl = np.s_[by:by + block, bx:bx + block]
            pos[sl + (0,)] = oy + ys[sl]
            pos[sl + (1,)] = ox + xs[sl]
    return pos


@pytest.mark.parametrize("wrap, seam, scale", [(False, 1.5, 0.3), (True, 0.7, 0.1)])
def test_settled_pixels_under_a_lattice_keep_what_the_full_search_gives(wrap, seam, scale):
    rng = np.random.default_rng(11)
    h, w, radius = 44, 44, 2
    feat = rng.standard_normal((h, w, 6))
    feat = (scale * (feat + np.roll(feat, 1, 0) + np.roll(feat, 1, 1))).astype(np.float32)
    src = lattice_copies((32, 40), (h, w), radius, 8, rng)
    jac = np.broadcast_to(np.eye(2, dtype=np.float32), (32, 40, 2, 2)).copy()
    knn = knn_table(feat, KnnParams((radius, radius), (h - 1 - radius, w - 1 - radius), 3, 2, 2))
    occ = rng.random((h, w)).astype(np.float32)
    area = copy_region_areas(src, jac, wrap)
    none = np.zeros((1, 1), np.float32)
    inv = 1.0 / PERIOD
    period = float(PERIOD)
    fields = (2, inv, 0.0, 0.0, inv, period, 0.0, 0.0, period, inv, 0.0, 0.0, inv, 0.0, 0.0)
    lattice = LatticeParams(*fields, True, 0, 0.5)
    table = np.array([[*fields, 1.0, 0.0, 0.5]], np.float64)
    moved = 0
    for parity in (0, 1):
        p = RefineParams(radius=radius, lam=0.5, wrap=wrap, lo=(2.0, 2.0),
                         hi=(h - 3.0, w - 3.0), n_random=3, seed=np.uint64(5),
                         salt=np.uint64(21 + parity), parity=parity, seam=seam,
                         max_area=60.0, guide=0.0)
        fast = src.copy()
        refine_pass(src, fast, feat, jac, knn, occ, area, none, none, p, lattice)
        full = src.copy()
        refine_pass(src, full, feat, jac, knn, occ, area, none, none, p, table=table,
                    regions=np.zeros((h, w), np.int32))
        assert fast.tobytes() == full.tobytes()
        moved += int((fast != src).any(axis=2).sum())
    assert moved > 0, "the search moved no pixel: nothing was compared"

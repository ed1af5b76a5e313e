"""The refinement kernel's shortcut for settled pixels (kernels/coherence.py) makes the same
decision as the full candidate search, pixel for pixel, without a lattice and under one
integral lattice."""

from __future__ import annotations

import numpy as np
import pytest

from osmap_kernels.coherence import KnnParams, RefineParams, knn_table, refine_pass
from osmap_kernels.lattice import NO_LATTICE, LatticeParams
from osmap_kernels.regions import copy_region_areas

# a lattice table of one region without a lattice: the same candidates as none, but the kernel
# then searches every pixel in full (the shortcut needs no table)
_FULL_SEARCH = np.zeros((1, 18), np.float64)
_UNGUIDED = np.zeros((1, 1), np.float32)
PERIOD = 4  # the lattice of the lattice test: period 4 on both axes


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


def _assert_shortcut_keeps_full_search(src, feat, occ, *, radius, wrap, seam, max_area, salt,
                                       guide=0.0, gex=_UNGUIDED, gout=_UNGUIDED,
                                       lattice=NO_LATTICE, table=_FULL_SEARCH):
    """Both parities of a pass from `src`: the pass with its shortcut (under `lattice`) writes
    the same field, byte for byte, as the same pass told by `table` to search every pixel in
    full; and the search moves some pixel, so something was compared."""
    h, w = feat.shape[:2]
    jac = np.broadcast_to(np.eye(2, dtype=np.float32), src.shape[:2] + (2, 2)).copy()
    knn = knn_table(feat, KnnParams((radius, radius), (h - 1 - radius, w - 1 - radius), 3, 2, 2))
    area = copy_region_areas(src, jac, wrap)
    moved = 0
    for parity in (0, 1):
        p = RefineParams(radius=radius, lam=0.5, wrap=wrap, lo=(2.0, 2.0),
                         hi=(h - 3.0, w - 3.0), n_random=3, seed=np.uint64(5),
                         salt=np.uint64(salt + parity), parity=parity, seam=seam,
                         max_area=max_area, guide=guide)
        fast = src.copy()
        refine_pass(src, fast, feat, jac, knn, occ, area, gex, gout, p, lattice)
        full = src.copy()
        refine_pass(src, full, feat, jac, knn, occ, area, gex, gout, p, table=table,
                    regions=np.zeros((h, w), np.int32))
        assert fast.tobytes() == full.tobytes()
        moved += int((fast != src).any(axis=2).sum())
    assert moved > 0, "the search moved no pixel: nothing was compared"


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
    occ = rng.random((h, w)).astype(np.float32)
    gex = rng.random((h, w)).astype(np.float32) if guided else _UNGUIDED
    gout = rng.random((36, 40)).astype(np.float32) if guided else _UNGUIDED
    _assert_shortcut_keeps_full_search(src, feat, occ, radius=radius, wrap=wrap, seam=seam,
                                       max_area=max_area, salt=11, guide=0.4 if guided else 0.0,
                                       gex=gex, gout=gout)


def _lattice_copies(shape, source, radius, block, rng):
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
    """Under one integral lattice the shortcut holds too: the same lattice given as a table of
    one region (which the kernel searches in full) gives the same field."""
    rng = np.random.default_rng(11)
    h, w, radius = 44, 44, 2
    feat = rng.standard_normal((h, w, 6))
    feat = (scale * (feat + np.roll(feat, 1, 0) + np.roll(feat, 1, 1))).astype(np.float32)
    src = _lattice_copies((32, 40), (h, w), radius, 8, rng)
    occ = rng.random((h, w)).astype(np.float32)
    inv, period = 1.0 / PERIOD, float(PERIOD)
    fields = (2, inv, 0.0, 0.0, inv, period, 0.0, 0.0, period, inv, 0.0, 0.0, inv, 0.0, 0.0)
    _assert_shortcut_keeps_full_search(
        src, feat, occ, radius=radius, wrap=wrap, seam=seam, max_area=60.0, salt=21,
        lattice=LatticeParams(*fields, True, 0, 0.5),
        table=np.array([[*fields, 1.0, 0.0, 0.5]], np.float64))

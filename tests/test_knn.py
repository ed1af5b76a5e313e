"""The k-NN table of similar positions (osmap_kernels.coherence.knn_table) is the direct search's,
entry for entry: its matrix-product screen only skips references that cannot be among the k
nearest, also among exact ties and when distances are tiny beside the features' norms."""

from __future__ import annotations

import numpy as np
import pytest

from osmap_kernels.coherence import KnnParams, knn_table


def direct_search(feat, p):
    """Every reference's distance summed as the kernel sums it (float32 differences squared,
    added in float64 in feature order), the k smallest kept in scan order on ties."""
    h, w, nf = feat.shape
    ref_y = np.arange(p.lo[0], p.hi[0] + 1, p.stride)
    ref_x = np.arange(p.lo[1], p.hi[1] + 1, p.stride)
    ry, rx = (a.ravel() for a in np.meshgrid(ref_y, ref_x, indexing="ij"))
    refs = feat[ry, rx]
    out = np.zeros((h, w, p.k, 2), np.int32)
    for y in range(h):
        for x in range(w):
            diff = feat[y, x] - refs
            dist = np.zeros(len(refs))
            for f in range(nf):
                dist += (diff[:, f] * diff[:, f]).astype(np.float64)
            allowed = ~((np.abs(ry - y) <= p.exclude) & (np.abs(rx - x) <= p.exclude))
            order = [i for i in np.argsort(dist, kind="stable") if allowed[i]][:p.k]
            out[y, x, :, 0] = min(max(y, p.lo[0]), p.hi[0])
            out[y, x, :, 1] = min(max(x, p.lo[1]), p.hi[1])
            for j, i in enumerate(order):
                out[y, x, j] = ry[i], rx[i]
    return out


@pytest.mark.parametrize("kind", ["random", "ties", "large norms", "few references"])
def test_the_table_is_the_direct_search(kind):
    rng = np.random.default_rng(5)
    feat = rng.standard_normal((14, 17, 6))
    p = KnnParams((1, 2), (12, 15), 4, 2, 2)
    if kind == "ties":
        feat = np.round(feat)
    elif kind == "large norms":
        feat = 40.0 + 1e-4 * feat
    elif kind == "few references":
        p = KnnParams((3, 3), (5, 6), 6, 2, 1)
    feat = feat.astype(np.float32)
    assert np.array_equal(knn_table(feat, p), direct_search(feat, p))

"""The guided window search of the structure-first fill: Kopf et al.'s slice-window search
(osmap_kernels.kopf conventions: PLANE, sparse window centres every `stride` voxels, PCA-reduced
window vectors) where every window also carries guide channels of its own slice family: the
structure as that slice shows it (the in-plane signed distance to the phase boundary, the
particle's or phase's identity), matched against the same channels computed on the exemplar.

Jacobi pass with hashed random numbers: results do not depend on the thread count.
"""

import numpy as np
from numba import njit, prange

from osmap_kernels.common import hash_uniform
from osmap_kernels.kopf import _at, _dist, _is_centre


@njit(cache=True, inline="always")
def _query(vol, guide, z, y, x, a, n, shape, wrap, basis, mean, window, query):
    """The PCA coordinates of the window of axis a centred at (z, y, x): colour channels from
    vol, guide channels from guide[a] (row, column, channel order: colour then guide)."""
    h0 = n // 2
    nc = vol.shape[3]
    ng = guide.shape[4]
    i = 0
    for ir in range(n):
        for ic in range(n):
            qz, qy, qx = _at(z, y, x, a, ir - h0, ic - h0, shape, wrap)
            for ch in range(nc):
                window[i] = vol[qz, qy, qx, ch] - mean[i]
                i += 1
            for ch in range(ng):
                window[i] = guide[a, qz, qy, qx, ch] - mean[i]
                i += 1
    query[:] = 0.0
    for j in range(window.shape[0]):
        w = window[j]
        for d in range(query.shape[0]):
            query[d] += w * basis[j, d]


@njit(cache=True, parallel=True)
def guided_search(vol, guide, pos, new_pos, dist, feats, basis, mean, ex_of_axis, knn, p):
    """Per window centre and axis: the exemplar window nearest (PCA space, colour + guide) to
    the volume's. Candidates: the current match, the 8 neighbouring centres' matches shifted
    to this centre and their knn similar positions, p.n_random random positions; or every valid
    position (p.exhaustive). p: osmap_kernels.kopf.KopfSearch. guide: float32 (3, Z, Y, X, G)."""
    nz, ny, nx = vol.shape[0], vol.shape[1], vol.shape[2]
    shape = (nz, ny, nx)
    n = p.size
    s = p.stride
    k = knn.shape[3]
    dims = basis.shape[1]
    for z in prange(nz):
        window = np.empty(basis.shape[0], np.float64)
        query = np.empty(dims, np.float64)
        for y in range(ny):
            for x in range(nx):
                for a in range(3):
                    new_pos[a, z, y, x, 0] = pos[a, z, y, x, 0]
                    new_pos[a, z, y, x, 1] = pos[a, z, y, x, 1]
                    if not _is_centre(z, y, x, a, s):
                        continue
                    e = ex_of_axis[a]
                    _query(vol, guide, z, y, x, a, n, shape, p.wrap, basis, mean, window, query)
                    lr, hr = p.lo[e, 0], p.hi[e, 0]
                    lc, hc = p.lo[e, 1], p.hi[e, 1]
                    br = min(max(pos[a, z, y, x, 0], lr), hr)
                    bc = min(max(pos[a, z, y, x, 1], lc), hc)
                    best = _dist(query, feats, e, br, bc, np.inf)
                    if p.exhaustive:
                        for r in range(lr, hr + 1):
                            for c in range(lc, hc + 1):
                                dd = _dist(query, feats, e, r, c, best)
                                if dd < best:
                                    best, br, bc = dd, r, c
                    else:
                        for dr in range(-1, 2):
                            for dc in range(-1, 2):
                                if dr == 0 and dc == 0:
                                    continue
                                qz, qy, qx = _at(z, y, x, a, dr * s, dc * s, shape, p.wrap)
                                pr = pos[a, qz, qy, qx, 0]
                                pc = pos[a, qz, qy, qx, 1]
                                for m in range(k + 1):
                                    if m == 0:
                                        r, c = pr - dr * s, pc - dc * s
                                    else:
                                        rr = min(max(pr, lr), hr)
                                        cc = min(max(pc, lc), hc)
                                        r = knn[e, rr, cc, m - 1, 0] - dr * s
                                        c = knn[e, rr, cc, m - 1, 1] - dc * s
                                    if r < lr or r > hr or c < lc or c > hc:
                                        continue
                                    dd = _dist(query, feats, e, r, c, best)
                                    if dd < best:
                                        best, br, bc = dd, r, c
                        vid = np.uint64(((z * ny + y) * nx + x) * 3 + a)
                        for m in range(p.n_random):
                            r = lr + min(int(hash_uniform(p.seed, p.salt, vid, 2 * m)
                                             * (hr - lr + 1)), hr - lr)
                            c = lc + min(int(hash_uniform(p.seed, p.salt, vid, 2 * m + 1)
                                             * (hc - lc + 1)), hc - lc)
                            dd = _dist(query, feats, e, r, c, best)
                            if dd < best:
                                best, br, bc = dd, r, c
                    new_pos[a, z, y, x, 0] = br
                    new_pos[a, z, y, x, 1] = bc
                    dist[a, z, y, x] = best

"""Kernels of the texture optimisation of Kopf et al. 2007 ("Solid Texture Synthesis from 2D
Exemplars") and of the sharpening passes built on it.

Conventions are those of osmap_kernels.solid: axis a's slices (a = 0, 1, 2: normal to x, y, z)
have the exemplar's rows / columns along the volume dims PLANE[a] of (z, y, x). An n x n window
covers the in-plane offsets -h0 .. n - 1 - h0 (h0 = n // 2) around its centre. Only voxels whose
two in-plane coordinates are multiples of `stride` are window centres of axis a (Kopf's sparse
neighbourhoods); pos[a, z, y, x] = (row, col) is the exemplar position matched to the window of
axis a centred there (undefined elsewhere), dist the squared distance of that match in the
PCA-reduced space.

Every kernel is a Jacobi pass (reads one array, writes another) and random numbers are hashes of
(seed, salt, voxel): results do not depend on the thread count.
"""

from collections import namedtuple

import numpy as np
from numba import njit, prange

from osmap_kernels.common import hash_uniform
from osmap_kernels.solid import PLANE

# Parameters of a search pass.
#   size        int64       window side n (offsets -n//2 .. n - 1 - n//2)
#   stride      int64       window centres every `stride` voxels in the plane
#   wrap        bool        the volume is toroidal
#   exhaustive  bool        try every valid exemplar position (coarsest level)
#   n_random    int64       random candidates per window (besides propagation and k-coherence)
#   lo, hi      int64[E, 2] valid window centres per exemplar
#   seed, salt  uint64
KopfSearch = namedtuple("KopfSearch", "size stride wrap exhaustive n_random lo hi seed salt")

# Parameters of an optimisation (averaging) pass.
#   size, stride, wrap  as above
#   window      float64[n, n] weight of each window pixel (1: flat, Kopf; centre-weighted)
# A proposal's weight is centre_weight[a, centre] (the IRLS weight of the window's match,
# (squared distance + eps) ** ((r - 2) / 2)) x window[pixel] x pixel_weight[e, row, col].
KopfAverage = namedtuple("KopfAverage", "size stride wrap window")


@njit(cache=True, inline="always")
def _fix(q, n, wrap):
    if wrap:
        return np.int64(q % n)
    if q < 0:
        return np.int64(0)
    if q >= n:
        return np.int64(n - 1)
    return np.int64(q)


@njit(cache=True, inline="always")
def _at(z, y, x, a, dr, dc, shape, wrap):
    """Voxel at in-plane offset (dr, dc) of axis a from (z, y, x), wrapped or clamped.
    Axis 0 (x): rows z, cols y; 1 (y): rows z, cols x; 2 (z): rows y, cols x."""
    if a == 0:
        return _fix(z + dr, shape[0], wrap), _fix(y + dc, shape[1], wrap), np.int64(x)
    if a == 1:
        return _fix(z + dr, shape[0], wrap), np.int64(y), _fix(x + dc, shape[2], wrap)
    return np.int64(z), _fix(y + dr, shape[1], wrap), _fix(x + dc, shape[2], wrap)


@njit(cache=True, inline="always")
def _is_centre(z, y, x, a, stride):
    for j in range(2):
        d = PLANE[a, j]
        v = z if d == 0 else (y if d == 1 else x)
        if v % stride != 0:
            return False
    return True


@njit(cache=True, inline="always")
def _dist(query, feats, e, r, c, best):
    s = 0.0
    for d in range(query.shape[0]):
        t = query[d] - feats[e, r, c, d]
        s += t * t
        if s >= best:
            return s
    return s


@njit(cache=True, parallel=True)
def kopf_search(vol, guide, pos, new_pos, dist, feats, basis, mean, ex_of_axis, knn, p):
    """Per window centre and axis: the exemplar window nearest to the volume's window in the
    PCA space (basis: (n*n*(C+G), D), mean: (n*n*(C+G),), feats: (E, H, W, D) exemplar windows
    projected). Each window pixel holds the volume's C colours, then the G guide channels of its
    slice family, guide[a] (float32 (3, Z, Y, X, G); G = 0: colours only): the structure as
    that family's slices show it, matched against the same channels of the exemplar windows.
    Candidates: the current match, the matches of the 8 neighbouring centres shifted to this
    centre (and their knn similar positions), random positions; or all (exhaustive)."""
    nz, ny, nx = vol.shape[0], vol.shape[1], vol.shape[2]
    shape = (nz, ny, nx)
    n = p.size
    h0 = n // 2
    nc = vol.shape[3]
    ng = guide.shape[4]
    dims = basis.shape[1]
    s = p.stride
    k = knn.shape[3]
    for z in prange(nz):
        window = np.empty(n * n * (nc + ng), np.float64)
        query = np.empty(dims, np.float64)
        for y in range(ny):
            for x in range(nx):
                for a in range(3):
                    new_pos[a, z, y, x, 0] = pos[a, z, y, x, 0]
                    new_pos[a, z, y, x, 1] = pos[a, z, y, x, 1]
                    if not _is_centre(z, y, x, a, s):
                        continue
                    e = ex_of_axis[a]
                    i = 0
                    for ir in range(n):
                        for ic in range(n):
                            qz, qy, qx = _at(z, y, x, a, ir - h0, ic - h0, shape, p.wrap)
                            for ch in range(nc):
                                window[i] = vol[qz, qy, qx, ch] - mean[i]
                                i += 1
                            for ch in range(ng):
                                window[i] = guide[a, qz, qy, qx, ch] - mean[i]
                                i += 1
                    # j outer, d inner: each query[d] still sums in j order (same bits as a
                    # dot product per d), but the inner loop runs along a basis row: SIMD
                    query[:] = 0.0
                    for j in range(n * n * (nc + ng)):
                        w = window[j]
                        for d in range(dims):
                            query[d] += w * basis[j, d]
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
                                r0 = pos[a, qz, qy, qx, 0] - dr * s
                                c0 = pos[a, qz, qy, qx, 1] - dc * s
                                for m in range(k + 1):
                                    if m == 0:
                                        r, c = r0, c0
                                    else:
                                        rr = min(max(pos[a, qz, qy, qx, 0], lr), hr)
                                        cc = min(max(pos[a, qz, qy, qx, 1], lc), hc)
                                        r = knn[e, rr, cc, m - 1, 0] - dr * s
                                        c = knn[e, rr, cc, m - 1, 1] - dc * s
                                    if r < lr or r > hr or c < lc or c > hc:
                                        continue
                                    dd = _dist(query, feats, e, r, c, best)
                                    if dd < best:
                                        best, br, bc = dd, r, c
                        vid = np.uint64(((z * ny + y) * nx + x) * 3 + a)
                        for m in range(p.n_random):
                            u = hash_uniform(p.seed, p.salt, vid, 2 * m)
                            v = hash_uniform(p.seed, p.salt, vid, 2 * m + 1)
                            r = lr + min(int(u * (hr - lr + 1)), hr - lr)
                            c = lc + min(int(v * (hc - lc + 1)), hc - lc)
                            dd = _dist(query, feats, e, r, c, best)
                            if dd < best:
                                best, br, bc = dd, r, c
                    new_pos[a, z, y, x, 0] = br
                    new_pos[a, z, y, x, 1] = bc
                    dist[a, z, y, x] = best


@njit(cache=True, inline="always")
def _covering(z, y, x, pos, shape, n, s, wrap, cand):
    """The windows of all three slice families that cover voxel (z, y, x), in a fixed order:
    cand[j] = (axis, exemplar row and column of the voxel's pixel, window row and column, the
    window centre's z, y, x); returns how many."""
    h0 = n // 2
    m = 0
    for a in range(3):
        vr = z if a < 2 else y
        vc = y if a == 0 else x
        for ir in range((vr + h0) % s, n, s):
            dr = ir - h0
            for ic in range((vc + h0) % s, n, s):
                dc = ic - h0
                cz, cy, cx = _at(z, y, x, a, -dr, -dc, shape, True)
                if not _is_centre(cz, cy, cx, a, s):
                    continue
                if not wrap:
                    oz, oy, ox = _at(z, y, x, a, -dr, -dc, shape, False)
                    if oz != cz or oy != cy or ox != cx:
                        continue
                cand[m, 0] = a
                cand[m, 1] = pos[a, cz, cy, cx, 0] + dr
                cand[m, 2] = pos[a, cz, cy, cx, 1] + dc
                cand[m, 3] = ir
                cand[m, 4] = ic
                cand[m, 5] = cz
                cand[m, 6] = cy
                cand[m, 7] = cx
                m += 1
    return m


def kopf_average(pos, centre_weight, images, ex_of_axis, pixel_weight, p, out, source):
    """Every voxel: the weighted mean of the exemplar colours that the windows of all three axes
    covering it place there (weight = IRLS weight of the window's match x window falloff x
    pixel_weight (E, H, W): the histogram modulation). source (Z, Y, X, 3) gets the (axis, row,
    col) of the heaviest proposal. (kopf_average_labelled without labels.)"""
    kopf_average_labelled(pos, centre_weight, images, ex_of_axis, pixel_weight, p, _NO_LABELS,
                          _NO_LABELS, 1.0, out, source)


_NO_LABELS = np.zeros((1, 1, 1), np.int32)


@njit(cache=True, parallel=True)
def kopf_average_labelled(pos, centre_weight, images, ex_of_axis, pixel_weight, p, ex_labels,
                          vol_labels, mismatch, out, source):
    """Every voxel: the weighted mean of the exemplar colours that the windows of all three axes
    covering it place there (weight = IRLS weight of the window's match x window falloff x
    pixel_weight (E, H, W): the histogram modulation), with the structure as a constraint: a
    proposal whose exemplar pixel's label (ex_labels int32 (E, H, W)) differs from the voxel's
    (vol_labels int32 (Z, Y, X)) weighs `mismatch` times as much (0 < mismatch < 1; 1: no
    constraint, the labels are not read), so a voxel of a 1-voxel gap takes gap colours whenever
    one covering window offers them, however many windows put stone there. source (Z, Y, X, 3)
    gets the (axis, row, col) of the heaviest proposal."""
    nz, ny, nx = out.shape[0], out.shape[1], out.shape[2]
    shape = (nz, ny, nx)
    n = p.size
    nc = out.shape[3]
    s = p.stride
    most = 3 * (n // s + 1) * (n // s + 1)
    labelled = mismatch < 1.0
    for z in prange(nz):
        acc = np.empty(nc, np.float64)
        cand = np.empty((most, 8), np.int64)
        for y in range(ny):
            for x in range(nx):
                acc[:] = 0.0
                wsum = 0.0
                wbest = -1.0
                sa, sr, sc = 0, 0, 0
                own = vol_labels[z, y, x] if labelled else 0
                for j in range(_covering(z, y, x, pos, shape, n, s, p.wrap, cand)):
                    a, er, ec = cand[j, 0], cand[j, 1], cand[j, 2]
                    e = ex_of_axis[a]
                    w = (centre_weight[a, cand[j, 5], cand[j, 6], cand[j, 7]]
                         * p.window[cand[j, 3], cand[j, 4]] * pixel_weight[e, er, ec])
                    if labelled and ex_labels[e, er, ec] != own:
                        w *= mismatch
                    for ch in range(nc):
                        acc[ch] += w * images[e, er, ec, ch]
                    wsum += w
                    if w > wbest:
                        wbest, sa, sr, sc = w, a, er, ec
                for ch in range(nc):
                    out[z, y, x, ch] = acc[ch] / wsum if wsum > 0 else 0.0
                source[z, y, x, 0] = sa
                source[z, y, x, 1] = sr
                source[z, y, x, 2] = sc


@njit(cache=True, parallel=True)
def kopf_pick(pos, images, ex_of_axis, target, p, support, out, source):
    """Sharpening: every voxel takes the single exemplar colour, among those the covering
    windows place on it, whose window agrees best with `target` (the averaged volume) over the
    (2 support + 1)^2 in-plane neighbourhood of the voxel (support 0: the voxel alone, which
    speckles; wider: neighbouring voxels choose the same window, copies stay whole)."""
    nz, ny, nx = out.shape[0], out.shape[1], out.shape[2]
    shape = (nz, ny, nx)
    n = p.size
    nc = out.shape[3]
    s = p.stride
    hgt = images.shape[1]
    wid = images.shape[2]
    most = 3 * (n // s + 1) * (n // s + 1)
    for z in prange(nz):
        cand = np.empty((most, 8), np.int64)
        for y in range(ny):
            for x in range(nx):
                best = np.inf
                sa, sr, sc = 0, 0, 0
                for j in range(_covering(z, y, x, pos, shape, n, s, p.wrap, cand)):
                    a, er, ec = cand[j, 0], cand[j, 1], cand[j, 2]
                    e = ex_of_axis[a]
                    cost = 0.0
                    wsum = 0.0
                    for u in range(-support, support + 1):
                        for v in range(-support, support + 1):
                            rr = er + u
                            cc = ec + v
                            if rr < 0 or rr >= hgt or cc < 0 or cc >= wid:
                                continue
                            qz, qy, qx = _at(z, y, x, a, u, v, shape, p.wrap)
                            g = 1.0 / (1.0 + u * u + v * v)
                            for ch in range(nc):
                                t = target[qz, qy, qx, ch] - images[e, rr, cc, ch]
                                cost += g * t * t
                            wsum += g
                    cost /= wsum
                    if cost < best:
                        best, sa, sr, sc = cost, a, er, ec
                e = ex_of_axis[sa]
                for ch in range(nc):
                    out[z, y, x, ch] = images[e, sr, sc, ch]
                source[z, y, x, 0] = sa
                source[z, y, x, 1] = sr
                source[z, y, x, 2] = sc


@njit(cache=True, parallel=True)
def fill_positions(pos, stride, lo, hi, ex_of_axis, out):
    """Every voxel's position per axis from the window centre at or before it in the plane,
    shifted by the offset (so positions exist everywhere for upsampling)."""
    nz, ny, nx = pos.shape[1], pos.shape[2], pos.shape[3]
    for z in prange(nz):
        for y in range(ny):
            for x in range(nx):
                for a in range(3):
                    e = ex_of_axis[a]
                    c = np.empty(3, np.int64)
                    c[0] = z
                    c[1] = y
                    c[2] = x
                    o0 = c[PLANE[a, 0]] % stride
                    o1 = c[PLANE[a, 1]] % stride
                    c[PLANE[a, 0]] -= o0
                    c[PLANE[a, 1]] -= o1
                    r = pos[a, c[0], c[1], c[2], 0] + o0
                    cc = pos[a, c[0], c[1], c[2], 1] + o1
                    out[a, z, y, x, 0] = min(max(r, lo[e, 0]), hi[e, 0])
                    out[a, z, y, x, 1] = min(max(cc, lo[e, 1]), hi[e, 1])


@njit(cache=True)
def position_counts(pos, stride, size, ex_of_axis, n_ex, h, w):
    """int64 (E, h, w): how many window pixels of the volume's matches land on each exemplar
    pixel (the exemplar-position histogram of Kopf et al.)."""
    counts = np.zeros((n_ex, h, w), np.int64)
    nz, ny, nx = pos.shape[1], pos.shape[2], pos.shape[3]
    h0 = size // 2
    for z in range(nz):
        for y in range(ny):
            for x in range(nx):
                for a in range(3):
                    if not _is_centre(z, y, x, a, stride):
                        continue
                    e = ex_of_axis[a]
                    r0 = pos[a, z, y, x, 0]
                    c0 = pos[a, z, y, x, 1]
                    for ir in range(size):
                        for ic in range(size):
                            counts[e, r0 + ir - h0, c0 + ic - h0] += 1
    return counts


def kopf_cluster(pos, centre_weight, images, ex_of_axis, pixel_weight, p, bandwidth2, steps,
                 cross, out, source):
    """Sharpening by the densest cluster of the proposals (kopf_cluster_labelled without
    labels)."""
    kopf_cluster_labelled(pos, centre_weight, images, ex_of_axis, pixel_weight, p, bandwidth2,
                          steps, cross, _NO_LABELS, _NO_LABELS, 1.0, out, source)


@njit(cache=True, parallel=True)
def kopf_cluster_labelled(pos, centre_weight, images, ex_of_axis, pixel_weight, p, bandwidth2,
                          steps, cross, ex_labels, vol_labels, mismatch, out, source):
    """Sharpening (mean shift instead of the mean): of the colours that the covering windows of
    all three axes place on a voxel (weights as in kopf_average), the one of highest weighted
    density (Epanechnikov kernel, squared radius bandwidth2) wins, and the voxel is the weighted
    mean of the proposals within bandwidth of it: flat areas are averaged as in Kopf et al.,
    edges are not (the two sides fall into different clusters and only one is kept).
    steps > 0: instead, `steps` mean-shift steps (Gaussian kernel) from the weighted mean: flat
    areas sharpen, boundaries keep some of their antialiasing (no pixel staircases).
    cross: the density of a proposal counts only the proposals of the other two slice families
    (a colour only one family's windows propose, e.g. one slice's copy showing as a 1-voxel
    stripe across the other families' slices, cannot win).
    ex_labels / vol_labels / mismatch: the structure's constraint, as in kopf_average_labelled
    (a proposal from an exemplar pixel of another label than the voxel's weighs `mismatch`
    times as much, in the density and in the cluster's mean alike; 1: labels not read)."""
    nz, ny, nx = out.shape[0], out.shape[1], out.shape[2]
    shape = (nz, ny, nx)
    n = p.size
    nc = out.shape[3]
    s = p.stride
    most = 3 * (n // s + 1) * (n // s + 1)
    labelled = mismatch < 1.0
    for z in prange(nz):
        col = np.empty((most, nc), np.float64)
        wts = np.empty(most, np.float64)
        ids = np.empty((most, 3), np.int64)
        acc = np.empty(nc, np.float64)
        mode = np.empty(nc, np.float64)
        cand = np.empty((most, 8), np.int64)
        for y in range(ny):
            for x in range(nx):
                own = vol_labels[z, y, x] if labelled else 0
                m = _covering(z, y, x, pos, shape, n, s, p.wrap, cand)
                for j in range(m):
                    a, er, ec = cand[j, 0], cand[j, 1], cand[j, 2]
                    e = ex_of_axis[a]
                    wts[j] = (centre_weight[a, cand[j, 5], cand[j, 6], cand[j, 7]]
                              * p.window[cand[j, 3], cand[j, 4]] * pixel_weight[e, er, ec])
                    if labelled and ex_labels[e, er, ec] != own:
                        wts[j] *= mismatch
                    for ch in range(nc):
                        col[j, ch] = images[e, er, ec, ch]
                    ids[j, 0] = a
                    ids[j, 1] = er
                    ids[j, 2] = ec
                if steps > 0:
                    wsum = 0.0
                    acc[:] = 0.0
                    for j in range(m):
                        for ch in range(nc):
                            acc[ch] += wts[j] * col[j, ch]
                        wsum += wts[j]
                    for ch in range(nc):
                        mode[ch] = acc[ch] / wsum if wsum > 0 else 0.0
                    for _ in range(steps):
                        acc[:] = 0.0
                        wsum = 0.0
                        for j in range(m):
                            d2 = 0.0
                            for ch in range(nc):
                                t = col[j, ch] - mode[ch]
                                d2 += t * t
                            k = wts[j] * np.exp(-d2 / bandwidth2)
                            for ch in range(nc):
                                acc[ch] += k * col[j, ch]
                            wsum += k
                        if wsum > 0:
                            for ch in range(nc):
                                mode[ch] = acc[ch] / wsum
                    bi = 0
                    near = np.inf
                    for j in range(m):
                        d2 = 0.0
                        for ch in range(nc):
                            t = col[j, ch] - mode[ch]
                            d2 += t * t
                        if d2 < near:
                            near, bi = d2, j
                    for ch in range(nc):
                        out[z, y, x, ch] = mode[ch]
                    source[z, y, x, 0] = ids[bi, 0]
                    source[z, y, x, 1] = ids[bi, 1]
                    source[z, y, x, 2] = ids[bi, 2]
                    continue
                best = -1.0
                bi = 0
                for i in range(m):
                    dens = 0.0
                    for j in range(m):
                        if cross and ids[j, 0] == ids[i, 0]:
                            continue
                        d2 = 0.0
                        for ch in range(nc):
                            t = col[i, ch] - col[j, ch]
                            d2 += t * t
                        if d2 < bandwidth2:
                            dens += wts[j] * (1.0 - d2 / bandwidth2)
                    if dens > best:
                        best, bi = dens, i
                acc[:] = 0.0
                wsum = 0.0
                for j in range(m):
                    d2 = 0.0
                    for ch in range(nc):
                        t = col[bi, ch] - col[j, ch]
                        d2 += t * t
                    if d2 < bandwidth2:
                        k = wts[j] * (1.0 - d2 / bandwidth2)
                        for ch in range(nc):
                            acc[ch] += k * col[j, ch]
                        wsum += k
                for ch in range(nc):
                    out[z, y, x, ch] = acc[ch] / wsum if wsum > 0 else col[bi, ch]
                source[z, y, x, 0] = ids[bi, 0]
                source[z, y, x, 1] = ids[bi, 1]
                source[z, y, x, 2] = ids[bi, 2]

"""Solid texture kernels: three exemplar positions per voxel, one per slice family.

A volume V (Z, Y, X) holds, for every voxel and every axis a (0 = x, 1 = y, 2 = z), an integer
exemplar position pos[a, z, y, x] = (row, col) in the exemplar of axis a. Axis a's slices are
the planes normal to a, with the exemplar's rows and columns along the volume dimensions
PLANE[a] = (row dim, col dim) of (z, y, x):  x -> (z, y),  y -> (z, x),  z -> (y, x)
(the slicing convention of texmetrics.py). The volume's appearance `vol` (Z, Y, X, F) is the
exemplar appearance at each voxel's chosen *source* (axis, row, col).

Two passes alternate (Kopf et al. 2007, with a mode instead of an average):
- search_pass: per voxel and axis, the exemplar position whose in-plane (2r+1)^2 neighbourhood
  best matches the current volume's neighbourhood in that plane (current, propagated from the
  8 in-plane neighbours, their k similar positions, random search; or every valid position);
- colour_pass: every in-plane neighbour of every axis proposes the exemplar pixel that its
  match places on this voxel; the voxel takes the proposal of highest weighted density in
  appearance space (averaging would blur), discounted by how over-used its exemplar pixel is.
Finally blend_render renders each voxel as the weighted mean of the proposals near its chosen
source in appearance space: exact where they all agree, blended across seams.

Both are Jacobi passes (read one array, write another) and every random number is a hash of
(seed, salt, voxel): the result does not depend on the thread count.
"""

from collections import namedtuple

import numpy as np
from numba import njit, prange

from osmap_kernels.common import hash_uniform

# Parameters of a search pass.
#   radius      int64     neighbourhood half-size
#   wrap        bool      the volume is toroidal in all three axes
#   n_random    int64     random-search candidates at halving radii (plus one global draw)
#   exhaustive  bool      try every valid exemplar position instead (coarsest level)
#   lo, hi      int64[E, 2] valid positions per exemplar (the whole window stays inside)
#   lam         float64   occupancy penalty: cost * (1 + lam * occupancy of the candidate)
#   seed, salt  uint64    hashed random numbers
#   seam        float64   cost added per in-plane 8-neighbour whose position does not continue
#                         the candidate (compact copy regions instead of fragments)
SearchParams = namedtuple("SearchParams",
                          "radius wrap n_random exhaustive lo hi lam seed salt seam")

# Parameters of a colour pass.
#   radius      int64     proposals come from the in-plane (2 radius + 1)^2 neighbours
#   wrap        bool
#   bandwidth2  float64   squared support radius of the (Epanechnikov) density kernel
#   power       float64   proposal weight = (match cost + eps) ** -power
#   eps         float64
#   lam         float64   occupancy discount: density / (1 + lam * occupancy)
#   across      float64   across-plane discount: density / (1 + across * d2 / bandwidth2), d2 the
#                         squared distance from the proposal's appearance to the mean of the
#                         volume's two voxels along its slice family's normal (no barcode of
#                         1-voxel stripes where one family's unrelated slices sit side by side)
ColourParams = namedtuple("ColourParams", "radius wrap bandwidth2 power eps lam across")

# (row dim, col dim) of each axis' slices in (z, y, x) order
PLANE = np.array([[0, 1], [0, 2], [1, 2]], np.int64)


@njit(cache=True, inline="always")
def _neighbour(z, y, x, a, dr, dc, shape, wrap):
    """Voxel at in-plane offset (dr, dc) from (z, y, x) in axis a's slice; ok False if outside."""
    q0, q1, q2 = z, y, x
    rd = PLANE[a, 0]
    cd = PLANE[a, 1]
    if rd == 0:
        q0 += dr
    else:
        q1 += dr
    if cd == 1:
        q1 += dc
    else:
        q2 += dc
    if wrap:
        return q0 % shape[0], q1 % shape[1], q2 % shape[2], True
    ok = 0 <= q0 < shape[0] and 0 <= q1 < shape[1] and 0 <= q2 < shape[2]
    return q0, q1, q2, ok


@njit(cache=True, inline="always")
def _cost(feat, occ, lam, py, px, nb, nb_ok, radius, best):
    """Occupancy-weighted SSD between the gathered neighbourhood and the exemplar's at
    (py, px); returns inf as soon as it cannot beat `best`."""
    nf = feat.shape[2]
    factor = 1.0 + lam * occ[py, px]
    limit = best / factor
    total = 0.0
    n = 0
    for dr in range(-radius, radius + 1):
        for dc in range(-radius, radius + 1):
            if nb_ok[n]:
                for f in range(nf):
                    diff = nb[n, f] - feat[py + dr, px + dc, f]
                    total += diff * diff
                if total >= limit:
                    return np.inf
            n += 1
    return total * factor


@njit(cache=True, inline="always")
def _seam(pos, a, z, y, x, cy, cx, shape, p):
    """p.seam times the number of in-plane 8-neighbours whose axis-a position is not
    (cy, cx) + their offset."""
    if p.seam == 0.0:
        return 0.0
    n = 0
    for dr in range(-1, 2):
        for dc in range(-1, 2):
            if dr == 0 and dc == 0:
                continue
            q0, q1, q2, ok = _neighbour(z, y, x, a, dr, dc, shape, p.wrap)
            if ok and (pos[a, q0, q1, q2, 0] != cy + dr or pos[a, q0, q1, q2, 1] != cx + dc):
                n += 1
    return p.seam * n


@njit(cache=True, inline="always")
def _total(pos, a, z, y, x, shape, feat, occ, p, cy, cx, nb, nb_ok, best):
    """Seam penalty plus matching cost of candidate (cy, cx); inf once it cannot beat best."""
    seam = _seam(pos, a, z, y, x, cy, cx, shape, p)
    if seam >= best:
        return np.inf
    return seam + _cost(feat, occ, p.lam, cy, cx, nb, nb_ok, p.radius, best - seam)


@njit(cache=True, parallel=True)
def search_pass(vol, pos, dst, cost, feats, ex_of_axis, knn, occ, p):
    """Best exemplar position per voxel and axis.

    vol float32[Z, Y, X, F]; pos, dst int32[3, Z, Y, X, 2] (read pos, write dst);
    cost float32[3, Z, Y, X] (written: the best match cost); feats float32[E, h, w, F];
    ex_of_axis int64[3]; knn int32[E, h, w, k, 2] similar positions; occ float32[E, h, w]
    use of each exemplar pixel (1 = uniform); p SearchParams.
    """
    Z, Y, X, nf = vol.shape
    shape = (Z, Y, X)
    r = p.radius
    side = 2 * r + 1
    k = knn.shape[3]
    for zy in prange(Z * Y):
        z = zy // Y
        y = zy % Y
        nb = np.empty((side * side, nf), np.float32)
        nb_ok = np.zeros(side * side, np.bool_)
        for x in range(X):
            index = (z * Y + y) * X + x
            for a in range(3):
                e = ex_of_axis[a]
                feat = feats[e]
                oc = occ[e]
                lo0, lo1 = p.lo[e, 0], p.lo[e, 1]
                hi0, hi1 = p.hi[e, 0], p.hi[e, 1]
                n = 0
                for dr in range(-r, r + 1):
                    for dc in range(-r, r + 1):
                        q0, q1, q2, ok = _neighbour(z, y, x, a, dr, dc, shape, p.wrap)
                        nb_ok[n] = ok
                        if ok:
                            for f in range(nf):
                                nb[n, f] = vol[q0, q1, q2, f]
                        n += 1
                by = min(max(pos[a, z, y, x, 0], lo0), hi0)
                bx = min(max(pos[a, z, y, x, 1], lo1), hi1)
                best = _total(pos, a, z, y, x, shape, feat, oc, p, by, bx, nb, nb_ok, np.inf)
                if p.exhaustive:
                    for cy in range(lo0, hi0 + 1):
                        for cx in range(lo1, hi1 + 1):
                            c = _total(pos, a, z, y, x, shape, feat, oc, p, cy, cx, nb, nb_ok, best)
                            if c < best:
                                best, by, bx = c, cy, cx
                else:
                    for dr in range(-1, 2):
                        for dc in range(-1, 2):
                            if dr == 0 and dc == 0:
                                continue
                            q0, q1, q2, ok = _neighbour(z, y, x, a, dr, dc, shape, p.wrap)
                            if not ok:
                                continue
                            cy = pos[a, q0, q1, q2, 0] - dr
                            cx = pos[a, q0, q1, q2, 1] - dc
                            if cy < lo0 or cy > hi0 or cx < lo1 or cx > hi1:
                                continue
                            c = _total(pos, a, z, y, x, shape, feat, oc, p, cy, cx, nb, nb_ok, best)
                            if c < best:
                                best, by, bx = c, cy, cx
                            for j in range(k):
                                ky = knn[e, cy, cx, j, 0]
                                kx = knn[e, cy, cx, j, 1]
                                c = _total(pos, a, z, y, x, shape, feat, oc, p, ky, kx, nb, nb_ok,
                                           best)
                                if c < best:
                                    best, by, bx = c, ky, kx
                    radius = max(hi0 - lo0, hi1 - lo1) * 0.5
                    for j in range(p.n_random + 1):
                        u = hash_uniform(p.seed, p.salt, index, 6 * j + 2 * a)
                        v = hash_uniform(p.seed, p.salt, index, 6 * j + 2 * a + 1)
                        if j == p.n_random:
                            cy = lo0 + int(u * (hi0 - lo0 + 1))
                            cx = lo1 + int(v * (hi1 - lo1 + 1))
                        else:
                            cy = by + int(np.floor((2 * u - 1) * radius + 0.5))
                            cx = bx + int(np.floor((2 * v - 1) * radius + 0.5))
                            radius *= 0.5
                        cy = min(max(cy, lo0), hi0)
                        cx = min(max(cx, lo1), hi1)
                        c = _total(pos, a, z, y, x, shape, feat, oc, p, cy, cx, nb, nb_ok, best)
                        if c < best:
                            best, by, bx = c, cy, cx
                dst[a, z, y, x, 0] = by
                dst[a, z, y, x, 1] = bx
                cost[a, z, y, x] = best


@njit(cache=True, inline="always")
def _merge_duplicates(pa, pr, pc, pw, n):
    """Merge identical proposals (same axis, row, col) into their first occurrence, summing the
    weights; returns the number left. The density ranking is unchanged (a duplicate is at
    distance 0) and the pairwise loop shrinks where neighbours copy coherently."""
    m = 0
    for i in range(n):
        j = 0
        while j < m and not (pa[j] == pa[i] and pr[j] == pr[i] and pc[j] == pc[i]):
            j += 1
        if j < m:
            pw[j] += pw[i]
        else:
            pa[m], pr[m], pc[m], pw[m] = pa[i], pr[i], pc[i], pw[i]
            m += 1
    return m


@njit(cache=True, inline="always")
def _gather_proposals(pos, cost, z, y, x, h, w, p, pa, pr, pc, pw):
    """The exemplar pixels voxel (z, y, x)'s in-plane neighbours (all three axes) propose for
    it: axis pa, row pr, column pc, weight pw = (match cost + eps)^-power. Returns their count."""
    shape = (pos.shape[1], pos.shape[2], pos.shape[3])
    n = 0
    for a in range(3):
        for dr in range(-p.radius, p.radius + 1):
            for dc in range(-p.radius, p.radius + 1):
                q0, q1, q2, ok = _neighbour(z, y, x, a, dr, dc, shape, p.wrap)
                if not ok:
                    continue
                pa[n] = a
                pr[n] = min(max(pos[a, q0, q1, q2, 0] - dr, 0), h - 1)
                pc[n] = min(max(pos[a, q0, q1, q2, 1] - dc, 0), w - 1)
                pw[n] = (cost[a, q0, q1, q2] + p.eps) ** (-p.power)
                n += 1
    return n


@njit(cache=True, inline="always")
def _step(z, y, x, d, step, shape, wrap):
    """Voxel `step` voxels from (z, y, x) along volume dim d; ok False if outside."""
    q0, q1, q2 = z + step * (d == 0), y + step * (d == 1), x + step * (d == 2)
    if wrap:
        return q0 % shape[0], q1 % shape[1], q2 % shape[2], True
    ok = 0 <= q0 < shape[0] and 0 <= q1 < shape[1] and 0 <= q2 < shape[2]
    return q0, q1, q2, ok


@njit(cache=True, inline="always")
def _across_means(prev, z, y, x, wrap, out):
    """out[a] = mean of prev's two voxels next to (z, y, x) across axis a's slice plane (the
    one inside the volume at a border)."""
    shape = (prev.shape[0], prev.shape[1], prev.shape[2])
    out[:] = 0.0
    for a in range(3):
        n = 0
        for step in (-1, 1):
            q0, q1, q2, ok = _step(z, y, x, 2 - a, step, shape, wrap)  # dim 2 - a is a's normal
            if ok:
                for f in range(prev.shape[3]):
                    out[a, f] += prev[q0, q1, q2, f]
                n += 1
        for f in range(prev.shape[3]):
            out[a, f] /= max(n, 1)


@njit(cache=True, parallel=True)
def colour_pass(pos, cost, feats, ex_of_axis, occ, p, prev, source, vol):
    """Choose every voxel's source among the proposals of its in-plane (2r+1)^2 neighbours.

    pos int32[3, Z, Y, X, 2]; cost float32[3, Z, Y, X]; feats float32[E, h, w, F];
    occ float32[E, h, w] usage of each exemplar pixel (1 = uniform); prev float32[Z, Y, X, F]
    the volume the search matched (read by the across-plane term); writes source
    int32[Z, Y, X, 3] = (axis, row, col) and vol float32[Z, Y, X, F] = its appearance.
    """
    Z, Y, X = pos.shape[1], pos.shape[2], pos.shape[3]
    nf = feats.shape[3]
    h, w = feats.shape[1], feats.shape[2]
    n_prop = 3 * (2 * p.radius + 1) ** 2
    inv2b = 1.0 / p.bandwidth2
    for zy in prange(Z * Y):
        z = zy // Y
        y = zy % Y
        pa = np.empty(n_prop, np.int64)
        pr = np.empty(n_prop, np.int64)
        pc = np.empty(n_prop, np.int64)
        pw = np.empty(n_prop)
        pf = np.empty((n_prop, nf), np.float32)
        score = np.empty(n_prop)
        across_mean = np.empty((3, nf))
        for x in range(X):
            n = _gather_proposals(pos, cost, z, y, x, h, w, p, pa, pr, pc, pw)
            n = _merge_duplicates(pa, pr, pc, pw, n)
            for i in range(n):
                e = ex_of_axis[pa[i]]
                for f in range(nf):
                    pf[i, f] = feats[e, pr[i], pc[i], f]
                score[i] = pw[i]
            for i in range(n):
                for j in range(i + 1, n):
                    d2 = 0.0
                    for f in range(nf):
                        diff = pf[i, f] - pf[j, f]
                        d2 += diff * diff
                    kern = 1.0 - d2 * inv2b  # Epanechnikov: compact, no exp
                    if kern > 0.0:
                        score[i] += pw[j] * kern
                        score[j] += pw[i] * kern
            if p.across > 0.0:
                _across_means(prev, z, y, x, p.wrap, across_mean)
            best_i = 0
            best_s = -1.0
            for i in range(n):
                s = score[i] / (1.0 + p.lam * occ[ex_of_axis[pa[i]], pr[i], pc[i]])
                if p.across > 0.0:
                    d2 = 0.0
                    for f in range(nf):
                        diff = pf[i, f] - across_mean[pa[i], f]
                        d2 += diff * diff
                    s /= 1.0 + p.across * d2 * inv2b
                if s > best_s:
                    best_s = s
                    best_i = i
            a = pa[best_i]
            source[z, y, x, 0] = a
            source[z, y, x, 1] = pr[best_i]
            source[z, y, x, 2] = pc[best_i]
            for f in range(nf):
                vol[z, y, x, f] = pf[best_i, f]


@njit(cache=True, parallel=True)
def gather_sources(source, images, ex_of_axis):
    """float32[Z, Y, X, C]: images[ex_of_axis[axis], row, col] for every voxel's source."""
    Z, Y, X = source.shape[0], source.shape[1], source.shape[2]
    C = images.shape[3]
    out = np.empty((Z, Y, X, C), np.float32)
    for zy in prange(Z * Y):
        z = zy // Y
        y = zy % Y
        for x in range(X):
            e = ex_of_axis[source[z, y, x, 0]]
            for c in range(C):
                out[z, y, x, c] = images[e, source[z, y, x, 1], source[z, y, x, 2], c]
    return out


@njit(cache=True)
def usage_counts(source, ex_of_axis, n_ex, h, w):
    """float32[E, h, w]: how many voxels take their colour from each exemplar pixel."""
    counts = np.zeros((n_ex, h, w), np.float32)
    Z, Y, X = source.shape[0], source.shape[1], source.shape[2]
    for z in range(Z):
        for y in range(Y):
            for x in range(X):
                counts[ex_of_axis[source[z, y, x, 0]], source[z, y, x, 1], source[z, y, x, 2]] += 1
    return counts


@njit(cache=True, parallel=True)
def blend_render(pos, cost, feats, images, ex_of_axis, source, p):
    """float32[Z, Y, X, C]: every voxel's colour as the weighted mean of the proposals that agree
    with its source (Kwatra-style voting restricted to the mode's cluster): proposal j weighs
    (cost_j + eps)^-power * max(0, 1 - |f_j - f_source|^2 / bandwidth2). Where every proposal is
    the source pixel itself, the voxel is that pixel exactly; across a seam the sides blend.

    pos, cost, feats, ex_of_axis, p as in colour_pass; images float32[E, h, w, C]; source
    int32[Z, Y, X, 3] the chosen sources.
    """
    Z, Y, X = pos.shape[1], pos.shape[2], pos.shape[3]
    nf = feats.shape[3]
    h, w = feats.shape[1], feats.shape[2]
    C = images.shape[3]
    n_prop = 3 * (2 * p.radius + 1) ** 2
    inv2b = 1.0 / p.bandwidth2
    out = np.empty((Z, Y, X, C), np.float32)
    for zy in prange(Z * Y):
        z = zy // Y
        y = zy % Y
        pa = np.empty(n_prop, np.int64)
        pr = np.empty(n_prop, np.int64)
        pc = np.empty(n_prop, np.int64)
        pw = np.empty(n_prop)
        acc = np.empty(C)
        for x in range(X):
            es = ex_of_axis[source[z, y, x, 0]]
            sr = source[z, y, x, 1]
            sc = source[z, y, x, 2]
            acc[:] = 0.0
            total = 0.0
            agree = True
            n = _gather_proposals(pos, cost, z, y, x, h, w, p, pa, pr, pc, pw)
            for j in range(n):
                e = ex_of_axis[pa[j]]
                row = pr[j]
                col = pc[j]
                d2 = 0.0
                for f in range(nf):
                    diff = feats[e, row, col, f] - feats[es, sr, sc, f]
                    d2 += diff * diff
                kern = 1.0 - d2 * inv2b
                if kern <= 0.0:
                    continue
                wt = kern * pw[j]
                for c in range(C):
                    v = images[e, row, col, c]
                    acc[c] += wt * v
                    agree = agree and v == images[es, sr, sc, c]
                total += wt
            for c in range(C):
                if agree or total == 0.0:
                    out[z, y, x, c] = images[es, sr, sc, c]
                else:
                    out[z, y, x, c] = acc[c] / total
    return out

"""Coherence optimisation of a position field: the kernels behind the `refine` stage.

A position field S (H, W, 2) holds, for every output pixel, a (row, col) position in the
exemplar (float32; integral when the output-to-exemplar Jacobian J is the identity). Its rendered
appearance is the exemplar's appearance features sampled at S. A sweep replaces S[p] by the
candidate position whose exemplar neighbourhood best matches the current output neighbourhood of p
(k-coherence + PatchMatch candidates), with a penalty on over-used exemplar regions.

Determinism: a pass updates one colour of a red-black checkerboard, reading the previous field
and writing a new one (Jacobi within a colour), and every random number is a hash of
(seed, salt, pixel): the result does not depend on the thread count or scheduling.
"""

from collections import namedtuple

import numpy as np
from numba import njit

from osmap_kernels.bands import run_bands
from osmap_kernels.common import EIGHT_NEIGHBOURS, hash_uniform, neighbour, sample

# Parameters of one refinement pass.
#   radius    int64    neighbourhood half-size (matching window (2r+1)^2 of feature vectors)
#   lam       float64  occupancy penalty: cost * (1 + lam * occupancy)
#   wrap      bool     output is toroidal (tileable)
#   lo, hi    float64[2] valid exemplar positions (the whole matching window stays inside)
#   n_random  int64    PatchMatch random-search candidates at halving radii
#   seed      uint64   user seed
#   salt      uint64   distinguishes level / sweep / colour
#   parity    int64    which checkerboard colour this pass updates
#   seam      float64  cost added per 8-neighbour whose position does not continue the candidate
#   max_area  float64  copy regions larger than this (pixels) are penalised as they grow
#   guide     float64  cost per squared guide difference (exemplar guide at the candidate vs
#                      output guide at the pixel); 0: unguided (the guide arrays are not read)
RefineParams = namedtuple("RefineParams",
                          "radius lam wrap lo hi n_random seed salt parity seam max_area guide")


@njit(cache=True, inline="always")
def _clamp(v, lo, hi):
    return min(max(v, lo), hi)


@njit(cache=True, inline="always")
def _seam_penalty(src, area, y, x, cy, cx, J, p):
    """p.seam times the number of 8-neighbours q whose position is not cy,cx + J (q - p), plus,
    for each neighbour it does continue, p.seam times how far that neighbour's copy region
    exceeds p.max_area (relative): seams cost, and so does growing an oversized copy."""
    if p.seam == 0.0:
        return 0.0
    H, W = src.shape[0], src.shape[1]
    n = 0
    excess = 0.0
    for k in range(8):
        dy, dx = EIGHT_NEIGHBOURS[k, 0], EIGHT_NEIGHBOURS[k, 1]
        qy, qx, inside = neighbour(y, x, dy, dx, H, W, p.wrap)
        if not inside:
            continue
        ey = src[qy, qx, 0] - cy - (J[0, 0] * dy + J[0, 1] * dx)
        ex = src[qy, qx, 1] - cx - (J[1, 0] * dy + J[1, 1] * dx)
        if abs(ey) > 0.25 or abs(ex) > 0.25:
            n += 1
        elif area[qy, qx] > p.max_area:
            excess += area[qy, qx] / p.max_area - 1.0
    return p.seam * (n + excess)


@njit(cache=True, inline="always")
def _guide_penalty(gex, gout, y, x, cy, cx, p):
    """p.guide times the squared difference between the exemplar guide at the candidate's
    nearest pixel and the output guide at (y, x); 0 when unguided."""
    if p.guide == 0.0:
        return 0.0
    iy = min(max(int(cy + 0.5), 0), gex.shape[0] - 1)
    ix = min(max(int(cx + 0.5), 0), gex.shape[1] - 1)
    d = gex[iy, ix] - gout[y, x]
    return p.guide * d * d


@njit(cache=True, inline="always")
def _total_cost(src, area, y, x, feat, cy, cx, J, nb, nb_ok, occ, p, best, buf, gex, gout):
    """Matching cost of candidate (cy, cx) for pixel (y, x) plus its seam and guide penalties."""
    seam = _seam_penalty(src, area, y, x, cy, cx, J, p) + _guide_penalty(gex, gout, y, x, cy,
                                                                          cx, p)
    if seam >= best:
        return np.inf
    # cy, cx as float64 (exact): one compiled _candidate_cost for the float32 current position
    # and the float64 candidates (it computes in float64 either way)
    return seam + _candidate_cost(feat, np.float64(cy), np.float64(cx), J, p.radius, nb, nb_ok,
                                  occ, p.lam, best - seam, buf)


@njit(cache=True)
def _candidate_cost(feat, cy, cx, jac, radius, nb, nb_ok, occ, lam, best, buf):
    """Occupancy-weighted SSD between the gathered output neighbourhood nb and the exemplar
    neighbourhood at (cy, cx); stops early once it cannot beat `best`."""
    h, w = occ.shape
    iy = min(max(int(cy + 0.5), 0), h - 1)
    ix = min(max(int(cx + 0.5), 0), w - 1)
    factor = 1.0 + lam * occ[iy, ix]
    limit = best / factor
    nf = feat.shape[2]
    total = 0.0
    n = 0
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if not nb_ok[n]:
                n += 1
                continue
            sy = cy + jac[0, 0] * dy + jac[0, 1] * dx
            sx = cx + jac[1, 0] * dy + jac[1, 1] * dx
            sample(feat, sy, sx, buf)
            for f in range(nf):
                diff = nb[n * nf + f] - buf[f]
                total += diff * diff
            n += 1
            if total >= limit:
                return np.inf
    return total * factor


def refine_pass(src, dst, feat, jac, knn, occ, area, gex, gout, p):
    """One red-black pass: for pixels of colour p.parity, write the best candidate into dst.

    src, dst float32[H, W, 2] (dst must be a copy of src); feat float32[h, w, F] exemplar
    appearance; jac float32[H, W, 2, 2] output-to-exemplar Jacobian per pixel; knn int32[h, w, k, 2]
    similar exemplar positions; occ float32[h, w] occupancy; area float32[H, W] the size of each
    pixel's copy region (copy_region_areas); gex float32[h, w] and gout float32[H, W] the
    exemplar and output guides, read only when p.guide != 0 (unguided: pass (1, 1) zeros).
    Row bands run on osmap_kernels.bands' threads.
    """
    run_bands(_refine_rows, src.shape[0], src, dst, feat, jac, knn, occ, area, gex, gout, p)


@njit(cache=True, nogil=True)
def _refine_rows(src, dst, feat, jac, knn, occ, area, gex, gout, p, y0, y1):
    """refine_pass on rows y0 <= y < y1 (reads src, writes only those rows of dst)."""
    H, W = src.shape[0], src.shape[1]
    nf = feat.shape[2]
    r = p.radius
    side = 2 * r + 1
    k = knn.shape[2]
    hmax = max(feat.shape[0], feat.shape[1])
    nb = np.empty(side * side * nf)
    nb_ok = np.zeros(side * side, np.bool_)
    buf = np.empty(nf)
    seen = np.empty((8, 2))
    for y in range(y0, y1):
        for x in range((y + p.parity) % 2, W, 2):
            J = jac[y, x]
            # gather the output neighbourhood's current appearance
            n = 0
            for dy in range(-r, r + 1):
                for dx in range(-r, r + 1):
                    qy, qx, inside = neighbour(y, x, dy, dx, H, W, p.wrap)
                    nb_ok[n] = inside
                    if inside:
                        sample(feat, src[qy, qx, 0], src[qy, qx, 1], buf)
                        for f in range(nf):
                            nb[n * nf + f] = buf[f]
                    n += 1

            by = src[y, x, 0]
            bx = src[y, x, 1]
            best = _total_cost(src, area, y, x, feat, by, bx, J, nb, nb_ok, occ, p, np.inf, buf,
                               gex, gout)
            y0 = by
            x0 = bx
            n_seen = 0
            index = y * W + x
            # coherent candidates from the 8 neighbours, and their k most similar positions
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    if dy == 0 and dx == 0:
                        continue
                    qy, qx, inside = neighbour(y, x, dy, dx, H, W, p.wrap)
                    if not inside:
                        continue
                    cy = src[qy, qx, 0] - (J[0, 0] * dy + J[0, 1] * dx)
                    cx = src[qy, qx, 1] - (J[1, 0] * dy + J[1, 1] * dx)
                    if cy < p.lo[0] or cy > p.hi[0] or cx < p.lo[1] or cx > p.hi[1]:
                        continue
                    # inside a copy the neighbours propose the same position: cost it (and its
                    # k-NN) once; the current position was costed first
                    duplicate = False
                    for j in range(n_seen):
                        if seen[j, 0] == cy and seen[j, 1] == cx:
                            duplicate = True
                    if duplicate:
                        continue
                    seen[n_seen, 0] = cy
                    seen[n_seen, 1] = cx
                    n_seen += 1
                    if cy != y0 or cx != x0:
                        cost = _total_cost(src, area, y, x, feat, cy, cx, J, nb, nb_ok, occ, p,
                                           best, buf, gex, gout)
                        if cost < best:
                            best, by, bx = cost, cy, cx
                    iy = int(cy + 0.5)
                    ix = int(cx + 0.5)
                    fy = cy - iy
                    fx = cx - ix
                    for j in range(k):
                        ky = _clamp(knn[iy, ix, j, 0] + fy, p.lo[0], p.hi[0])
                        kx = _clamp(knn[iy, ix, j, 1] + fx, p.lo[1], p.hi[1])
                        cost = _total_cost(src, area, y, x, feat, ky, kx, J, nb, nb_ok, occ, p,
                                           best, buf, gex, gout)
                        if cost < best:
                            best, by, bx = cost, ky, kx
            # PatchMatch random search around the best, at halving radii, plus one global draw
            radius = hmax * 0.5
            for j in range(p.n_random + 1):
                u = hash_uniform(p.seed, p.salt, index, 2 * j)
                v = hash_uniform(p.seed, p.salt, index, 2 * j + 1)
                if j == p.n_random:
                    cy = p.lo[0] + u * (p.hi[0] - p.lo[0])
                    cx = p.lo[1] + v * (p.hi[1] - p.lo[1])
                else:
                    cy = by + (2 * u - 1) * radius
                    cx = bx + (2 * v - 1) * radius
                    radius *= 0.5
                cy = _clamp(np.floor(cy) + (by - np.floor(by)), p.lo[0], p.hi[0])
                cx = _clamp(np.floor(cx) + (bx - np.floor(bx)), p.lo[1], p.hi[1])
                cost = _total_cost(src, area, y, x, feat, cy, cx, J, nb, nb_ok, occ, p, best, buf,
                                   gex, gout)
                if cost < best:
                    best, by, bx = cost, cy, cx
            dst[y, x, 0] = by
            dst[y, x, 1] = bx


def knn_table(feat, lo0, hi0, lo1, hi1, k, stride, exclude):
    """For every exemplar pixel, the k positions (from a grid of the given stride inside the
    valid box) with the nearest appearance features, excluding those within `exclude` pixels.
    Returns int32[h, w, k, 2]; ties are broken by scan order."""
    out = np.zeros((feat.shape[0], feat.shape[1], k, 2), np.int32)
    run_bands(_knn_rows, feat.shape[0], feat, lo0, hi0, lo1, hi1, k, stride, exclude, out)
    return out


@njit(cache=True, nogil=True)
def _knn_rows(feat, lo0, hi0, lo1, hi1, k, stride, exclude, out, y0, y1):
    """knn_table's rows y0 <= y < y1, written into out."""
    h, w, nf = feat.shape
    ref_y = np.arange(lo0, hi0 + 1, stride)
    ref_x = np.arange(lo1, hi1 + 1, stride)
    best_d = np.empty(k)
    best_i = np.empty((k, 2), np.int64)
    for y in range(y0, y1):
        for x in range(w):
            for j in range(k):
                best_d[j] = np.inf
                best_i[j, 0] = min(max(y, lo0), hi0)
                best_i[j, 1] = min(max(x, lo1), hi1)
            for ry in ref_y:
                for rx in ref_x:
                    if abs(ry - y) <= exclude and abs(rx - x) <= exclude:
                        continue
                    dist = 0.0
                    for f in range(nf):
                        diff = feat[y, x, f] - feat[ry, rx, f]
                        dist += diff * diff
                        if dist >= best_d[k - 1]:
                            break
                    if dist < best_d[k - 1]:
                        j = k - 1
                        while j > 0 and best_d[j - 1] > dist:
                            best_d[j] = best_d[j - 1]
                            best_i[j, 0] = best_i[j - 1, 0]  # not best_i[j] = best_i[j - 1]:
                            best_i[j, 1] = best_i[j - 1, 1]  # see som._update_box
                            j -= 1
                        best_d[j] = dist
                        best_i[j, 0] = ry
                        best_i[j, 1] = rx
            for j in range(k):
                out[y, x, j, 0] = best_i[j, 0]
                out[y, x, j, 1] = best_i[j, 1]
    return out


@njit(cache=True)
def usage_counts(pos, h, w):
    """How many output pixels use each exemplar pixel (nearest integer position)."""
    counts = np.zeros((h, w), np.float32)
    for y in range(pos.shape[0]):
        for x in range(pos.shape[1]):
            iy = min(max(int(pos[y, x, 0] + 0.5), 0), h - 1)
            ix = min(max(int(pos[y, x, 1] + 0.5), 0), w - 1)
            counts[iy, ix] += 1.0
    return counts

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
from osmap_kernels.lattice import NO_LATTICE, NO_REGIONS, NO_TABLE, lattice_snap, region_lattice

# the exemplar phase map of a lattice of one exemplar (osmap_kernels.lattice): none
_NO_PHASE = np.zeros((1, 1, 2), np.float32)

# Parameters of one refinement pass.
#   radius    int64    neighbourhood half-size (matching window (2r+1)^2 of feature vectors)
#   lam       float64  occupancy penalty: cost * (1 + lam * occupancy)
#   wrap      bool     output is toroidal (tileable)
#   lo, hi    (float, float) valid exemplar positions (the whole matching window stays inside);
#             tuples, not arrays: an array field costs atomic reference counting per access
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


@njit(cache=True)
def _total_cost(src, area, y, x, feat, cy, cx, J, nb, nb_ok, occ, p, best, buf, gex, gout):
    """Matching cost of candidate (cy, cx) for pixel (y, x) plus its seam and guide penalties.

    Called, not inlined (nor is _gather): an inlined copy is compiled again at each of
    _refine_rows' call sites, and a first run compiles about a second less this way; only the
    general path (rotated, scaled or field-driven synthesis) calls it, about 5 % slower."""
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


@njit(cache=True, inline="always")
def _integral_inside(cy, cx, lo, hi_y, hi_x):
    """Whether (cy, cx) is an integer position whose rows cy - lo .. cy + lo and columns
    cx - lo .. cx + lo all lie inside [0, hi_y] x [0, hi_x]."""
    return (cy == np.floor(cy) and cx == np.floor(cx) and cy >= lo and cy <= hi_y - lo
            and cx >= lo and cx <= hi_x - lo)


@njit(cache=True)
def _gather(src, feat, y, x, p, nb, nb_ok, buf):
    """The output neighbourhood's current appearance at pixel (y, x), for _total_cost: nb[n * F
    + f] feature f of window element n (scan order) where nb_ok[n] (inside the output)."""
    H, W = src.shape[0], src.shape[1]
    nf = feat.shape[2]
    n = 0
    for dy in range(-p.radius, p.radius + 1):
        for dx in range(-p.radius, p.radius + 1):
            qy, qx, inside = neighbour(y, x, dy, dx, H, W, p.wrap)
            nb_ok[n] = inside
            if inside:
                sample(feat, src[qy, qx, 0], src[qy, qx, 1], buf)
                for f in range(nf):
                    nb[n * nf + f] = buf[f]
            n += 1


def refine_pass(src, dst, feat, jac, knn, occ, area, gex, gout, p, lattice=NO_LATTICE,
                phase_map=_NO_PHASE, table=NO_TABLE, regions=NO_REGIONS):
    """One red-black pass: for pixels of colour p.parity, write the best candidate into dst.

    src, dst float32[H, W, 2] (dst must be a copy of src); feat float32[h, w, F] exemplar
    appearance; jac float32[H, W, 2, 2] output-to-exemplar Jacobian per pixel; knn int32[h, w, k, 2]
    similar exemplar positions; occ float32[h, w] occupancy; area float32[H, W] the size of each
    pixel's copy region (copy_region_areas); gex float32[h, w] and gout float32[H, W] the
    exemplar and output guides, read only when p.guide != 0 (unguided: pass (1, 1) zeros).
    lattice (osmap_kernels.lattice.LatticeParams) and phase_map (float32 (h, w, 2), or (1, 1,
    2) for one exemplar): with a lattice (rank > 0), every
    candidate but the current position is first moved to the nearest position consistent with
    its pixel (lattice_snap) and dropped if that leaves [p.lo, p.hi]; src should be consistent
    already (osmap_kernels.lattice.snap_field). table and regions (osmap_kernels.lattice): a
    lattice per region of the exemplar instead, each candidate snapped to its own region's.
    Row bands run on osmap_kernels.bands' threads.
    """
    run_bands(_refine_rows, src.shape[0], src, dst, feat, jac, knn, occ, area, gex, gout, p,
              lattice, phase_map, table, regions)


@njit(cache=True, nogil=True)
def _refine_rows(src, dst, feat, jac, knn, occ, area, gex, gout, p, lattice, phase_map, table,
                 regions, y0, y1):
    """refine_pass on rows y0 <= y < y1 (reads src, writes only those rows of dst).

    Where the Jacobian is the identity and every position in a pixel's window is integral (the
    default synth), a candidate with an integral position whose window lies inside the exemplar
    is costed in place (below): the same float64 operations in the same order as _total_cost,
    so the same cost bit for bit, from exact integer arithmetic. A window element whose
    position implies the candidate itself holds exactly the candidate's exemplar pixel: its
    term is +0.0, which leaves every partial sum as it is, so it is skipped (inside a copy the
    current position costs nothing to check); the others read the exemplar at both positions
    directly (no gathered neighbourhood, no bilinear sample). The code is written out here,
    not called: each array handed to an inlined function costs atomic reference-count updates
    per call, about half the time of a pass. Other pixels and candidates go to _total_cost.

    A settled pixel is not searched further: on that fast path, with no lattice or one integral
    lattice (lattice_snap keeps an integral position integral), an integral box [p.lo, p.hi]
    and non-negative p.seam and p.guide, every candidate is integral, so one other than the
    current position breaks every 8-neighbour inside the output when all of them continue the
    pixel's copy, and its seam term alone, p.seam * that count (or more with a guide), reaches
    a best cost at or below it and is rejected before any matching: the candidate list, the
    k-NN look-ups and the random draws are then skipped, and the pixel keeps its position, as
    the full search would (80-87 % of a pass's pixel visits on cells.png, brick.png and
    grass_256.png). A pixel whose whole window continues its copy is checked first, without
    the window's bookkeeping."""
    H, W = src.shape[0], src.shape[1]
    h, w, nf = feat.shape
    r = p.radius
    side = 2 * r + 1
    k = knn.shape[2]
    hmax = max(h, w)
    nb = np.empty(side * side * nf)
    nb_ok = np.zeros(side * side, np.bool_)
    buf = np.empty(nf)
    seen = np.empty((8, 2))
    # window element -> the position it holds (win) and the one it implies for the pixel
    # (implied: its position minus its offset; NaN outside the output); the 8 neighbours' areas
    win = np.empty((side * side, 2), np.int64)
    implied = np.empty((side * side, 2))
    area8 = np.empty(8)
    # the coherent and k-NN candidates of a pixel, in the order they are costed
    listed = np.empty((8 * (1 + k), 3))  # (row, col, 1 for a neighbour's continuation)
    # every candidate is integral where the pixel's window is (fast): settling is exact. An
    # integral lattice (identity Jacobian) snaps integral positions to integral ones; a table
    # of regions' lattices is searched in full
    plain = ((lattice.rank == 0 or lattice.integral) and table.shape[0] == 0
             and p.seam >= 0.0 and p.guide >= 0.0
             and p.lo[0] == np.floor(p.lo[0]) and p.lo[1] == np.floor(p.lo[1])
             and p.hi[0] == np.floor(p.hi[0]) and p.hi[1] == np.floor(p.hi[1]))
    for y in range(y0, y1):
        for x in range((y + p.parity) % 2, W, 2):
            # J's entries as scalars, not a view jac[y, x] (reference counts, see above)
            j00 = jac[y, x, 0, 0]
            j01 = jac[y, x, 0, 1]
            j10 = jac[y, x, 1, 0]
            j11 = jac[y, x, 1, 1]
            fast = j00 == 1.0 and j01 == 0.0 and j10 == 0.0 and j11 == 1.0
            if fast and plain and _integral_inside(src[y, x, 0], src[y, x, 1], r, h - 1, w - 1):
                # a pixel whose whole window continues its copy: settled? (see the docstring;
                # the current position's cost from the operations the search below uses)
                cy = np.float64(src[y, x, 0])
                cx = np.float64(src[y, x, 1])
                whole = True
                for dy in range(-r, r + 1):
                    for dx in range(-r, r + 1):
                        qy, qx, inside = neighbour(y, x, dy, dx, H, W, p.wrap)
                        if inside and (src[qy, qx, 0] - dy != cy or src[qy, qx, 1] - dx != cx):
                            whole = False
                            break
                    if not whole:
                        break
                if whole:
                    n_inside = 0
                    excess = 0.0
                    for j in range(8):
                        qy, qx, inside = neighbour(y, x, EIGHT_NEIGHBOURS[j, 0],
                                                   EIGHT_NEIGHBOURS[j, 1], H, W, p.wrap)
                        if inside:
                            n_inside += 1
                            if area[qy, qx] > p.max_area:
                                excess += area[qy, qx] / p.max_area - 1.0
                    # the current position matches itself (matching cost 0): its cost is its
                    # seam and guide terms alone
                    best = 0.0
                    if p.seam != 0.0:
                        best = p.seam * excess
                    if p.guide != 0.0:
                        gy = min(max(int(cy + 0.5), 0), gex.shape[0] - 1)
                        gx = min(max(int(cx + 0.5), 0), gex.shape[1] - 1)
                        d = gex[gy, gx] - gout[y, x]
                        best = best + p.guide * d * d
                    if best <= p.seam * n_inside:
                        dst[y, x, 0] = src[y, x, 0]
                        dst[y, x, 1] = src[y, x, 1]
                        continue
            n = 0
            for dy in range(-r, r + 1):
                for dx in range(-r, r + 1):
                    qy, qx, inside = neighbour(y, x, dy, dx, H, W, p.wrap)
                    nb_ok[n] = inside
                    if inside:
                        sy = src[qy, qx, 0]
                        sx = src[qy, qx, 1]
                        if (sy == np.floor(sy) and sx == np.floor(sx) and sy >= 0
                                and sy <= h - 1 and sx >= 0 and sx <= w - 1):
                            win[n, 0] = int(sy)
                            win[n, 1] = int(sx)
                            implied[n, 0] = sy - dy
                            implied[n, 1] = sx - dx
                        else:
                            fast = False
                    else:
                        implied[n, 0] = np.nan
                        implied[n, 1] = np.nan
                    n += 1
            if fast:
                for j in range(8):
                    qy, qx, inside = neighbour(y, x, EIGHT_NEIGHBOURS[j, 0],
                                               EIGHT_NEIGHBOURS[j, 1], H, W, p.wrap)
                    if inside:
                        area8[j] = area[qy, qx]
            else:
                _gather(src, feat, y, x, p, nb, nb_ok, buf)
            gathered = not fast

            by = src[y, x, 0]
            bx = src[y, x, 1]
            y0 = by
            x0 = bx
            # a settled pixel (see the docstring): every inside 8-neighbour continues it
            n_inside = -1
            if fast and plain:
                n_inside = 0
                for j in range(8):
                    e = (r + EIGHT_NEIGHBOURS[j, 0]) * side + r + EIGHT_NEIGHBOURS[j, 1]
                    ey = implied[e, 0]
                    if ey != ey:  # no neighbour there
                        continue
                    if ey != y0 or implied[e, 1] != x0:
                        n_inside = -1
                        break
                    n_inside += 1
            # costed in turn: the current position, the listed ones, then the PatchMatch random
            # search around the best so far, at halving radii, plus one global draw
            index = y * W + x
            radius = hmax * 0.5
            best = np.inf
            n_listed = 0
            for c in range(2 + 8 * (1 + k) + p.n_random):
                if c > n_listed + p.n_random + 1:
                    break
                if c == 1:
                    if n_inside >= 0 and best <= p.seam * n_inside:
                        break  # settled: no other candidate can beat the current position
                    # coherent candidates from the 8 neighbours, each followed by its k most
                    # similar positions
                    n_listed = 0
                    n_seen = 0
                    for dy in range(-1, 2):
                        for dx in range(-1, 2):
                            if dy == 0 and dx == 0:
                                continue
                            qy, qx, inside = neighbour(y, x, dy, dx, H, W, p.wrap)
                            if not inside:
                                continue
                            cy = src[qy, qx, 0] - (j00 * dy + j01 * dx)
                            cx = src[qy, qx, 1] - (j10 * dy + j11 * dx)
                            if cy < p.lo[0] or cy > p.hi[0] or cx < p.lo[1] or cx > p.hi[1]:
                                continue
                            # inside a copy the neighbours propose the same position: cost it
                            # (and its k-NN) once; the current position was costed first
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
                                listed[n_listed, 0] = cy
                                listed[n_listed, 1] = cx
                                listed[n_listed, 2] = 1.0
                                n_listed += 1
                            iy = int(cy + 0.5)
                            ix = int(cx + 0.5)
                            fy = cy - iy
                            fx = cx - ix
                            for j in range(k):
                                listed[n_listed, 0] = _clamp(knn[iy, ix, j, 0] + fy, p.lo[0],
                                                             p.hi[0])
                                listed[n_listed, 1] = _clamp(knn[iy, ix, j, 1] + fx, p.lo[1],
                                                             p.hi[1])
                                listed[n_listed, 2] = 0.0
                                n_listed += 1
                if c == 0:
                    cy = np.float64(by)
                    cx = np.float64(bx)
                elif c <= n_listed:
                    cy = listed[c - 1, 0]
                    cx = listed[c - 1, 1]
                else:
                    j = c - 1 - n_listed
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
                if c > 0 and (lattice.rank != 0 or table.shape[0] != 0):
                    lp = region_lattice(lattice, table, regions, cy, cx)
                    if lp.rank != 0:
                        continuing = c <= n_listed and listed[c - 1, 2] != 0.0
                        cy, cx = lattice_snap(cy, cx, y, x, lp, phase_map,
                                              lp.keep if continuing else 0.5)
                        if cy < p.lo[0] or cy > p.hi[0] or cx < p.lo[1] or cx > p.hi[1]:
                            continue
                if fast and _integral_inside(cy, cx, r, h - 1, w - 1):
                    # _total_cost in place (see the docstring): the seam penalty ...
                    seam = 0.0
                    if p.seam != 0.0:
                        n_broken = 0
                        excess = 0.0
                        for j in range(8):
                            e = (r + EIGHT_NEIGHBOURS[j, 0]) * side + r + EIGHT_NEIGHBOURS[j, 1]
                            ey = implied[e, 0]
                            if ey != ey:  # no neighbour there
                                continue
                            if ey != cy or implied[e, 1] != cx:
                                n_broken += 1
                            elif area8[j] > p.max_area:
                                excess += area8[j] / p.max_area - 1.0
                        seam = p.seam * (n_broken + excess)
                    if p.guide != 0.0:  # _guide_penalty (0.0 unguided: seam + 0.0 is seam)
                        gy = min(max(int(cy + 0.5), 0), gex.shape[0] - 1)
                        gx = min(max(int(cx + 0.5), 0), gex.shape[1] - 1)
                        d = gex[gy, gx] - gout[y, x]
                        seam = seam + p.guide * d * d
                    cost = np.inf
                    if not seam >= best:  # (not <: a NaN best, from an infinite occupancy)
                        # ... and _candidate_cost's occupancy-weighted SSD
                        iy = int(cy)
                        ix = int(cx)
                        factor = 1.0 + p.lam * occ[iy, ix]
                        limit = (best - seam) / factor
                        total = 0.0
                        n = 0
                        for dy in range(-r, r + 1):
                            for dx in range(-r, r + 1):
                                ey = implied[n, 0]
                                if ey == ey and (ey != cy or implied[n, 1] != cx):
                                    sy = win[n, 0]
                                    sx = win[n, 1]
                                    for f in range(nf):
                                        diff = (np.float64(feat[sy, sx, f])
                                                - np.float64(feat[iy + dy, ix + dx, f]))
                                        total += diff * diff
                                    if total >= limit:
                                        break
                                n += 1
                            if total >= limit:
                                break
                        if not total >= limit:  # as _candidate_cost, NaN limit included
                            cost = seam + total * factor
                elif c == 0:  # two call sites on purpose: one shared branch compiles longer
                    if not gathered:
                        _gather(src, feat, y, x, p, nb, nb_ok, buf)
                        gathered = True
                    # the current position as stored (float32 arithmetic in the seam test)
                    cost = _total_cost(src, area, y, x, feat, src[y, x, 0], src[y, x, 1],
                                       jac[y, x], nb, nb_ok, occ, p, best, buf, gex, gout)
                else:
                    if not gathered:
                        _gather(src, feat, y, x, p, nb, nb_ok, buf)
                        gathered = True
                    cost = _total_cost(src, area, y, x, feat, cy, cx, jac[y, x], nb, nb_ok, occ,
                                       p, best, buf, gex, gout)
                if c == 0 or cost < best:
                    best, by, bx = cost, cy, cx
            dst[y, x, 0] = by
            dst[y, x, 1] = bx


# Parameters of a k-NN table of similar positions (knn_table).
#   lo, hi    (int, int)  the box of reference positions (row, col), inclusive
#   k         int64       positions per pixel
#   stride    int64       step of the reference grid inside the box
#   exclude   int64       references within this many pixels of the pixel (both axes) are skipped
KnnParams = namedtuple("KnnParams", "lo hi k stride exclude")

# knn_table's screen. A matrix product in float32 gives every squared distance |a - r|^2 to
# within _DOT_SLACK (|a|^2 + |r|^2) (a 16-term float32 dot product's error bound is about a tenth
# of that), and the direct search's own sum (float32 differences squared, summed in float64) is
# within _SQUARE_SLACK of the true distance (three roundings of 2^-24, with room to spare).
_DOT_SLACK = 1e-5
_SQUARE_SLACK = 1e-6
_TINY = 1e-30  # below any of these: float32 squares that underflow
_INVERSE = 1.0 / (1.0 - _SQUARE_SLACK) * (1.0 + 1e-15)  # no smaller than the division
# one product's size (its rows: pixels): about 1 MB of dot products, in the cache when the
# kernel reads them, in few enough calls
_SCREEN_BYTES = 1 << 20


def knn_table(feat, p):
    """For every exemplar pixel, the p.k positions (from a grid of step p.stride inside the box
    p.lo..p.hi) with the nearest appearance features, excluding those within p.exclude pixels.
    Returns int32[h, w, k, 2]; ties are broken by scan order. p: KnnParams.

    Each pixel's distances to all references are first bounded from a matrix product (BLAS);
    only the references whose bound can reach the k nearest are then summed exactly
    as a direct search sums them: the same table as the direct search, in a fraction of the
    time."""
    h, w, nf = feat.shape
    out = np.zeros((h, w, p.k, 2), np.int32)
    ref_y = np.arange(p.lo[0], p.hi[0] + 1, p.stride, dtype=np.int64)
    ref_x = np.arange(p.lo[1], p.hi[1] + 1, p.stride, dtype=np.int64)
    feat = np.ascontiguousarray(feat)
    refs = np.ascontiguousarray(feat[ref_y][:, ref_x].reshape(-1, nf))
    norms = np.square(refs, dtype=np.float64).sum(axis=1)
    bounds = np.stack(((1.0 + _DOT_SLACK) * norms, (1.0 - _DOT_SLACK) * norms))
    pixels = max(1, _SCREEN_BYTES // (4 * max(refs.shape[0], 1)))
    # features-major for the exact sums, as the direct search holds them
    # each reference's row and column (scan order), read where a reference is kept
    grid_y, grid_x = np.meshgrid(ref_y, ref_x, indexing="ij")
    run_bands(_knn_band, h, feat, refs, np.ascontiguousarray(refs.T), bounds, grid_y.ravel(),
              grid_x.ravel(), p, out, pixels)
    return out


def _knn_band(feat, refs, refs_fm, bounds, ref_y, ref_x, p, out, pixels, y0, y1):
    """knn_table's rows y0 <= y < y1: a product for `pixels` pixels (in scan order) at a time,
    then the kernel."""
    w, nf = feat.shape[1], feat.shape[2]
    flat = feat.reshape(-1, nf)
    for first in range(y0 * w, y1 * w, pixels):
        end = min(first + pixels, y1 * w)
        _knn_rows(feat, refs_fm, bounds, ref_y, ref_x, flat[first:end] @ refs.T, p, out, first,
                  end)


@njit(cache=True, nogil=True)
def _knn_rows(feat, refs, bounds, ref_y, ref_x, dots, p, out, first, end):
    """knn_table's pixels first <= y * w + x < end (scan order), written into out.
    dots[y * w + x - first, i]: pixel (y, x)'s dot product with reference i (from a matrix
    product); bounds: (1 +- _DOT_SLACK) |r_i|^2 (float64 [2, n]); ref_y, ref_x: reference i's
    row and column.

    With a = the pixel's features, reference i's distance d_i (the direct search's sum) lies
    between (1 - S)((1 - D)|a|^2 + lo_i) and (1 + S)((1 + D)|a|^2 + up_i), where up_i, lo_i =
    (1 +- D)|r_i|^2 - 2 a.r_i (D: _DOT_SLACK, S: _SQUARE_SLACK). A reference whose lower bound
    exceeds the k-th smallest upper bound (of the references not excluded) is beaten by k
    others: only the rest are summed exactly, in scan order, into the same insertion as the
    direct search (ties keep the earlier reference)."""
    lo0, hi0, lo1, hi1 = p.lo[0], p.hi[0], p.lo[1], p.hi[1]
    k, exclude = p.k, p.exclude
    w, nf = feat.shape[1], feat.shape[2]
    count = ref_y.size
    kept = np.empty(count, np.int64)
    best_d = np.empty(k)
    best_i = np.empty((k, 2), np.int64)
    low = np.empty(count)
    for n in range(first, end):
        y = n // w
        x = n - y * w
        row = dots[n - first]
        for i in range(count):  # apart from the pass below: a loop that vectorises
            low[i] = bounds[1, i] - 2.0 * np.float64(row[i])
        na = 0.0
        for f in range(nf):
            na += np.float64(feat[y, x, f]) * np.float64(feat[y, x, f])
        for j in range(k):
            best_d[j] = np.inf
        # one pass: the k smallest upper bounds so far, and every reference whose lower
        # bound is within the k-th of them at its turn (the k-th only falls: a superset)
        limit = np.inf
        n_kept = 0
        for i in range(count):
            if not low[i] <= limit:
                continue
            if abs(ref_y[i] - y) <= exclude and abs(ref_x[i] - x) <= exclude:
                continue
            kept[n_kept] = i
            n_kept += 1
            u = bounds[0, i] - 2.0 * np.float64(row[i])
            if u < best_d[k - 1]:
                j = k - 1
                while j > 0 and best_d[j - 1] > u:
                    best_d[j] = best_d[j - 1]
                    j -= 1
                best_d[j] = u
                bound = (1.0 + _SQUARE_SLACK) * ((1.0 + _DOT_SLACK) * na + best_d[k - 1])
                limit = (bound + 2 * _TINY) * _INVERSE - (1.0 - _DOT_SLACK) * na
        for j in range(k):
            best_d[j] = np.inf
            best_i[j, 0] = min(max(y, lo0), hi0)
            best_i[j, 1] = min(max(x, lo1), hi1)
        for m in range(n_kept):  # in scan order, so ties keep the earlier reference
            i = kept[m]
            if not low[i] <= limit:
                continue
            d = 0.0
            for f in range(nf):  # features in order: the direct search's sums
                diff = feat[y, x, f] - refs[f, i]
                d += diff * diff
            if d < best_d[k - 1]:
                j = k - 1
                while j > 0 and best_d[j - 1] > d:
                    best_d[j] = best_d[j - 1]
                    best_i[j, 0] = best_i[j - 1, 0]  # not best_i[j] = best_i[j - 1]:
                    best_i[j, 1] = best_i[j - 1, 1]  # see som._update_box
                    j -= 1
                best_d[j] = d
                best_i[j, 0] = ref_y[i]
                best_i[j, 1] = ref_x[i]
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

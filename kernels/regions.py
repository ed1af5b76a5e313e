"""Copy regions of a position field: labelling, areas, and whole-region shifts.

A copy region is a 4-connected set of output pixels whose exemplar positions continue each other
(S[q] - S[p] == J (q - p)): a verbatim copy of part of the exemplar. Pixel-wise refinement moves
the borders between copies but never the copies themselves: a copy's offset is fixed where it
first appears, at a coarse level. `align_regions` moves whole copies by a few pixels where that
makes their borders match better, as image quilting chooses each block's offset by its overlap.
"""

from collections import namedtuple

import numpy as np
from numba import njit

from osmap_kernels.common import EIGHT_NEIGHBOURS, find_root, neighbour, sample
from osmap_kernels.lattice import NO_LATTICE, lattice_shift_ok

# Parameters of one alignment pass.
#   radius    int64    matching window half-size, as in RefineParams
#   wrap      bool     output is toroidal (tileable)
#   lo, hi    float64[2] valid exemplar positions
#   seam      float64  cost per 8-neighbour whose position does not continue a pixel's
#   max_area  float64  a shift may not merge two copies into one larger than this (pixels)
#   reach     int64    shifts tried: every (dy, dx) with |dy|, |dx| <= reach
#   lattice   osmap_kernels.lattice.LatticeParams: with a lattice (rank > 0), only the shifts
#             that keep a consistent copy consistent (lattice_shift_ok)
AlignParams = namedtuple("AlignParams", "radius wrap lo hi seam max_area reach lattice",
                         defaults=(NO_LATTICE,))

# neighbours whose positions continue each other to within this (each axis) are one copy
COPY_TOL = 1e-3


@njit(cache=True)
def _stable_order(keys, n_keys):
    """The stable sorting permutation of integer keys in [0, n_keys) (a counting sort: the same
    order as np.argsort(keys, kind="mergesort"), without compiling Numba's merge sort), and
    starts: the sorted positions of key k are starts[k] .. starts[k + 1] - 1."""
    starts = np.zeros(n_keys + 1, np.int64)
    for i in range(keys.shape[0]):
        starts[keys[i] + 1] += 1
    for k in range(n_keys):
        starts[k + 1] += starts[k]
    order = np.empty(keys.shape[0], np.int64)
    fill = starts[:n_keys].copy()
    for i in range(keys.shape[0]):
        k = keys[i]
        order[fill[k]] = i
        fill[k] += 1
    return order, starts


@njit(cache=True)
def _label_counts(labels, count):
    """Pixels per label (labels int64[H, W] in [0, count)): float64[count]."""
    counts = np.zeros(count)
    for y in range(labels.shape[0]):
        for x in range(labels.shape[1]):
            counts[labels[y, x]] += 1.0
    return counts


@njit(cache=True, inline="always")
def _copy_region_forest(pos, jac, wrap, tol):
    """Union-find forest (int64[H*W]) of the copy regions (neighbours whose positions continue
    each other to within tol on each axis): every root is its region's first pixel in scan
    order."""
    H, W = pos.shape[0], pos.shape[1]
    parent = np.arange(H * W)
    for y in range(H):
        for x in range(W):
            for step in range(2):
                dy = 1 if step == 0 else 0
                dx = 1 - dy
                qy = y + dy
                qx = x + dx
                if qy >= H or qx >= W:
                    if not wrap:
                        continue
                    qy %= H
                    qx %= W
                J = jac[y, x]
                ey = pos[qy, qx, 0] - pos[y, x, 0] - (J[0, 0] * dy + J[0, 1] * dx)
                ex = pos[qy, qx, 1] - pos[y, x, 1] - (J[1, 0] * dy + J[1, 1] * dx)
                if abs(ey) < tol and abs(ex) < tol:
                    a = find_root(parent, y * W + x)
                    b = find_root(parent, qy * W + qx)
                    if a != b:
                        parent[max(a, b)] = min(a, b)
    return parent


@njit(cache=True, inline="always")
def copy_region_labels(pos, jac, wrap):
    """Label of every pixel's copy region: the scan index of its first pixel. int64[H, W]."""
    H, W = pos.shape[0], pos.shape[1]
    parent = _copy_region_forest(pos, jac, wrap, COPY_TOL)
    labels = np.empty((H, W), np.int64)
    for y in range(H):
        for x in range(W):
            labels[y, x] = find_root(parent, y * W + x)
    return labels


@njit(cache=True, inline="always")
def copy_region_ids(pos, jac, wrap, tol=COPY_TOL):
    """(ids int64[H, W], count): the copy regions numbered 0 .. count - 1 in the scan order of
    their first pixels. The same order as copy_region_labels', so label-ordered work gives the
    same result; per-region arrays then hold count entries, not H*W. A larger `tol` joins
    near-copies too (neighbours whose positions continue each other to within tol)."""
    H, W = pos.shape[0], pos.shape[1]
    parent = _copy_region_forest(pos, jac, wrap, tol)
    ids = np.empty((H, W), np.int64)
    count = 0
    for i in range(H * W):
        root = find_root(parent, i)
        if root == i:  # a region's first pixel
            ids[i // W, i % W] = count
            count += 1
        else:
            ids[i // W, i % W] = ids[root // W, root % W]
    return ids, count


@njit(cache=True, nogil=True)
def copy_region_areas(pos, jac, wrap):
    """Area of the verbatim-copy region around every pixel (see copy_region_labels).
    float32[H, W]."""
    labels, count = copy_region_ids(pos, jac, wrap)
    counts = _label_counts(labels, count)
    out = np.empty(labels.shape, np.float32)
    for y in range(labels.shape[0]):
        for x in range(labels.shape[1]):
            out[y, x] = counts[labels[y, x]]
    return out


@njit(cache=True, inline="always")
def _border_pixels(labels, count, radius, wrap):
    """(region, pixel) pairs, sorted by region (labels in [0, count)): pixel b is on region R's
    border when b's matching window holds pixels of R and of another region, i.e. when shifting
    R changes b's cost."""
    H, W = labels.shape
    side = 2 * radius + 1
    out_region = np.empty(H * W * 4, np.int64)
    out_pixel = np.empty(H * W * 4, np.int64)
    found = np.empty(side * side, np.int64)
    n = 0
    for y in range(H):
        for x in range(W):
            n_found = 0
            for dy in range(-radius, radius + 1):
                for dx in range(-radius, radius + 1):
                    qy, qx, inside = neighbour(y, x, dy, dx, H, W, wrap)
                    if not inside:
                        continue
                    label = labels[qy, qx]
                    new = True
                    for j in range(n_found):
                        if found[j] == label:
                            new = False
                    if new:
                        found[n_found] = label
                        n_found += 1
            if n_found < 2:
                continue
            if n + n_found > out_region.shape[0]:
                out_region = np.concatenate((out_region, np.empty_like(out_region)))
                out_pixel = np.concatenate((out_pixel, np.empty_like(out_pixel)))
            for j in range(n_found):
                out_region[n] = found[j]
                out_pixel[n] = y * W + x
                n += 1
    order, _ = _stable_order(out_region[:n], count)
    regions = np.empty(n, np.int64)
    pixels = np.empty(n, np.int64)
    for j in range(n):
        regions[j] = out_region[order[j]]
        pixels[j] = out_pixel[order[j]]
    return regions, pixels


@njit(cache=True, inline="always")
def _border_terms(pos, labels, group, area, feat, jac, border, region, p, terms):
    """The border cost terms that change when `region` moves by a shift d, in a form that
    costs each shift cheaply: matching terms |fixed - feat(base + d)|^2 (a pixel of the region
    against one outside it, in either role), and seam terms that vanish when d == target (the
    shift that makes a pair of 8-neighbours across the border continue each other), with the
    region on the other side, flagged when that would merge two copies into one larger than
    p.max_area (group, area: the copies merged so far and their areas). Fills the scratch
    arrays `terms` (see _scratch) and returns views of the filled parts."""
    H, W = pos.shape[0], pos.shape[1]
    nf = feat.shape[2]
    r = p.radius
    fixed, base, target, merges, others = terms
    buf = np.empty(nf)
    n = 0
    m = 0
    for b in border:
        y = b // W
        x = b - y * W
        J = jac[y, x]
        inner = labels[y, x] == region
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                qy, qx, inside = neighbour(y, x, dy, dx, H, W, p.wrap)
                if not inside or (labels[qy, qx] == region) == inner:
                    continue
                ey = pos[y, x, 0] + J[0, 0] * dy + J[0, 1] * dx
                ex = pos[y, x, 1] + J[1, 0] * dy + J[1, 1] * dx
                if inner:  # the window's centre moves, its outside neighbour stays
                    sample(feat, pos[qy, qx, 0], pos[qy, qx, 1], buf)
                    base[n, 0] = ey
                    base[n, 1] = ex
                else:
                    sample(feat, ey, ex, buf)
                    base[n, 0] = pos[qy, qx, 0]
                    base[n, 1] = pos[qy, qx, 1]
                for f in range(nf):
                    fixed[n, f] = buf[f]
                n += 1
        for k in range(8):
            dy, dx = EIGHT_NEIGHBOURS[k, 0], EIGHT_NEIGHBOURS[k, 1]
            qy, qx, inside = neighbour(y, x, dy, dx, H, W, p.wrap)
            if not inside or (labels[qy, qx] == region) == inner:
                continue
            ey = pos[qy, qx, 0] - pos[y, x, 0] - (J[0, 0] * dy + J[0, 1] * dx)
            ex = pos[qy, qx, 1] - pos[y, x, 1] - (J[1, 0] * dy + J[1, 1] * dx)
            sign = 1.0 if inner else -1.0
            target[m, 0] = sign * ey
            target[m, 1] = sign * ex
            here = find_root(group, labels[y, x])
            there = find_root(group, labels[qy, qx])
            merges[m] = here != there and area[here] + area[there] > p.max_area
            others[m] = labels[qy, qx] if inner else labels[y, x]
            m += 1
    return fixed[:n], base[:n], target[:m], merges[:m], others[:m]


@njit(cache=True, inline="always")
def _scratch(longest_border, radius, nf):
    """Scratch arrays for _border_terms, large enough for a border of `longest_border` pixels:
    allocated once per pass rather than once per region."""
    n_max = longest_border * (2 * radius + 1) ** 2
    return (np.empty((n_max, nf), np.float32), np.empty((n_max, 2)),
            np.empty((longest_border * 8, 2)), np.empty(longest_border * 8, np.bool_),
            np.empty(longest_border * 8, np.int64))


@njit(cache=True)
def _shift_cost(feat, fixed, base, target, merges, sy, sx, seam, limit):
    """Cost of the border terms with the region moved by (sy, sx): inf for a forbidden merge
    or once the cost reaches `limit`."""
    moved = sy != 0 or sx != 0
    total = 0.0
    for m in range(target.shape[0]):
        if abs(sy - target[m, 0]) > 1e-3 or abs(sx - target[m, 1]) > 1e-3:
            total += seam
        elif moved and merges[m]:
            return np.inf
    nf = feat.shape[2]
    buf = np.empty(nf)
    for n in range(fixed.shape[0]):
        sample(feat, base[n, 0] + sy, base[n, 1] + sx, buf)
        for f in range(nf):
            diff = fixed[n, f] - buf[f]
            total += diff * diff
        if total >= limit:
            return np.inf
    return total


@njit(cache=True, inline="always")
def _shifts_by_length(reach):
    """Every (dy, dx) with |dy|, |dx| <= reach, shortest first (ties in scan order), so that
    among equally good shifts the smallest wins; (0, 0) first."""
    side = 2 * reach + 1
    shifts = np.empty((side * side, 2), np.int64)
    lengths = np.empty(side * side, np.int64)
    for j in range(side * side):
        shifts[j, 0] = j // side - reach
        shifts[j, 1] = j % side - reach
        lengths[j] = shifts[j, 0] ** 2 + shifts[j, 1] ** 2
    order, _ = _stable_order(lengths, 2 * reach * reach + 1)
    out = np.empty((side * side, 2), np.int64)
    for j in range(side * side):
        out[j, 0] = shifts[order[j], 0]
        out[j, 1] = shifts[order[j], 1]
    return out


@njit(cache=True, inline="always")
def _seam_part(target, merges, sy, sx, seam):
    """The seam terms of shift (sy, sx) of a moved region, added in _shift_cost's order; inf
    for a forbidden merge."""
    total = 0.0
    for m in range(target.shape[0]):
        if abs(sy - target[m, 0]) > 1e-3 or abs(sx - target[m, 1]) > 1e-3:
            total += seam
        elif merges[m]:
            return np.inf
    return total


# _best_shift's screen: a shift's matching terms summed in float32, each term's features in any
# order (a loop that vectorises), are within 2e-6 of its exact float64 sum (about twenty
# roundings of 2^-24 per term, every term >= 0): _SCREEN_SLACK leaves room to spare, and
# _ROUNDING covers the float64 sums' own roundings
_SCREEN_SLACK = 1e-5
_ROUNDING = 1e-9
_UNDERFLOW = 1e-25  # float32 squares too small to represent, all terms together


@njit(cache=True, fastmath={"reassoc", "contract", "nsz", "arcp"})
def _screen_terms(fixed, n, feat, at, n_live, totals):
    """Adds |fixed[n] - feat[at[k]]|^2 (float32, in whatever order vectorises: the screen's
    terms) to totals[k, 1] for each of the first n_live shifts."""
    for k in range(n_live):
        y, x = at[k, 0], at[k, 1]
        total = np.float32(0.0)
        for f in range(feat.shape[2]):
            diff = fixed[n, f] - feat[y, x, f]
            total += diff * diff
        totals[k, 1] += np.float64(total)


@njit(cache=True, inline="always")
def _exact_cost(feat, fixed, base, sy, sx, start, limit, fetched):
    """`start` plus the matching terms of shift (sy, sx), summed term by term and feature by
    feature in float64 (_shift_cost's sums); stops once the sum reaches `limit`."""
    h, w, nf = feat.shape
    total = start
    for n in range(fixed.shape[0]):
        by, bx = base[n, 0], base[n, 1]
        if by == np.floor(by) and bx == np.floor(bx):  # integer shifts: sample's fetch
            y0 = min(max(int(by) + sy, 0), h - 1)
            x0 = min(max(int(bx) + sx, 0), w - 1)
            for f in range(nf):
                diff = np.float64(fixed[n, f]) - np.float64(feat[y0, x0, f])
                total += diff * diff
        else:
            sample(feat, by + sy, bx + sx, fetched)
            for f in range(nf):
                diff = fixed[n, f] - fetched[f]
                total += diff * diff
        if total >= limit:
            break
    return total


@njit(cache=True, inline="always")
def _best_shift(feat, fixed, base, target, merges, shifts, lo_pos, hi_pos, p, live, totals,
                fetched, at):
    """Index into shifts of the cheapest shift that keeps the region's positions (extent lo_pos
    to hi_pos) inside [p.lo, p.hi]; 0 (no shift) unless another is strictly cheaper.

    Every shift's cost is its seam terms plus its matching terms, summed in _shift_cost's order
    (float64). A screen first bounds them cheaply (the matching terms in float32,
    _screen_terms): the unshifted cost from above, then every shift's from below, all shifts
    together, one border term at a time, a shift dropping out once its bound reaches the
    unshifted one (it then cannot be cheaper). Only the shifts left (most regions have none)
    are summed exactly, with the unshifted cost, in shift order, the smallest index winning a
    tie, as when the shifts are tried one by one. `live`, `totals`, `fetched` and `at` are
    scratch arrays (a shift each; two columns a shift; the feature count; two columns a
    shift)."""
    h, w, nf = feat.shape
    # the screen's bound on the unshifted cost: the seam terms, then the matching terms
    unshifted = 0.0
    for m in range(target.shape[0]):  # as _shift_cost's for no shift (the region stays)
        if abs(target[m, 0]) > 1e-3 or abs(target[m, 1]) > 1e-3:
            unshifted += p.seam
    totals[0, 1] = 0.0
    for n in range(fixed.shape[0]):
        by, bx = base[n, 0], base[n, 1]
        if by == np.floor(by) and bx == np.floor(bx):
            at[0, 0] = min(max(int(by), 0), h - 1)
            at[0, 1] = min(max(int(bx), 0), w - 1)
            _screen_terms(fixed, n, feat, at, 1, totals)
        else:
            sample(feat, by, bx, fetched)
            for f in range(nf):
                diff = fixed[n, f] - fetched[f]
                totals[0, 1] += diff * diff
    most = (unshifted + (1.0 + _SCREEN_SLACK) * totals[0, 1] + _UNDERFLOW) * (1.0 + _ROUNDING)
    n_live = 0
    for j in range(1, shifts.shape[0]):
        sy, sx = shifts[j, 0], shifts[j, 1]
        if (lo_pos[0] + sy < p.lo[0] or hi_pos[0] + sy > p.hi[0]
                or lo_pos[1] + sx < p.lo[1] or hi_pos[1] + sx > p.hi[1]):
            continue
        if p.lattice.rank != 0 and not lattice_shift_ok(sy, sx, p.lattice):
            continue
        total = _seam_part(target, merges, sy, sx, p.seam)
        if total < most:
            live[n_live] = j
            totals[n_live, 0] = total  # the seam terms
            totals[n_live, 1] = 0.0  # the screen's matching sum
            n_live += 1
    n = 0
    while n_live > 0 and n < fixed.shape[0]:
        by, bx = base[n, 0], base[n, 1]
        exact = by == np.floor(by) and bx == np.floor(bx)  # integer shifts: sample's fetch
        if exact:
            for k in range(n_live):
                at[k, 0] = min(max(int(by) + shifts[live[k], 0], 0), h - 1)
                at[k, 1] = min(max(int(bx) + shifts[live[k], 1], 0), w - 1)
            _screen_terms(fixed, n, feat, at, n_live, totals)
        else:
            for k in range(n_live):
                sample(feat, by + shifts[live[k], 0], bx + shifts[live[k], 1], fetched)
                term = 0.0
                for f in range(nf):
                    diff = fixed[n, f] - fetched[f]
                    term += diff * diff
                totals[k, 1] += term
        kept = 0
        for k in range(n_live):  # in order: the earlier of two equal shifts stays first
            least = ((totals[k, 0] + (1.0 - _SCREEN_SLACK) * totals[k, 1] - _UNDERFLOW)
                     * (1.0 - _ROUNDING))
            if least < most:
                live[kept] = live[k]
                totals[kept, 0] = totals[k, 0]
                totals[kept, 1] = totals[k, 1]
                kept += 1
        n_live = kept
        n += 1
    if n_live == 0:
        return 0
    zero = np.int64(0)  # not a literal 0: that would compile _shift_cost a second time
    best = 0
    best_cost = _shift_cost(feat, fixed, base, target, merges, zero, zero, p.seam, np.inf)
    for k in range(n_live):
        sy, sx = shifts[live[k], 0], shifts[live[k], 1]
        total = _exact_cost(feat, fixed, base, sy, sx, totals[k, 0], best_cost, fetched)
        if total < best_cost:
            best, best_cost = live[k], total
    return best


@njit(cache=True, inline="always")
def _region_extents(pos, labels, count):
    """Per label (in [0, count)), the smallest and largest exemplar position of its pixels:
    [count, 2] x 2, in pos's dtype (float32 in synth: exact)."""
    H, W = labels.shape
    lo_pos = np.full((count, 2), np.inf, pos.dtype)
    hi_pos = np.full((count, 2), -np.inf, pos.dtype)
    for y in range(H):
        for x in range(W):
            label = labels[y, x]
            for c in range(2):
                lo_pos[label, c] = min(lo_pos[label, c], pos[y, x, c])
                hi_pos[label, c] = max(hi_pos[label, c], pos[y, x, c])
    return lo_pos, hi_pos


@njit(cache=True, inline="always")
def _region_starts(regions):
    """Start index of each run of equal labels in the sorted `regions`, and the end; and the
    longest run."""
    runs = 1
    for i in range(1, regions.shape[0]):
        if regions[i] != regions[i - 1]:
            runs += 1
    starts = np.empty(runs + 1, np.int64)
    starts[0] = 0
    j = 1
    longest = 0
    for i in range(1, regions.shape[0] + 1):
        if i == regions.shape[0] or regions[i] != regions[i - 1]:
            starts[j] = i
            longest = max(longest, i - starts[j - 1])
            j += 1
    return starts, longest


@njit(cache=True, nogil=True)
def align_regions(pos, feat, jac, p):
    """Move whole copy regions, one at a time in label order, by the shift within p.reach that
    most lowers the matching and seam cost of their borders (none if no shift does). A shift
    may merge copies (make them continue each other) only up to p.max_area.

    pos float32[H, W, 2] positions, feat float32[h, w, F] exemplar appearance, jac float32[H, W,
    2, 2] output-to-exemplar Jacobian. Returns the new positions; pos is not modified.
    """
    pos = pos.copy()
    W = pos.shape[1]
    # regions numbered in label order: the same order, per-region arrays of `count` entries
    labels, count = copy_region_ids(pos, jac, p.wrap)
    regions, pixels = _border_pixels(labels, count, p.radius, p.wrap)
    if regions.shape[0] == 0:
        return pos
    starts, longest = _region_starts(regions)
    lo_pos, hi_pos = _region_extents(pos, labels, count)
    area = _label_counts(labels, count)
    group = np.arange(count)  # copies merged by this pass's shifts (union-find over regions)
    members, member_starts = _stable_order(labels.ravel(), count)  # pixels by region
    shifts = _shifts_by_length(p.reach)
    terms = _scratch(longest, p.radius, feat.shape[2])
    live = np.empty(shifts.shape[0], np.int64)
    totals = np.empty((shifts.shape[0], 2))
    fetched = np.empty(feat.shape[2])
    at = np.empty((shifts.shape[0], 2), np.int64)
    for i in range(starts.shape[0] - 1):
        region = regions[starts[i]]
        border = pixels[starts[i]:starts[i + 1]]
        fixed, base, target, merges, others = _border_terms(pos, labels, group, area, feat, jac,
                                                            border, region, p, terms)
        j = _best_shift(feat, fixed, base, target, merges, shifts, lo_pos[region],
                        hi_pos[region], p, live, totals, fetched, at)
        if j == 0:
            continue
        sy, sx = shifts[j, 0], shifts[j, 1]
        for m in range(member_starts[region], member_starts[region + 1]):
            y = members[m] // W
            x = members[m] - y * W
            pos[y, x, 0] += sy
            pos[y, x, 1] += sx
        for m in range(target.shape[0]):  # the copies it now continues are one copy
            if abs(target[m, 0] - sy) <= 1e-3 and abs(target[m, 1] - sx) <= 1e-3:
                a = find_root(group, region)
                b = find_root(group, others[m])
                if a != b:
                    group[max(a, b)] = min(a, b)
                    area[min(a, b)] += area[max(a, b)]
    return pos

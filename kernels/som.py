"""OS-Map training kernel: local winner search and the anisotropic (matrix-exponential) update.

One kernel, specialised by the parameter record rather than copied: the same loop serves the
classic Kohonen SOM, the paper's OS-Map, and our extensions (coherent targets, range kernel,
periodic data components). The one specialisation is `update_classic`: for Kohonen's update
(target x, nothing else) each row of nodes is updated in a loop the compiler vectorises, with
the general loop's arithmetic, so the weights are the same bit for bit. `train_steps` picks the
update in Python and calls one of two specialisations of the compiled step loop `_train`, so
that synthesis compiles only the general update. Everything
random (inputs, window positions) and the schedule values are computed by the caller, so the
kernel is a pure function of its arrays and is deterministic.

Map nodes live on a grid padded to three axes (a 2D map of shape (H, W) is (1, H, W)); node i has
grid coordinates (i // (g1*g2), (i // g2) % g1, i % g2). D is the map-space vector from the winner
to a node, in those padded coordinates.

Winner search has two exact strategies with the same result (ties: first node in the window's
scan order): a brute-force scan of the window, and an inverse map (`Buckets`): nodes bucketed on
a data-space grid by their model vector, kept up to date by the update, searched in growing rings
of cells around x until no unvisited cell can hold a nearer node.
"""

from collections import namedtuple

import numpy as np
from numba import njit

# The parameter record passed to `train_steps` (a namedtuple is a first-class Numba type).
#   grid      int64[3]        padded map shape
#   wrap      bool[3]         toroidal axes
#   window    int64[3]        winner-search window extent per axis (== grid: global search)
#   quad      float64[F,d,3,3] per frame and data component k: A_k = sum_j c_kj P_kj P_kj^T
#   extent    float64[F,3]    truncation half-width per axis for sigma = 1 (inf: whole axis)
#   separable bool            every A_k diagonal and one frame: use 1D tables
#   jac       float64[d,3]    coherent target x + jac @ D (zeros: the paper's target x)
#   periods   float64[d]      period of each data component (0: not periodic)
#   lo, hi    float64[d]      targets outside [lo, hi] are not applied to that node
#   range_a, range_b  float64 range kernel exp(-|t - m|^2 / 2 tau^2), tau = a*sigma + b (0: off)
#   cutoff    float64         neighbourhood weights below cutoff are skipped
KernelParams = namedtuple(
    "KernelParams",
    "grid wrap window quad extent separable jac periods lo hi range_a range_b cutoff",
)

# The inverse map: a data-space bucket grid over up to 3 non-periodic components.
#   active    bool        use it (False: brute-force scan; the arrays may then be empty)
#   comps     int64[3]    data component of each bucket axis (-1: unused axis, one cell)
#   shape     int64[3]    cells per axis
#   origin    float64[3]  cell c covers origin + [c, c + 1) * size along each axis
#   inv_size  float64[3]  1 / size (the cells at either end reach on to infinity)
#   size      float64[3]  cell size
#   head      int64[C]    first node filed under each cell (-1: empty)
#   links     int64[3, N] per node: next and previous node in its cell's list, and its cell
Buckets = namedtuple("Buckets", "active comps shape origin inv_size size head links")


@njit(cache=True, error_model="numpy")
def _wrapped_diff(a, period):
    """a reduced to [-period/2, period/2) when period > 0."""
    if period > 0.0:
        return a - period * np.floor(a / period + 0.5)
    return a


@njit(cache=True, error_model="numpy")
def _wrap_index(a, g):
    """Grid coordinate a (within one period of [0, g)) brought into [0, g)."""
    if a < 0:
        return a + g
    if a >= g:
        return a - g
    return a


@njit(cache=True, error_model="numpy")
def _run(c, start, last, g):
    """A run of offsets [start, stop] from grid coordinate c along an axis of size g that stays
    contiguous in memory (stops where the axis wraps around): (coordinate of start, stop)."""
    a = _wrap_index(c + start, g)
    return a, min(last, start + g - 1 - a)


@njit(cache=True, error_model="numpy")
def _node_dist(weights, i, x, periods):
    """Squared distance from x to node i's model vector (periodic components wrapped)."""
    dist = 0.0
    for k in range(weights.shape[1]):
        diff = _wrapped_diff(x[k] - weights[i, k], periods[k])
        dist += diff * diff
    return dist


@njit(cache=True, error_model="numpy")
def _run_dists(flat, d, i0, n, x, periods, out):
    """out[j] = squared distance from x to node i0 + j, j < n, summed over k in the same order
    as `_node_dist` (so the values are identical). `flat` is the weights as one C-order vector:
    a slice of it indexed from 0 lets the loops vectorise across nodes (2D indexing does not)."""
    w = flat[i0 * d:(i0 + n) * d]
    if d == 2 and periods[0] == 0.0 and periods[1] == 0.0:
        x0, x1 = x[0], x[1]  # unrolled: the common 2D and 3D cases
        for j in range(n):
            e0 = x0 - w[2 * j]
            e1 = x1 - w[2 * j + 1]
            out[j] = 0.0 + e0 * e0 + e1 * e1
        return
    if d == 3 and periods[0] == 0.0 and periods[1] == 0.0 and periods[2] == 0.0:
        x0, x1, x2 = x[0], x[1], x[2]
        for j in range(n):
            e0 = x0 - w[3 * j]
            e1 = x1 - w[3 * j + 1]
            e2 = x2 - w[3 * j + 2]
            out[j] = 0.0 + e0 * e0 + e1 * e1 + e2 * e2
        return
    for j in range(n):
        out[j] = 0.0
    for k in range(d):
        xk = x[k]
        period = periods[k]
        if period > 0.0:
            for j in range(n):
                diff = _wrapped_diff(xk - w[j * d + k], period)
                out[j] += diff * diff
        else:
            for j in range(n):
                diff = xk - w[j * d + k]
                out[j] += diff * diff


SHORT_UPDATE = 8  # shorter runs of the classic update go node by node
LONG_RUN = 256  # windows of whole rows with at least this many nodes a plane: block-wise scan


@njit(cache=True, error_model="numpy")
def _block_min(out, n):
    """Smallest of out[:n]: eight independent running minima, so the loop vectorises (a single
    running minimum is a serial dependency chain). Exact: a minimum does not round."""
    a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = np.inf
    j = 0
    while j + 8 <= n:
        v0, v1, v2, v3 = out[j], out[j + 1], out[j + 2], out[j + 3]
        v4, v5, v6, v7 = out[j + 4], out[j + 5], out[j + 6], out[j + 7]
        a0 = v0 if v0 < a0 else a0
        a1 = v1 if v1 < a1 else a1
        a2 = v2 if v2 < a2 else a2
        a3 = v3 if v3 < a3 else a3
        a4 = v4 if v4 < a4 else a4
        a5 = v5 if v5 < a5 else a5
        a6 = v6 if v6 < a6 else a6
        a7 = v7 if v7 < a7 else a7
        j += 8
    a0 = min(min(min(a0, a1), min(a2, a3)), min(min(a4, a5), min(a6, a7)))
    while j < n:
        a0 = out[j] if out[j] < a0 else a0
        j += 1
    return a0


@njit(cache=True, error_model="numpy", inline="always")
def _scan_run(flat, d, i0, n, x, periods, dists, best, best_dist):
    """Fold nodes i0 .. i0 + n - 1 (in that order) into the running (best, best_dist) minimum,
    a block of len(dists) nodes at a time: distances, their minimum, and only when it beats the
    best the first node reaching it (so ties keep the earliest node, as a node-by-node scan)."""
    size = dists.shape[0]
    s = 0
    while s < n:
        m = min(size, n - s)
        _run_dists(flat, d, i0 + s, m, x, periods, dists)
        low = _block_min(dists, m)
        if low < best_dist:
            for j in range(m):
                if dists[j] == low:
                    best, best_dist = i0 + s + j, low
                    break
        s += m
    return best, best_dist


@njit(cache=True, error_model="numpy")
def find_winner(weights, x, grid, origin, window, periods, dists):
    """Index of the node nearest to x (squared Euclidean, periodic components wrapped) among the
    nodes of the window [origin, origin + window) (wrapping on wrapped axes). Ties: first node in
    scan order. `dists` is scratch space of at least grid[2] float64."""
    return _find_winner_flat(weights, weights.reshape(-1), x, grid, origin, window, periods,
                             dists)


@njit(cache=True, error_model="numpy", inline="always")
def _find_winner_flat(weights, flat, x, grid, origin, window, periods, dists):
    """`find_winner`, given also the weights as one C-order vector `flat` (the same memory)."""
    # np.int64 rather than bare literals for values passed on to other kernels: a literal
    # argument (-1, 0) makes Numba compile the callee once more for the literal's own type
    best = np.int64(-1)
    best_dist = np.inf
    d = weights.shape[1]
    if window[2] == grid[2] and origin[2] == 0 and window[1] * grid[2] >= LONG_RUN:
        # whole rows from coordinate 0: a plane's rows are one or two long runs of consecutive
        # nodes (split where axis 1 wraps), scanned block-wise
        for o0 in range(window[0]):
            a0 = _wrap_index(origin[0] + o0, grid[0])
            start = np.int64(0)
            while start < window[1]:
                a1, stop = _run(origin[1], start, window[1] - 1, grid[1])
                i0 = (a0 * grid[1] + a1) * grid[2]
                best, best_dist = _scan_run(flat, d, i0, (stop - start + 1) * grid[2], x,
                                            periods, dists, best, best_dist)
                start = stop + 1
        return best
    for o0 in range(window[0]):
        a0 = _wrap_index(origin[0] + o0, grid[0])
        for o1 in range(window[1]):
            base = (a0 * grid[1] + _wrap_index(origin[1] + o1, grid[1])) * grid[2]
            # the row as one or two contiguous runs of node indices
            start = np.int64(0)
            while start < window[2]:
                a2, stop = _run(origin[2], start, window[2] - 1, grid[2])
                i0 = base + a2
                _run_dists(flat, d, i0, stop - start + 1, x, periods, dists)
                for j in range(stop - start + 1):
                    if dists[j] < best_dist:
                        best_dist = dists[j]
                        best = i0 + j
                start = stop + 1
    return best


# ----------------------------------------------------------------------------- inverse map

@njit(cache=True, error_model="numpy")
def _cell_index(value, origin, inv_size, cells):
    """Cell of a data value along one bucket axis (clamped: the end cells reach infinity)."""
    return np.int64(min(max((value - origin) * inv_size, 0.0), cells - 1.0))


@njit(cache=True, error_model="numpy")
def _bucket_of(weights, i, comps, shape, origin, inv_size):
    """The cell node i's model vector falls in."""
    cell = 0
    for a in range(3):
        c = 0
        if comps[a] >= 0:
            c = _cell_index(weights[i, comps[a]], origin[a], inv_size[a], shape[a])
        cell = cell * shape[a] + c
    return cell


@njit(cache=True, error_model="numpy")
def _bucket_link(head, links, i, cell):
    first = head[cell]
    links[0, i] = first
    links[1, i] = -1
    if first >= 0:
        links[1, first] = i
    head[cell] = i
    links[2, i] = cell


@njit(cache=True, error_model="numpy")
def _bucket_move(head, links, i, cell):
    """Refile node i under `cell` if it is not there already."""
    old = links[2, i]
    if cell == old:
        return
    nxt = links[0, i]
    prv = links[1, i]
    if prv >= 0:
        links[0, prv] = nxt
    else:
        head[old] = nxt
    if nxt >= 0:
        links[1, nxt] = prv
    _bucket_link(head, links, i, cell)


@njit(cache=True, error_model="numpy")
def fill_buckets(weights, b):
    """File every node under its cell (b's head and links are overwritten)."""
    b.head[:] = -1
    for i in range(weights.shape[0]):
        cell = _bucket_of(weights, i, b.comps, b.shape, b.origin, b.inv_size)
        _bucket_link(b.head, b.links, i, cell)


@njit(cache=True, error_model="numpy")
def _scan_rank(i, grid, origin, window):
    """Position of node i in the window's scan order, -1 if i is outside the window."""
    a0 = i // (grid[1] * grid[2])
    a1 = (i // grid[2]) % grid[1]
    a2 = i % grid[2]
    coords = (a0, a1, a2)
    rank = 0
    for a in range(3):
        r = coords[a] - origin[a]
        if r < 0:
            r += grid[a]  # only reachable in range on wrapped axes (origin < grid elsewhere)
        if r >= window[a]:
            return -1
        rank = rank * window[a] + r
    return rank


@njit(cache=True, error_model="numpy")
def _axis_cell(x, comp, corner, inv_size, cells):
    """Cell of x along one bucket axis (0 on an unused axis)."""
    if comp < 0:
        return 0
    return _cell_index(x[comp], corner, inv_size, cells)


@njit(cache=True, error_model="numpy")
def _axis_gap(x, comp, c, cells, corner, size):
    """Squared distance from x to cell c along one bucket axis (the end cells reach infinity)."""
    if comp < 0:
        return 0.0
    xa = x[comp]
    if c > 0:
        e = corner + c * size - xa
        if e > 0.0:
            return e * e
    if c < cells - 1:
        e = xa - corner - (c + 1) * size
        if e > 0.0:
            return e * e
    return 0.0


@njit(cache=True, error_model="numpy")
def _ring_bound(x, comp, c, r, cells, corner, size):
    """Nearest that cells r steps from cell c along one axis can be to x (inf: none exist)."""
    if comp < 0:
        return np.inf
    if r == 0:
        return 0.0
    bound = np.inf
    if c + r <= cells - 1:
        bound = corner + (c + r) * size - x[comp]
    if c - r >= 0:
        bound = min(bound, x[comp] - corner - (c - r + 1) * size)
    return bound


@njit(cache=True, error_model="numpy", inline="always")
def _scan_cell(weights, x, cell, head, links, grid, origin, window, whole, periods, best,
               best_dist, best_rank):
    """Fold the nodes filed under `cell` into the running (distance, scan rank) minimum.

    A whole-map window (`whole`) contains every node, so the rank (integer divisions) is only
    needed to break ties; -1 stands for "not computed yet"."""
    i = head[cell]
    while i >= 0:
        dist = _node_dist(weights, i, x, periods)
        if dist < best_dist:
            rank = -1 if whole else _scan_rank(i, grid, origin, window)
            if whole or rank >= 0:
                best, best_dist, best_rank = i, dist, rank
        elif dist == best_dist:
            rank = _scan_rank(i, grid, origin, window)
            if best_rank < 0:
                best_rank = _scan_rank(best, grid, origin, window)
            if rank >= 0 and rank < best_rank:
                best, best_rank = i, rank
        i = links[0, i]
    return best, best_dist, best_rank


@njit(cache=True, error_model="numpy", inline="always")
def find_winner_buckets(weights, x, grid, origin, window, periods, b):
    """`find_winner` through the inverse map b: the same node (ties: first in scan order).

    Rings of cells at Chebyshev distance r = 0, 1, ... around x's cell are searched until no
    cell of the next ring can hold a node as near as the best; cells farther than the best are
    skipped without reading them.
    """
    comps, shape, corner, size, inv = b.comps, b.shape, b.origin, b.size, b.inv_size
    head, links = b.head, b.links
    k0, k1, k2 = comps[0], comps[1], comps[2]
    s0, s1, s2 = shape[0], shape[1], shape[2]
    cx0 = _axis_cell(x, k0, corner[0], inv[0], s0)
    cx1 = _axis_cell(x, k1, corner[1], inv[1], s1)
    cx2 = _axis_cell(x, k2, corner[2], inv[2], s2)
    margin = 1e-9 * (size[0] + size[1] + size[2])  # rounding in cell assignment and distances
    whole = window[0] == grid[0] and window[1] == grid[1] and window[2] == grid[2]
    best, best_dist, best_rank = np.int64(-1), np.inf, np.int64(-1)  # see _find_winner_flat
    r = np.int64(0)
    while True:
        bound = min(_ring_bound(x, k0, cx0, r, s0, corner[0], size[0]),
                    _ring_bound(x, k1, cx1, r, s1, corner[1], size[1]),
                    _ring_bound(x, k2, cx2, r, s2, corner[2], size[2]))
        if bound == np.inf:
            break  # every cell visited
        bound = max(bound - margin, 0.0)
        if bound * bound > best_dist:
            break
        for c0 in range(max(cx0 - r, 0), min(cx0 + r, s0 - 1) + 1):
            g0 = _axis_gap(x, k0, c0, s0, corner[0], size[0])
            face0 = abs(c0 - cx0) == r  # r == 0: the single cell cx, a "face" too
            for c1 in range(max(cx1 - r, 0), min(cx1 + r, s1 - 1) + 1):
                g01 = g0 + _axis_gap(x, k1, c1, s1, corner[1], size[1])
                base = (c0 * s1 + c1) * s2
                # the whole row of the ring's box, or only its two end cells along axis 2
                step = 1 if face0 or abs(c1 - cx1) == r else 2 * r
                for c2 in range(cx2 - r, cx2 + r + 1, step):
                    if c2 < 0 or c2 >= s2:
                        continue
                    gap = max(np.sqrt(g01 + _axis_gap(x, k2, c2, s2, corner[2], size[2]))
                              - margin, 0.0)
                    if gap * gap > best_dist:
                        continue  # no node of this cell can win (or tie)
                    best, best_dist, best_rank = _scan_cell(
                        weights, x, base + c2, head, links, grid, origin, window, whole,
                        periods, best, best_dist, best_rank)
        r += 1
    return best


# ----------------------------------------------------------------------------- the update

@njit(cache=True, error_model="numpy")
def _update_run(flat, d, i0, n, x, alpha, row_q, tables, t0):
    """The separable path's update of nodes i0 .. i0 + n - 1 for the paper's target x (no
    coherent target, range kernel, periodic component or bounds): m += alpha h (x - m) with
    h_k = row_q[k] tables[k, 2, t0 + j], rounded exactly as the general loop rounds it. Indexed
    from 0 in a slice of the flat weights so the loop vectorises across nodes."""
    w = flat[i0 * d:(i0 + n) * d]
    if d == 2:
        x0, x1, q0, q1 = x[0], x[1], row_q[0], row_q[1]
        f0 = tables[0, 2, t0:t0 + n]
        f1 = tables[1, 2, t0:t0 + n]
        for j in range(n):
            m0 = w[2 * j]
            m1 = w[2 * j + 1]
            w[2 * j] = m0 + (alpha * (q0 * f0[j])) * (x0 - m0)
            w[2 * j + 1] = m1 + (alpha * (q1 * f1[j])) * (x1 - m1)
        return
    if d == 3:
        x0, x1, x2, q0, q1, q2 = x[0], x[1], x[2], row_q[0], row_q[1], row_q[2]
        f0 = tables[0, 2, t0:t0 + n]
        f1 = tables[1, 2, t0:t0 + n]
        f2 = tables[2, 2, t0:t0 + n]
        for j in range(n):
            m0 = w[3 * j]
            m1 = w[3 * j + 1]
            m2 = w[3 * j + 2]
            w[3 * j] = m0 + (alpha * (q0 * f0[j])) * (x0 - m0)
            w[3 * j + 1] = m1 + (alpha * (q1 * f1[j])) * (x1 - m1)
            w[3 * j + 2] = m2 + (alpha * (q2 * f2[j])) * (x2 - m2)
        return
    for j in range(n):
        for k in range(d):
            m = w[j * d + k]
            w[j * d + k] = m + (alpha * (row_q[k] * tables[k, 2, t0 + j])) * (x[k] - m)


@njit(cache=True, error_model="numpy")
def _refile_run(flat, d, i0, n, b, cells):
    """Refile nodes i0 .. i0 + n - 1 in the inverse map b (as `_bucket_of` and `_bucket_move`
    node by node, in the same order): their cells computed axis by axis into the int64 scratch
    `cells` in loops that vectorise, then only the nodes whose cell changed are moved."""
    w = flat[i0 * d:(i0 + n) * d]
    for j in range(n):
        cells[j] = 0
    for a in range(3):
        comp = b.comps[a]
        if comp < 0:
            continue  # an unused axis: one cell, index 0
        count = b.shape[a]
        corner, inv, top = b.origin[a], b.inv_size[a], count - 1.0
        for j in range(n):
            c = np.int64(min(max((w[j * d + comp] - corner) * inv, 0.0), top))
            cells[j] = cells[j] * count + c
    links = b.links
    for j in range(n):
        if cells[j] != links[2, i0 + j]:
            _bucket_move(b.head, links, i0 + j, cells[j])


@njit(cache=True, error_model="numpy")
def _row_hmax(row_q, tables, j):
    """Largest component weight at axis-2 table position j of a row (separable path)."""
    hmax = 0.0
    for k in range(row_q.shape[0]):
        hmax = max(hmax, row_q[k] * tables[k, 2, j])
    return hmax


@njit(cache=True, error_model="numpy")
def _axis_range(c, radius, g, wrap):
    """Offsets [lo, hi] of the update box along one axis around winner coordinate c."""
    if wrap:
        if 2 * radius + 1 >= g:
            lo = -(g // 2)
            return lo, lo + g - 1
        return -radius, radius
    return max(-radius, -c), min(radius, g - 1 - c)


@njit(cache=True, error_model="numpy", inline="always")
def _update_box(c, sigma, p, frame, tables, bounds):
    """The update's box around winner c, as offsets bounds[0] <= D <= bounds[1], and on the
    separable path the 1D factors tables[k, a, D_a - bounds[0, a]] = exp(-A_k,aa D_a^2 / 2
    sigma^2). Returns the winner's grid coordinates."""
    grid = p.grid
    quad = p.quad[frame]
    c0 = c // (grid[1] * grid[2])
    c1 = (c // grid[2]) % grid[1]
    c2 = c % grid[2]
    coords = (c0, c1, c2)
    inv2s2 = 1.0 / (2.0 * sigma * sigma)
    lo = bounds[0]
    hi = bounds[1]
    for a in range(3):
        e = p.extent[frame, a] * sigma
        radius = grid[a] if not np.isfinite(e) or e >= grid[a] else np.int64(np.ceil(e))
        lo[a], hi[a] = _axis_range(coords[a], radius, grid[a], p.wrap[a])

    if p.separable:
        for k in range(quad.shape[0]):
            for a in range(3):
                caa = quad[k, a, a]
                if k > 0 and caa == quad[k - 1, a, a]:
                    # same factor as the previous component (e.g. isotropic maps); copied in a
                    # loop: an array-to-slice assignment compiles Numba's shape-mismatch error
                    # message (string formatting), seconds of a first run's compile
                    for j in range(hi[a] - lo[a] + 1):
                        tables[k, a, j] = tables[k - 1, a, j]
                    continue
                for off in range(lo[a], hi[a] + 1):
                    tables[k, a, off - lo[a]] = np.exp(-caa * off * off * inv2s2)
    return c0, c1, c2


@njit(cache=True, error_model="numpy", inline="always")
def update_neighbourhood(weights, c, x, alpha, sigma, p, tables, scratch, bounds, b, refile):
    """m_i += h_ci (target_i - m_i) for the nodes around winner c (one OS-Map step, eq. 1-4).

    h_ci is diagonal: component k uses exp(-D^T A_k D / (2 sigma^2)), times the optional range
    kernel. `tables` (d, 3, L) holds the separable path's 1D factors; `scratch` (5, d) float64
    and `bounds` (2, 3) int64 are work space. With `refile`, moved nodes are refiled in the
    inverse map b.
    """
    grid = p.grid
    d = weights.shape[1]
    frame = c if p.quad.shape[0] > 1 else 0
    quad = p.quad[frame]
    c0, c1, c2 = _update_box(c, sigma, p, frame, tables, bounds)
    inv2s2 = 1.0 / (2.0 * sigma * sigma)
    lo = bounds[0]
    hi = bounds[1]

    jac, periods, t_lo, t_hi, cutoff = p.jac, p.periods, p.lo, p.hi, p.cutoff
    separable = p.separable
    comps, bshape, corner, inv_size, head, links = (b.comps, b.shape, b.origin, b.inv_size,
                                                     b.head, b.links)
    use_range = p.range_a > 0.0 or p.range_b > 0.0
    tau = p.range_a * sigma + p.range_b
    inv2t2 = 1.0 / (2.0 * tau * tau) if use_range else 0.0
    periodic = False
    bounded = False
    for k in range(d):
        periodic = periodic or periods[k] > 0.0
        bounded = bounded or t_lo[k] > -np.inf or t_hi[k] < np.inf
    target, h, row_t, row_q, row_b = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]

    for o0 in range(lo[0], hi[0] + 1):
        a0 = _wrap_index(c0 + o0, grid[0])
        for o1 in range(lo[1], hi[1] + 1):
            base = (a0 * grid[1] + _wrap_index(c1 + o1, grid[1])) * grid[2]
            # per row: targets, and the neighbourhood exponent as a polynomial in o2
            row_max = 0.0
            for k in range(d):
                row_t[k] = x[k] + jac[k, 0] * o0 + jac[k, 1] * o1
                if separable:
                    row_q[k] = tables[k, 0, o0 - lo[0]] * tables[k, 1, o1 - lo[1]]
                    row_max = max(row_max, row_q[k])
                else:
                    row_q[k] = (quad[k, 0, 0] * o0 * o0 + 2.0 * quad[k, 0, 1] * o0 * o1
                                + quad[k, 1, 1] * o1 * o1) * inv2s2
                    row_b[k] = 2.0 * (quad[k, 0, 2] * o0 + quad[k, 1, 2] * o1) * inv2s2
                    row_max = 1.0
            if row_max < cutoff:
                continue  # axis-2 factors are <= 1: the whole row is below the cutoff
            first, last = lo[2], hi[2]
            if separable:
                # the row's weights fall off symmetrically from o2 = 0: trim the ends below the
                # cutoff here instead of testing every node (same products, same decisions)
                while first <= last and _row_hmax(row_q, tables, first - lo[2]) < cutoff:
                    first += 1
                while last >= first and _row_hmax(row_q, tables, last - lo[2]) < cutoff:
                    last -= 1
            # the row's nodes as one or two contiguous runs of indices (i = shift + o2)
            start = first
            while start <= last:
                a2, stop = _run(c2, start, last, grid[2])
                shift = base + a2 - start
                for o2 in range(start, stop + 1):
                    i = shift + o2
                    inside = True
                    for k in range(d):
                        t = row_t[k] + jac[k, 2] * o2
                        if bounded and (t < t_lo[k] or t > t_hi[k]):
                            inside = False
                        target[k] = t
                    if not inside:
                        continue

                    if separable:
                        for k in range(d):
                            h[k] = row_q[k] * tables[k, 2, o2 - lo[2]]
                    else:
                        hmax = 0.0
                        for k in range(d):
                            w = np.exp(-(row_q[k] + (row_b[k] + quad[k, 2, 2] * o2 * inv2s2) * o2))
                            h[k] = w
                            hmax = max(hmax, w)
                        if hmax < cutoff:
                            continue

                    r = alpha
                    if use_range:
                        r *= np.exp(-_node_dist(weights, i, target, periods) * inv2t2)

                    for k in range(d):
                        wik = weights[i, k]
                        if periodic:
                            m = wik + r * h[k] * _wrapped_diff(target[k] - wik, periods[k])
                            if periods[k] > 0.0:
                                m -= periods[k] * np.floor(m / periods[k])
                        else:
                            m = wik + r * h[k] * (target[k] - wik)
                        weights[i, k] = m
                    if refile:
                        cell = _bucket_of(weights, i, comps, bshape, corner, inv_size)
                        _bucket_move(head, links, i, cell)
                start = stop + 1


@njit(cache=True, error_model="numpy")
def update_classic(weights, flat, c, x, alpha, sigma, p, tables, scratch, bounds, cells, b,
                   refile):
    """`update_neighbourhood` for the separable path with the paper's target x and nothing else
    (no coherent target, range kernel, periodic component or bounds; `is_classic`): the same
    nodes, the same arithmetic and rounding, the same weights, but each row's nodes updated in a
    loop that vectorises. `flat` is `weights.reshape(-1)`; `cells` (grid[2],) int64 is work
    space for refiling."""
    grid = p.grid
    d = weights.shape[1]
    c0, c1, c2 = _update_box(c, sigma, p, 0, tables, bounds)
    lo = bounds[0]
    hi = bounds[1]
    cutoff = p.cutoff
    row_q = scratch[3]
    for o0 in range(lo[0], hi[0] + 1):
        a0 = _wrap_index(c0 + o0, grid[0])
        for o1 in range(lo[1], hi[1] + 1):
            base = (a0 * grid[1] + _wrap_index(c1 + o1, grid[1])) * grid[2]
            row_max = 0.0
            for k in range(d):
                row_q[k] = tables[k, 0, o0 - lo[0]] * tables[k, 1, o1 - lo[1]]
                row_max = max(row_max, row_q[k])
            if row_max < cutoff:
                continue
            first, last = lo[2], hi[2]
            while first <= last and _row_hmax(row_q, tables, first - lo[2]) < cutoff:
                first += 1
            while last >= first and _row_hmax(row_q, tables, last - lo[2]) < cutoff:
                last -= 1
            start = first
            while start <= last:
                a2, stop = _run(c2, start, last, grid[2])
                i0 = base + a2
                n = stop - start + 1
                if n >= SHORT_UPDATE:
                    _update_run(flat, d, i0, n, x, alpha, row_q, tables, start - lo[2])
                    if refile:
                        _refile_run(flat, d, i0, n, b, cells)
                else:  # node by node: no slicing set-up
                    for j in range(n):
                        i = i0 + j
                        t2 = start - lo[2] + j
                        for k in range(d):
                            m = weights[i, k]
                            weights[i, k] = m + (alpha * (row_q[k] * tables[k, 2, t2])) * (x[k] - m)
                        if refile:
                            _bucket_move(b.head, b.links, i,
                                         _bucket_of(weights, i, b.comps, b.shape, b.origin,
                                                    b.inv_size))
                start = stop + 1


def is_classic(p) -> bool:
    """The classic SOM update (separable, target x, nothing else): `update_classic` applies.
    Plain Python, decided once per `train_steps` call, so that only the kernel a run uses is
    compiled."""
    classic = bool(p.separable) and p.range_a == 0.0 and p.range_b == 0.0 and p.quad.shape[0] == 1
    return bool(classic and np.all(p.periods == 0.0) and np.all(p.lo == -np.inf)
                and np.all(p.hi == np.inf) and np.all(p.jac == 0.0))


@njit(cache=True, error_model="numpy", nogil=True)
def _train(weights, inputs, origins, alphas, sigmas, p, b, bucket_from, classic):
    """`train_steps`, with `update_classic` when `classic` is True and `update_neighbourhood`
    when it is None. A None argument is a compile-time constant: Numba prunes the classic branch
    before typing it, so the general specialisation compiles neither `update_classic` nor its
    helpers."""
    d = weights.shape[1]
    max_len = 2 * max(p.grid[0], p.grid[1], p.grid[2]) + 1
    tables = np.empty((d, 3, max_len))
    scratch = np.empty((5, d))
    dists = np.empty(max(p.grid[2], 256))
    bounds = np.empty((2, 3), np.int64)
    cells = np.empty(p.grid[2], np.int64)
    flat = weights.reshape(-1)  # once: a reshape per step costs as much as a small window scan
    winners = np.empty(inputs.shape[0], np.int64)
    use = False
    for t in range(inputs.shape[0]):
        if b.active and t == bucket_from:
            fill_buckets(weights, b)
            use = True
        x = inputs[t]
        if use:
            c = find_winner_buckets(weights, x, p.grid, origins[t], p.window, p.periods, b)
        else:
            c = _find_winner_flat(weights, flat, x, p.grid, origins[t], p.window, p.periods,
                                  dists)
        winners[t] = c
        if classic is None:
            update_neighbourhood(weights, c, x, alphas[t], sigmas[t], p, tables, scratch, bounds,
                                 b, use)
        else:
            update_classic(weights, flat, c, x, alphas[t], sigmas[t], p, tables, scratch, bounds,
                           cells, b, use)
    return winners


def train_steps(weights, inputs, origins, alphas, sigmas, p, b, bucket_from):
    """Run len(inputs) OS-Map steps in place: winner in the window at origins[t], then update.

    weights float32[N, d]; inputs float64[T, d]; origins int64[T, 3]; alphas, sigmas float64[T].
    Steps t < bucket_from scan the window; from step bucket_from on (when b is active) the
    inverse map b is filled and searched instead, which finds the same winners: the switch
    only changes the speed (scanning is cheaper while the updates are wide and the map moves a
    lot, the inverse map once the radius has shrunk). Returns the winners (int64[T]).

    The update is chosen here, in Python: the compiled step loop `_train` is called with
    classic=True (Kohonen's update, `is_classic`) or classic=None (the general update), two
    specialisations sharing every helper; a run compiles only the one it calls (synthesis never
    takes the classic path).
    """
    classic = True if is_classic(p) else None
    return _train(weights, inputs, origins, alphas, sigmas, p, b, bucket_from, classic)

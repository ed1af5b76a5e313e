"""Kernels of the structure-first solid method: exact Euclidean distance transforms, connected
components, convex-hull areas of pixel sets, and the marking of particles in a volume.

Every kernel is deterministic and thread-count independent: parallel loops write disjoint
outputs and the union-find labelling numbers components in raster order of their first pixel.
"""

import numpy as np
from numba import njit, prange

from osmap_kernels.common import EIGHT_NEIGHBOURS, find_root, neighbour

BIG = 1.0e20


@njit(cache=True, inline="always")
def _envelope(f, n, v, z, out):
    """Felzenszwalb-Huttenlocher lower envelope of the parabolas (i, f[i]), sampled at 0..n-1."""
    k = 0
    v[0] = 0
    z[0] = -BIG
    z[1] = BIG
    for q in range(1, n):
        if f[q] >= BIG:
            continue
        if f[v[k]] >= BIG:
            v[k] = q
            continue
        s = ((f[q] + q * q) - (f[v[k]] + v[k] * v[k])) / (2.0 * q - 2.0 * v[k])
        while s <= z[k]:
            k -= 1
            s = ((f[q] + q * q) - (f[v[k]] + v[k] * v[k])) / (2.0 * q - 2.0 * v[k])
        k += 1
        v[k] = q
        z[k] = s
        z[k + 1] = BIG
    if f[v[0]] >= BIG:
        for q in range(n):
            out[q] = BIG
        return
    k = 0
    for q in range(n):
        while z[k + 1] < q:
            k += 1
        d = q - v[k]
        out[q] = d * d + f[v[k]]


@njit(cache=True, parallel=True)
def squared_distance_rows(rows, wrap):
    """Every row of rows (M, n): the squared 1D distance transform (rows hold 0 at features,
    BIG or a squared distance elsewhere: the passes of an N-D transform chain). wrap: each row
    is periodic (solved on three copies, the middle one kept)."""
    m, n = rows.shape
    reps = 3 if wrap else 1
    length = n * reps
    out = np.empty_like(rows)
    for i in prange(m):
        f = np.empty(length, np.float64)
        v = np.empty(length, np.int64)
        z = np.empty(length + 1, np.float64)
        d = np.empty(length, np.float64)
        for j in range(length):
            f[j] = rows[i, j % n]
        _envelope(f, length, v, z, d)
        base = n if wrap else 0
        for j in range(n):
            out[i, j] = d[base + j]
    return out


@njit(cache=True)
def _union(parent, a, b):
    ra = find_root(parent, a)
    rb = find_root(parent, b)
    if ra < rb:
        parent[rb] = ra
    elif rb < ra:
        parent[ra] = rb


@njit(cache=True)
def label_components(labels, eight, wrap):
    """Connected components of equal labels (int64[H, W]; negative: ignored). Returns int64
    [H, W] component ids 0..count-1 (-1 where ignored), numbered in raster order of each
    component's first pixel, and the count. eight: 8-connectivity; wrap: toroidal."""
    h, w = labels.shape
    parent = np.arange(h * w)
    for y in range(h):
        for x in range(w):
            lab = labels[y, x]
            if lab < 0:
                continue
            for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
                if not eight and dy == 1 and dx != 0:
                    continue
                qy, qx, inside = neighbour(y, x, dy, dx, h, w, wrap)
                if inside and labels[qy, qx] == lab:
                    _union(parent, y * w + x, qy * w + qx)
    ids = np.full((h, w), -1, np.int64)
    remap = np.full(h * w, -1, np.int64)
    count = 0
    for y in range(h):
        for x in range(w):
            if labels[y, x] < 0:
                continue
            r = find_root(parent, y * w + x)
            if remap[r] < 0:
                remap[r] = count
                count += 1
            ids[y, x] = remap[r]
    return ids, count


@njit(cache=True)
def _cross(ox, oy, ax, ay, bx, by):
    return (ax - ox) * (by - oy) - (ay - oy) * (bx - ox)


@njit(cache=True)
def hull_areas(ids, count):
    """float64[count]: the area of the convex hull of each component's pixels (unit squares:
    the hull of their corners; monotone chain per component)."""
    h, w = ids.shape
    # every pixel's corners, grouped by component (corner x, y scaled to integers)
    sizes = np.zeros(count + 1, np.int64)
    for y in range(h):
        for x in range(w):
            if ids[y, x] >= 0:
                sizes[ids[y, x] + 1] += 1
    for c in range(count):
        sizes[c + 1] += sizes[c]
    pts = np.empty((4 * sizes[count], 2), np.int64)
    fill = sizes[:count].copy()
    for y in range(h):
        for x in range(w):
            c = ids[y, x]
            if c < 0:
                continue
            j = 4 * fill[c]
            pts[j, 0], pts[j, 1] = x, y
            pts[j + 1, 0], pts[j + 1, 1] = x + 1, y
            pts[j + 2, 0], pts[j + 2, 1] = x, y + 1
            pts[j + 3, 0], pts[j + 3, 1] = x + 1, y + 1
            fill[c] += 1
    areas = np.zeros(count)
    for c in range(count):
        p = pts[4 * sizes[c]:4 * sizes[c + 1]]
        key = p[:, 0] * (2 * h + 4) + p[:, 1]
        order = np.argsort(key)
        q = p[order]
        m = q.shape[0]
        hull = np.empty((2 * m + 1, 2), np.int64)
        k = 0
        for i in range(m):
            while k >= 2 and _cross(hull[k - 2, 0], hull[k - 2, 1], hull[k - 1, 0],
                                    hull[k - 1, 1], q[i, 0], q[i, 1]) <= 0:
                k -= 1
            hull[k] = q[i]
            k += 1
        lower = k + 1
        for i in range(m - 2, -1, -1):
            while k >= lower and _cross(hull[k - 2, 0], hull[k - 2, 1], hull[k - 1, 0],
                                        hull[k - 1, 1], q[i, 0], q[i, 1]) <= 0:
                k -= 1
            hull[k] = q[i]
            k += 1
        a = 0.0
        for i in range(k - 1):
            a += hull[i, 0] * hull[i + 1, 1] - hull[i + 1, 0] * hull[i, 1]
        areas[c] = abs(a) / 2.0
    return areas


@njit(cache=True, inline="always")
def _wrapped(d, n, wrap):
    if wrap:
        if d > n / 2:
            return d - n
        if d < -n / 2:
            return d + n
    return d


@njit(cache=True)
def _grid(centres, shape, cell):
    """A hash grid of points: (grid dims, cell sizes, heads, next) with cells of about
    `cell` voxels (at least one per dim)."""
    dims = np.empty(3, np.int64)
    sizes = np.empty(3)
    for d in range(3):
        dims[d] = max(1, int(shape[d] // cell))
        sizes[d] = shape[d] / dims[d]
    heads = np.full(dims[0] * dims[1] * dims[2], -1, np.int64)
    nxt = np.full(centres.shape[0], -1, np.int64)
    return dims, sizes, heads, nxt


@njit(cache=True, inline="always")
def _cell_of(p0, p1, p2, dims, sizes):
    c0 = min(max(int(p0 / sizes[0]), 0), dims[0] - 1)
    c1 = min(max(int(p1 / sizes[1]), 0), dims[1] - 1)
    c2 = min(max(int(p2 / sizes[2]), 0), dims[2] - 1)
    return c0, c1, c2


@njit(cache=True)
def _insert(i, p0, p1, p2, dims, sizes, heads, nxt):
    c0, c1, c2 = _cell_of(p0, p1, p2, dims, sizes)
    k = (c0 * dims[1] + c1) * dims[2] + c2
    nxt[i] = heads[k]
    heads[k] = i


@njit(cache=True, inline="always")
def _span(k, c, n, wrap):
    """Offsets -lo .. hi of a shell of radius k around cell c along a grid dim of n cells."""
    if wrap:
        return min(k, n // 2), min(k, n - 1 - n // 2)
    return min(k, c), min(k, n - 1 - c)


@njit(cache=True)
def _shell(k, c0, c1, c2, dims, wrap, out):
    """The grid cells at Chebyshev distance k from cell (c0, c1, c2), each once (a wrapped
    dimension shorter than the shell is visited once whole), written to out; returns how
    many (-1: no dimension reaches distance k any more: every cell was visited)."""
    l0, h0 = _span(k, c0, dims[0], wrap)
    l1, h1 = _span(k, c1, dims[1], wrap)
    l2, h2 = _span(k, c2, dims[2], wrap)
    if max(l0, h0, l1, h1, l2, h2) < k:
        return -1
    m = 0
    for a in range(-l0, h0 + 1):
        for b in range(-l1, h1 + 1):
            edge = abs(a) == k or abs(b) == k
            for c in range(-l2, h2 + 1):
                if not edge and abs(c) != k:
                    continue
                out[m] = (((c0 + a) % dims[0]) * dims[1] + (c1 + b) % dims[1]) * dims[2] \
                    + (c2 + c) % dims[2]
                m += 1
    return m


@njit(cache=True)
def place_spheres(shape, radii, exclusion, attempts, seed, wrap):
    """Random sequential addition: float64 (N, 3) centres (z, y, x) of the spheres in
    `radii` (placed in the given order, largest first for a dense packing), each at least
    exclusion x (r_i + r_j) from every placed one; a sphere with no free place after `attempts`
    tries goes where it overlaps least. Random numbers from a generator seeded with `seed`."""
    n = radii.shape[0]
    centres = np.zeros((n, 3))
    rmax = radii.max()
    # cells of at least a quarter of the largest reach: a wide size range (specks beside
    # stones) would otherwise make the largest spheres search thousands of tiny cells; the
    # search covers every cell within reach whatever their size, so the result is the same
    cell = max(2.0 * exclusion * np.median(radii), 0.5 * exclusion * rmax, 1.0)
    dims, sizes, heads, nxt = _grid(centres, shape, cell)
    smin = sizes.min()
    buf = np.empty(dims[0] * dims[1] * dims[2] + 1, np.int64)
    state = np.uint64(seed) * np.uint64(6364136223846793005) + np.uint64(1442695040888963407)
    for i in range(n):
        best = np.inf
        bz, by, bx = 0.0, 0.0, 0.0
        limit = exclusion * (radii[i] + rmax)
        for _ in range(attempts):
            pt = np.empty(3)
            for d in range(3):
                state = state * np.uint64(6364136223846793005) + np.uint64(1442695040888963407)
                pt[d] = (state >> np.uint64(11)) * (1.0 / 9007199254740992.0) * shape[d]
            worst = 0.0
            c0, c1, c2 = _cell_of(pt[0], pt[1], pt[2], dims, sizes)
            k = 0
            while True:
                m = _shell(k, c0, c1, c2, dims, wrap, buf)
                if m < 0:
                    break
                for t in range(m):
                    j = heads[buf[t]]
                    while j >= 0:
                        dz = _wrapped(pt[0] - centres[j, 0], shape[0], wrap)
                        dy = _wrapped(pt[1] - centres[j, 1], shape[1], wrap)
                        dx = _wrapped(pt[2] - centres[j, 2], shape[2], wrap)
                        over = exclusion * (radii[i] + radii[j]) - np.sqrt(dz * dz + dy * dy
                                                                           + dx * dx)
                        if over > worst:
                            worst = over
                        j = nxt[j]
                if k * smin > limit:
                    break
                k += 1
            if worst < best:
                best, bz, by, bx = worst, pt[0], pt[1], pt[2]
                if worst <= 0.0:
                    break
        centres[i, 0], centres[i, 1], centres[i, 2] = bz, by, bx
        _insert(i, bz, by, bx, dims, sizes, heads, nxt)
    return centres


@njit(cache=True, inline="always")
def _shape_value(i, dz, dy, dx, radius, frames, planes, bumps, bump_amp, floor):
    """Signed distance-like value of particle i at offset (dz, dy, dx) from its centre,
    positive inside (voxels): an ellipsoid (frames[i]: rotation with the inverse axis ratios
    folded in) cut by planes (planes[i, k] = unit normal, offset relative to the radius) and
    modulated by bumps (bumps[i, k] = unit direction, frequency, phase). Values certainly
    below `floor` are returned as found without the bumps and planes (cheaper)."""
    q0 = frames[i, 0, 0] * dz + frames[i, 0, 1] * dy + frames[i, 0, 2] * dx
    q1 = frames[i, 1, 0] * dz + frames[i, 1, 1] * dy + frames[i, 1, 2] * dx
    q2 = frames[i, 2, 0] * dz + frames[i, 2, 1] * dy + frames[i, 2, 2] * dx
    rho = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    top = radius * (1.0 + bump_amp * np.sqrt(bumps.shape[1])) - rho
    if top < floor:
        return top
    bump = 0.0
    if rho > 1e-9 and bump_amp > 0.0:
        for k in range(bumps.shape[1]):
            u = (bumps[i, k, 0] * q0 + bumps[i, k, 1] * q1 + bumps[i, k, 2] * q2) / rho
            bump += np.cos(bumps[i, k, 3] * u + bumps[i, k, 4])
        bump *= bump_amp / np.sqrt(bumps.shape[1])
    value = radius * (1.0 + bump) - rho
    for k in range(planes.shape[1]):
        v = planes[i, k, 3] * radius - (planes[i, k, 0] * q0 + planes[i, k, 1] * q1
                                        + planes[i, k, 2] * q2)
        if v < value:
            value = v
    return value


@njit(cache=True)
def class_grids(shape, centres, classes, reaches):
    """Hash grids of particles by size class: particles classes[k] .. classes[k + 1] - 1 (sorted
    by class) in a grid of cells about reaches[k] wide. Returns (dims (K, 3), sizes (K, 3),
    head offsets (K + 1), heads, next)."""
    count = classes.shape[0] - 1
    dims = np.empty((count, 3), np.int64)
    sizes = np.empty((count, 3))
    offsets = np.zeros(count + 1, np.int64)
    for k in range(count):
        for d in range(3):
            dims[k, d] = max(1, int(shape[d] // max(reaches[k], 1.0)))
            sizes[k, d] = shape[d] / dims[k, d]
        offsets[k + 1] = offsets[k] + dims[k, 0] * dims[k, 1] * dims[k, 2]
    heads = np.full(offsets[count], -1, np.int64)
    nxt = np.full(centres.shape[0], -1, np.int64)
    for k in range(count):
        for i in range(classes[k], classes[k + 1]):
            c0, c1, c2 = _cell_of(centres[i, 0], centres[i, 1], centres[i, 2], dims[k], sizes[k])
            cell = offsets[k] + (c0 * dims[k, 1] + c1) * dims[k, 2] + c2
            nxt[i] = heads[cell]
            heads[cell] = i
    return dims, sizes, offsets, heads, nxt


@njit(cache=True, parallel=True)
def render_particles(shape, centres, radii, extents, classes, reaches, frames, planes, bumps,
                     bump_amp, gap, wrap, owner, sdf):
    """Every voxel: the particle whose shape value (signed distance-like, positive inside) is
    highest there, and sdf = min(that value, half its lead over the runner-up less half the
    gap): overlapping particles are parted along the surface where their values are equal, a
    gap apart; elsewhere each keeps its own shape. owner = that particle where sdf > 0, else -1
    (matrix). Particles come in size classes (see class_grids); particle j is only evaluated
    within extents[j] + gap voxels of its centre (beyond, its value is taken as very low)."""
    nz, ny, nx = shape[0], shape[1], shape[2]
    dims, sizes, offsets, heads, nxt = class_grids(shape.astype(np.float64), centres, classes,
                                                   reaches)
    most = 0
    for k in range(dims.shape[0]):
        most = max(most, dims[k, 0] * dims[k, 1] * dims[k, 2])
    far = -1.0e9
    for z in prange(nz):
        buf = np.empty(most + 1, np.int64)
        for y in range(ny):
            for x in range(nx):
                p0, p1, p2 = z + 0.5, y + 0.5, x + 0.5
                s1, s2 = far, far
                i1 = -1
                for cl in range(dims.shape[0]):
                    c0, c1, c2 = _cell_of(p0, p1, p2, dims[cl], sizes[cl])
                    for k in range(2):
                        m = _shell(k, c0, c1, c2, dims[cl], wrap, buf)
                        for t in range(max(m, 0)):
                            j = heads[offsets[cl] + buf[t]]
                            while j >= 0:
                                dz = _wrapped(p0 - centres[j, 0], nz, wrap)
                                dy = _wrapped(p1 - centres[j, 1], ny, wrap)
                                dx = _wrapped(p2 - centres[j, 2], nx, wrap)
                                d2 = dz * dz + dy * dy + dx * dx
                                lim = extents[j] + gap
                                if d2 <= lim * lim:
                                    # values below the runner-up (or far outside) change nothing
                                    floor = max(s2, -gap - 1.0)
                                    v = _shape_value(j, dz, dy, dx, radii[j], frames, planes,
                                                     bumps, bump_amp, floor)
                                    if v > s1 or (v == s1 and j < i1):
                                        s2 = s1
                                        s1, i1 = v, j
                                    elif v > s2:
                                        s2 = v
                                j = nxt[j]
                if i1 < 0:
                    owner[z, y, x] = -1
                    sdf[z, y, x] = -gap
                    continue
                value = s1
                parting = 0.5 * (s1 - s2 - gap)
                if parting < value:
                    value = parting
                sdf[z, y, x] = value
                owner[z, y, x] = i1 if value > 0.0 else -1


@njit(cache=True)
def split_touching(dist, mask, dynamic, wrap):
    """Watershed of the distance map `dist` (float64 [H, W], inside `mask`) by flooding from
    the highest values down: a pixel joins the region of its already flooded 8-neighbours;
    where two regions meet, the one whose peak rises less than `dynamic` above the meeting
    level merges into the other, else the pixel is a split line. Returns bool [H, W] split
    lines (the touching-stone boundaries)."""
    h, w = dist.shape
    order = np.argsort(-dist.ravel(), kind="mergesort")
    region = np.full(h * w, -1, np.int64)
    parent = np.arange(h * w)
    peak = np.zeros(h * w)
    split = np.zeros((h, w), np.bool_)
    for idx in order:
        y = idx // w
        x = idx % w
        if not mask[y, x]:
            continue
        level = dist[y, x]
        found = -1
        for k in range(8):
            qy, qx, inside = neighbour(y, x, EIGHT_NEIGHBOURS[k, 0], EIGHT_NEIGHBOURS[k, 1], h, w,
                                       wrap)
            if not inside:
                continue
            r = region[qy * w + qx]
            if r < 0:
                continue
            r = find_root(parent, r)
            if found < 0:
                found = r
            elif r != found:
                low, high = (r, found) if peak[r] < peak[found] else (found, r)
                if peak[low] - level < dynamic:
                    parent[low] = high
                    found = high
                else:
                    split[y, x] = True
        if split[y, x]:
            continue
        if found < 0:
            region[idx] = idx
            peak[idx] = level
        else:
            region[idx] = found
    return split

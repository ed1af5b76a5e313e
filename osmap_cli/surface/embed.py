"""Geodesic initialisation of an open map: the nodes start ordered along the surface.

Why: with x and y varying along u only, the roll's map is in effect a chain of columns
on the spiral. From a random start, the large-radius phase of the schedule pulls that chain into
a near-closed ring whose opening slides around the ring while sigma is large; where it happens to
be when the radius shrinks is where the grid opens. When that is not the spiral's own gap, one
column of the grid bridges the two layers (seeds 11 and 14 of 50 in the benchmark), and on a
1.5-turn roll, whose layers overlap in angle, the smooth large-radius chain cuts across layers
every time. Starting from the surface's own unrolled coordinates removes the symmetry the
schedule had to break by luck.

How: a landmark Isomap (de Silva and Tenenbaum 2003) on a subsample of the points:
1. SUBSAMPLE points drawn with a seed derived from the fit's seed;
2. the symmetric K-nearest-neighbour graph with Euclidean edge lengths; its largest connected
   component is kept;
3. LANDMARKS landmarks by farthest-point sampling in graph (geodesic) distance, one Dijkstra run
   per landmark;
4. classical MDS of the landmarks' squared geodesic distances to 2D, and every other point placed
   by distance-based triangulation from its distances to the landmarks.
On a developable surface (the roll) this recovers the unrolled (arc length, height) rectangle up
to a rotation and reflection. Map axes are then matched to the two embedding axes (see
`geodesic_init`). Only for maps without wrapped axes: a closed surface has no 2D unrolling.
"""

from __future__ import annotations

import numpy as np
from numba import njit

SUBSAMPLE = 2000
K = 10
LANDMARKS = 40


@njit(cache=True)
def _dijkstra(indptr, indices, weights, src):
    """Graph distances from src (O(V^2) array Dijkstra: no heap, exact, deterministic)."""
    m = indptr.shape[0] - 1
    dist = np.full(m, np.inf)
    done = np.zeros(m, np.bool_)
    dist[src] = 0.0
    for _ in range(m):
        u = -1
        best = np.inf
        for i in range(m):
            if not done[i] and dist[i] < best:
                best = dist[i]
                u = i
        if u < 0:
            break
        done[u] = True
        for e in range(indptr[u], indptr[u + 1]):
            v = indices[e]
            nd = best + weights[e]
            if nd < dist[v]:
                dist[v] = nd
    return dist


def _knn_graph(pts: np.ndarray, k: int):
    """CSR (indptr, indices, weights) of the symmetric k-nearest-neighbour graph."""
    from osmap_cli.surface.geodesic import _knn

    idx, dist = _knn(pts, pts, k + 1)
    m = len(pts)
    src = np.repeat(np.arange(m), k)
    dst = idx[:, 1:].ravel()
    w = dist[:, 1:].ravel()
    a = np.concatenate([src, dst])
    b = np.concatenate([dst, src])
    ww = np.concatenate([w, w])
    keep = a != b
    a, b, ww = a[keep], b[keep], ww[keep]
    key = a * m + b
    key, first = np.unique(key, return_index=True)
    a, b, ww = key // m, key % m, ww[first]
    indptr = np.zeros(m + 1, np.int64)
    np.add.at(indptr, a + 1, 1)
    return np.cumsum(indptr), b.astype(np.int64), ww


def _components(indptr, indices) -> np.ndarray:
    m = len(indptr) - 1
    label = np.full(m, -1)
    n = 0
    for s in range(m):
        if label[s] >= 0:
            continue
        stack = [s]
        label[s] = n
        while stack:
            u = stack.pop()
            for v in indices[indptr[u]:indptr[u + 1]]:
                if label[v] < 0:
                    label[v] = n
                    stack.append(v)
        n += 1
    return label


def geodesic_embedding(points: np.ndarray, seed: int = 0, subsample: int = SUBSAMPLE,
                       k: int = K, landmarks: int = LANDMARKS):
    """(sub (m, 3) points, emb (m, 2) unrolled coordinates, largest axis first), or None when
    the graph gives no usable 2D embedding."""
    points = np.asarray(points, np.float64)
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x6E0])
    if len(points) > subsample:
        sub = points[np.sort(rng.choice(len(points), subsample, replace=False))]
    else:
        sub = points.copy()
    sub = np.ascontiguousarray(sub)
    if len(sub) < max(3 * k, 16):
        return None
    indptr, indices, w = _knn_graph(sub, k)
    label = _components(indptr, indices)
    biggest = np.argmax(np.bincount(label))
    if np.sum(label == biggest) < len(sub):
        sub = np.ascontiguousarray(sub[label == biggest])
        if len(sub) < max(3 * k, 16):
            return None
        indptr, indices, w = _knn_graph(sub, k)
    m = len(sub)
    nl = min(landmarks, m)
    # farthest-point landmarks in graph distance, starting from the point farthest from point 0
    d0 = _dijkstra(indptr, indices, w, 0)
    if not np.all(np.isfinite(d0)):
        return None
    chosen = [int(np.argmax(d0))]
    dl = [_dijkstra(indptr, indices, w, chosen[0])]
    nearest = dl[0].copy()
    while len(chosen) < nl:
        nxt = int(np.argmax(nearest))
        if nearest[nxt] <= 0:
            break
        chosen.append(nxt)
        dl.append(_dijkstra(indptr, indices, w, nxt))
        nearest = np.minimum(nearest, dl[-1])
    d2 = np.stack(dl) ** 2  # (L, m) squared geodesic distances
    lm = d2[:, chosen]
    nl = len(chosen)
    j = np.eye(nl) - 1.0 / nl
    b = -0.5 * j @ lm @ j
    vals, vecs = np.linalg.eigh(b)
    order = np.argsort(vals)[::-1][:2]
    vals, vecs = vals[order], vecs[:, order]
    if vals[1] <= 1e-12 * max(vals[0], 1e-300):
        return None
    # triangulation: y = -1/2 L# (d2_x - mean over landmarks of d2_landmark)
    pinv = vecs / np.sqrt(vals)  # (L, 2)
    emb = -0.5 * ((d2 - lm.mean(1, keepdims=True)).T @ pinv)
    # a deterministic sign: the point with the largest |coordinate| on each axis is positive
    for a in range(2):
        if emb[np.argmax(np.abs(emb[:, a])), a] < 0:
            emb[:, a] = -emb[:, a]
    return sub, emb


def _nearest(emb: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Index of the embedded point nearest to each target (2D, brute force)."""
    out = np.empty(len(targets), np.int64)
    for s in range(0, len(targets), 256):
        t = targets[s:s + 256]
        d = np.sum((t[:, None, :] - emb[None, :, :]) ** 2, axis=2)
        out[s:s + 256] = np.argmin(d, axis=1)
    return out


def _grid_targets(emb: np.ndarray, shape, u_axis: int) -> np.ndarray:
    """Node positions in the embedding: the grid spread over the embedding's 1-99 % box, map
    u (columns) along embedding axis u_axis."""
    rows, cols = shape
    lo = np.percentile(emb, 1.0, axis=0)
    hi = np.percentile(emb, 99.0, axis=0)
    i, jj = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    fu = (jj + 0.5) / cols
    fv = (i + 0.5) / rows
    v_axis = 1 - u_axis
    t = np.empty((rows, cols, 2))
    t[..., u_axis] = lo[u_axis] + fu * (hi[u_axis] - lo[u_axis])
    t[..., v_axis] = lo[v_axis] + fv * (hi[v_axis] - lo[v_axis])
    return t.reshape(-1, 2)


def along_score(grid: np.ndarray, along: list[tuple[int, str]]) -> float:
    """How badly a (rows, cols, d) grid breaks `along` [(component, 'u' | 'v')]: the variance of
    each constrained component across its direction over its total variance, summed."""
    score = 0.0
    for k, axis in along:
        c = grid[..., k]
        total = float(np.var(c)) + 1e-300
        across = np.var(c, axis=0).mean() if axis == "u" else np.var(c, axis=1).mean()
        score += float(across) / total
    return score


def geodesic_init(points: np.ndarray, shape, to_frame, along, seed: int = 0):
    """Initial model vectors (rows * cols, 3) in frame coordinates, ordered along the surface,
    or None when no embedding could be made.

    `along` [(component, 'u' | 'v')] are the components the orientation ties to one map axis;
    of the two ways to lay the grid on the embedding (its longer axis along u or along v), the
    one that keeps those components most nearly constant across their direction is used; with
    none, the embedding's longer axis goes along the map's longer side (u on a tie).
    """
    got = geodesic_embedding(points, seed)
    if got is None:
        return None
    sub, emb = got
    rows, cols = shape
    best = None
    for u_axis in (0, 1):
        init = to_frame(sub[_nearest(emb, _grid_targets(emb, shape, u_axis))])
        if along:
            score = along_score(init.reshape(rows, cols, -1), along)
        else:
            score = float(u_axis != (0 if cols >= rows else 1))
        if best is None or score < best[0]:
            best = (score, init)
    return best[1]

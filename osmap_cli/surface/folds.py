"""Fold detection without ground truth: is a fitted grid folded or bridging?

Only the grid and the input points are used, so it works on any point cloud. Three signals:
- gap_edges: the fraction of grid edges (wrap edges included) with a point farther than TAU from
  every sample, testing the two nodes and GAP_SAMPLES - 2 evenly spaced interior points. An edge
  that jumps between the layers of a roll, or across the hole of a torus, crosses empty space;
  an edge that follows the surface stays within the sample spacing of it;
- off_surface_nodes: the fraction of nodes themselves farther than TAU from every sample: the
  fit-error outliers (a node left in the gap between two layers);
- reversed_quads: the fraction of quads whose normal points against the normal of an
  edge-adjacent quad (cosine below REVERSED_COS): where the grid folds back over itself on the
  surface, without any edge leaving it.
TAU = max(TAU_EDGE x the median grid edge, TAU_SPACING x the median nearest-neighbour distance of
the samples): one edge, or a few sample spacings on sparse clouds. Half an edge was tried first:
on the roll with a 4x density ramp the end column on the sparse, tightly curved inner turn sits
0.2 off the samples and was flagged in every fit (a bridge is 1.5 to 3 away, two to four edges).
The grid is `folded` when any edge or quad is flagged. The samples are a deterministic subsample
of at most SAMPLE points.
"""

from __future__ import annotations

import numpy as np

SAMPLE = 20000
SPACING_QUERIES = 2000
GAP_SAMPLES = 9
TAU_EDGE = 1.0
TAU_SPACING = 4.0
REVERSED_COS = -0.5


def _quad_normals(nodes: np.ndarray, quads: np.ndarray) -> np.ndarray:
    a, b, c, d = (nodes[quads[:, k]] for k in range(4))
    return np.cross(c - a, d - b)


def _quad_neighbours(rows: int, cols: int, wrap) -> np.ndarray:
    """(P, 2) index pairs of edge-adjacent quads, in the order of metrics.grid_quads."""
    qr = rows if wrap[0] and rows > 2 else rows - 1
    qc = cols if wrap[1] and cols > 2 else cols - 1
    idx = np.arange(qr * qc).reshape(qr, qc)
    pairs = []
    if qc > 1:
        right = np.roll(idx, -1, axis=1) if wrap[1] and cols > 2 else idx[:, 1:]
        left = idx if wrap[1] and cols > 2 else idx[:, :-1]
        pairs.append(np.stack([left.ravel(), right.ravel()], 1))
    if qr > 1:
        down = np.roll(idx, -1, axis=0) if wrap[0] and rows > 2 else idx[1:, :]
        up = idx if wrap[0] and rows > 2 else idx[:-1, :]
        pairs.append(np.stack([up.ravel(), down.ravel()], 1))
    return np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)


def fold_check(grid_xyz: np.ndarray, wrap, points: np.ndarray, seed: int = 0) -> dict:
    """The fold signals of a (rows, cols, 3) grid fitted to `points` (see the module doc)."""
    from osmap_cli.surface.geodesic import _knn
    from osmap_cli.surface.metrics import grid_edges, grid_quads

    rows, cols = grid_xyz.shape[:2]
    nodes = np.ascontiguousarray(grid_xyz.reshape(-1, 3), np.float64)
    pts = np.asarray(points, np.float64)
    if len(pts) > SAMPLE:
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0xF01D])
        pts = pts[np.sort(rng.choice(len(pts), SAMPLE, replace=False))]
    pts = np.ascontiguousarray(pts)
    edges = grid_edges(rows, cols, wrap)
    a, b = nodes[edges[:, 0]], nodes[edges[:, 1]]
    straight = np.linalg.norm(b - a, axis=1)
    step = max(1, len(pts) // SPACING_QUERIES)
    _, nn = _knn(pts, np.ascontiguousarray(pts[::step]), 2)
    spacing = float(np.median(nn[:, 1]))
    tau = max(TAU_EDGE * float(np.median(straight)), TAU_SPACING * spacing)

    t = np.linspace(0.0, 1.0, GAP_SAMPLES)[1:-1]
    line = (a[:, None] + t[None, :, None] * (b - a)[:, None]).reshape(-1, 3)
    _, d_line = _knn(pts, np.ascontiguousarray(line), 1)
    _, d_node = _knn(pts, nodes, 1)
    d_node = d_node[:, 0]
    far_node = d_node > tau
    gap = (d_line[:, 0].reshape(len(edges), -1).max(1) > tau) | far_node[edges[:, 0]] \
        | far_node[edges[:, 1]]

    quads = grid_quads(rows, cols, wrap)
    normals = _quad_normals(nodes, quads)
    length = np.linalg.norm(normals, axis=1)
    ok = length > 1e-9 * max(float(np.median(length)), 1e-300)
    unit = normals / np.where(ok, length, 1.0)[:, None]
    pairs = _quad_neighbours(rows, cols, wrap)
    reversed_q = np.zeros(len(quads), bool)
    if len(pairs):
        cos = np.sum(unit[pairs[:, 0]] * unit[pairs[:, 1]], axis=1)
        bad = (cos < REVERSED_COS) & ok[pairs[:, 0]] & ok[pairs[:, 1]]
        reversed_q[pairs[bad, 0]] = True
        reversed_q[pairs[bad, 1]] = True
    out = {
        "gap_edges": float(np.mean(gap)),
        "off_surface_nodes": float(np.mean(far_node)),
        "reversed_quads": float(np.mean(reversed_q)),
        "tau": tau,
        "gap_mask": gap,
    }
    out["folded"] = bool(gap.any() or reversed_q.any())
    out["score"] = out["gap_edges"] + out["reversed_quads"] + out["off_surface_nodes"]
    return out


def describe(signals: dict) -> str:
    """'gap edges 0.0161, off-surface nodes 0.0010, reversed quads 0.0000'."""
    return (f"gap edges {signals['gap_edges']:.4f}, off-surface nodes "
            f"{signals['off_surface_nodes']:.4f}, reversed quads {signals['reversed_quads']:.4f}")

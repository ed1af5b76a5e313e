"""Quality metrics of a quad grid fitted to a surface.

Distances are in units of the ideal edge length L = sqrt(area / nodes).

- shortcut_edges: fraction of grid edges (wrap edges included) whose surface distance is over
  1.3x their straight-line length AND over 2x the median straight edge: edges that jump across
  empty space (between the layers of a roll, across the hole of a torus);
- flipped_quads:  fraction of quads whose signed area in the surface's own parameter space has the
  minority sign (zero area counts as flipped): folds;
- angle_error:    mean |corner angle - 90| in degrees over the four corners of every quad, in 3D;
- fit_error:      mean distance from the nodes to the surface, in units of L;
- windings:       (shapes with periodic parameters, wrapped map axes) the winding number of every
  grid loop around each periodic parameter; `windings_ok` says whether every loop along each
  wrapped map axis winds exactly once around one parameter and zero times around the others,
  with different axes going around different parameters.

On the built-in shapes the surface distance, parameters and distance to the surface are exact
(see shapes.py). On other inputs (point clouds, meshes) there is no parameterisation: the surface
distance is estimated from local planes through the nearest samples (geodesic.py), the fit error
is the distance to the local plane, flips and windings are not measured, and L uses
the mesh area (meshes) or the area of the fitted grid (point clouds).
"""

from __future__ import annotations

import numpy as np

from osmap_cli.surface.shapes import Shape


def grid_edges(rows: int, cols: int, wrap: tuple[bool, bool]) -> np.ndarray:
    """(E, 2) node index pairs: edges along u (within rows), then along v; wrap edges included."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    edges = []
    right = idx[:, 1:] if not wrap[1] else np.roll(idx, -1, axis=1)
    left = idx[:, :-1] if not wrap[1] else idx
    edges.append(np.stack([left.ravel(), right.ravel()], 1))
    down = idx[1:, :] if not wrap[0] else np.roll(idx, -1, axis=0)
    up = idx[:-1, :] if not wrap[0] else idx
    edges.append(np.stack([up.ravel(), down.ravel()], 1))
    if cols == 2 and wrap[1]:  # the two wrap-around edges would duplicate the inner ones
        edges[0] = edges[0][: rows]
    if rows == 2 and wrap[0]:
        edges[1] = edges[1][: cols]
    return np.concatenate(edges)


def grid_quads(rows: int, cols: int, wrap: tuple[bool, bool]) -> np.ndarray:
    """(Q, 4) node indices of each quad, corners (i,j), (i,j+1), (i+1,j+1), (i+1,j)."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    r = rows if wrap[0] and rows > 2 else rows - 1
    c = cols if wrap[1] and cols > 2 else cols - 1
    i, j = np.meshgrid(np.arange(r), np.arange(c), indexing="ij")
    i1, j1 = (i + 1) % rows, (j + 1) % cols
    return np.stack([idx[i, j], idx[i, j1], idx[i1, j1], idx[i1, j]], -1).reshape(-1, 4)


def _wrapped(d: np.ndarray, period: float) -> np.ndarray:
    return d if period <= 0 else d - period * np.floor(d / period + 0.5)


def corner_angle_error(nodes: np.ndarray, quads: np.ndarray) -> float:
    """Mean |angle - 90 deg| at the quad corners, in degrees."""
    errs = []
    for c in range(4):
        p = nodes[quads[:, c]]
        a = nodes[quads[:, (c + 1) % 4]] - p
        b = nodes[quads[:, (c + 3) % 4]] - p
        na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
        cos = np.sum(a * b, axis=1) / np.maximum(na * nb, 1e-300)
        ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        ang = np.where((na > 0) & (nb > 0), ang, 0.0)  # a collapsed corner counts as 90 deg off
        errs.append(np.abs(ang - 90.0))
    return float(np.mean(errs))


def flipped_fraction(params: np.ndarray, periods, quads: np.ndarray) -> float:
    """Fraction of quads whose signed parameter-space area has the minority sign."""
    p0 = params[quads[:, 0]]
    rel = [np.zeros_like(p0)]
    for c in range(1, 4):
        d = params[quads[:, c]] - p0
        rel.append(np.stack([_wrapped(d[:, 0], periods[0]), _wrapped(d[:, 1], periods[1])], 1))
    area = 0.0
    for c in range(4):
        a, b = rel[c], rel[(c + 1) % 4]
        area = area + a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    pos, neg = np.sum(area > 0), np.sum(area < 0)
    majority = 1.0 if pos >= neg else -1.0
    return float(np.mean(np.sign(area) != majority))


def windings(params: np.ndarray, periods, shape: tuple[int, int], wrap: tuple[bool, bool]):
    """{map axis name: (loops, n_periodic) int array} of winding numbers of the closed grid
    loops along each wrapped map axis around each periodic parameter."""
    rows, cols = shape
    p = params.reshape(rows, cols, -1)
    periodic = [k for k in range(p.shape[-1]) if periods[k] > 0]
    out = {}
    for axis, name in ((1, "u"), (0, "v")):
        if not wrap[axis]:
            continue
        w = []
        for k in periodic:
            d = _wrapped(np.roll(p[..., k], -1, axis=axis) - p[..., k], periods[k])
            w.append(np.rint(d.sum(axis=axis) / periods[k]).astype(int))
        out[name] = np.stack(w, -1) if w else np.zeros((p.shape[1 - axis], 0), int)
    return out


def windings_ok(wind: dict) -> bool:
    """Every loop of each wrapped axis winds once around one parameter (its own) and zero
    times around the others."""
    used = set()
    for w in wind.values():
        if w.shape[1] == 0:
            return False
        a = np.abs(w)
        good = None
        for k in range(w.shape[1]):
            others = np.delete(a, k, axis=1)
            if np.all(a[:, k] == 1) and np.all(others == 0):
                good = k
        if good is None or good in used:
            return False
        used.add(good)
    return True


def _winding_summary(wind: dict, names) -> dict:
    """Most common winding vector per wrapped axis, e.g. {'u': 'phi 1, theta 0'}."""
    out = {}
    for axis, w in wind.items():
        rows, counts = np.unique(w, axis=0, return_counts=True)
        best = rows[np.argmax(counts)]
        frac = counts.max() / len(w)
        out[axis] = ", ".join(f"{n} {int(v)}" for n, v in zip(names, best, strict=True)) + (
            "" if frac == 1 else f" ({100 * frac:.0f}% of loops)")
    return out


def evaluate(grid_xyz: np.ndarray, wrap: tuple[bool, bool], shape: Shape | None = None,
             points: np.ndarray | None = None, area: float | None = None) -> dict:
    """All metrics of a (rows, cols, 3) grid, against an analytic shape or sample points."""
    rows, cols = grid_xyz.shape[:2]
    nodes = grid_xyz.reshape(-1, 3).astype(np.float64)
    edges = grid_edges(rows, cols, wrap)
    quads = grid_quads(rows, cols, wrap)
    straight = np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)
    out = {}
    if shape is not None:
        area = shape.area
        params = shape.params(nodes)
        surf = shape.surface_distance(params[edges[:, 0]], params[edges[:, 1]])
        fit = shape.distance(nodes)
    else:
        from osmap_cli.surface.geodesic import SampledSurface

        if area is None:
            area = grid_area(nodes, quads)
        sampled = SampledSurface(points)
        fit = sampled.nearest_distance(nodes)
        surf = sampled.path_lengths(nodes, edges)
    unit = np.sqrt(area / (rows * cols))
    shortcut = (surf > 1.3 * straight) & (surf > 2.0 * np.median(straight))
    out["shortcut_edges"] = float(np.mean(shortcut))
    out["shortcut_mask"] = shortcut
    if shape is not None:
        out["flipped_quads"] = flipped_fraction(params, shape.periods, quads)
    out["angle_error_deg"] = corner_angle_error(nodes, quads)
    out["fit_error"] = float(np.mean(fit) / unit)
    out["edge_length"] = float(np.median(straight) / unit)
    if shape is not None and any(p > 0 for p in shape.periods) and any(wrap):
        wind = windings(params, shape.periods, (rows, cols), wrap)
        names = [n for n, p in zip(shape.param_names, shape.periods, strict=True) if p > 0]
        out["windings_ok"] = windings_ok(wind)
        out["windings"] = _winding_summary(wind, names)
    out["ideal_edge"] = float(unit)
    return out


def grid_area(nodes: np.ndarray, quads: np.ndarray) -> float:
    """Area of the grid's quads, each split into two triangles."""
    a, b, c, d = (nodes[quads[:, k]] for k in range(4))
    t1 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    t2 = np.linalg.norm(np.cross(c - a, d - a), axis=1)
    return float(0.5 * np.sum(t1 + t2))


def format_report(metrics: dict) -> list[str]:
    """One line per metric."""
    lines = [f"shortcut_edges: {metrics['shortcut_edges']:.4f}"]
    if "flipped_quads" in metrics:
        lines.append(f"flipped_quads: {metrics['flipped_quads']:.4f}")
    else:
        lines.append("flipped_quads: n/a (no parameterisation of this input)")
    lines.append(f"angle_error_deg: {metrics['angle_error_deg']:.2f}")
    lines.append(f"fit_error: {metrics['fit_error']:.4f}")
    lines.append(f"median_edge: {metrics['edge_length']:.3f}")
    if "topographic_error" in metrics:
        lines.append(f"topographic_error: {metrics['topographic_error']:.4f}")
    if "windings" in metrics:
        for axis, text in metrics["windings"].items():
            lines.append(f"winding_{axis}: {text}")
        lines.append(f"windings_ok: {'yes' if metrics['windings_ok'] else 'no'}")
    lines.append(f"ideal_edge_length: {metrics['ideal_edge']:.4g}")
    if "init" in metrics:
        lines.append(f"init: {metrics['init']}")
        lines.append(f"fits_run: {metrics['fits_run']}")
        lines.append(f"seed_used: {metrics['seed_used']}")
        lines.append(f"fold_check: {metrics['fold_check']}")
        for k in ("gap_edges", "off_surface_nodes", "reversed_quads"):
            if f"fold_{k}" in metrics:
                lines.append(f"fold_{k}: {metrics[f'fold_{k}']:.4f}")
    return lines


def topographic_error(grid_xyz: np.ndarray, wrap: tuple[bool, bool], points: np.ndarray,
                      sample: int = 4000, seed: int = 0) -> float:
    """Fraction of (up to `sample`) data points whose two nearest nodes are not grid neighbours
    (8-neighbourhood, wrapping on wrapped axes): Kohonen's topographic error. It needs no
    parameterisation, so it can pick the best of several restarts on any input."""
    rows, cols = grid_xyz.shape[:2]
    nodes = grid_xyz.reshape(-1, 3).astype(np.float64)
    pts = np.asarray(points, np.float64)
    if len(pts) > sample:
        pts = pts[np.random.default_rng(seed).choice(len(pts), sample, replace=False)]
    nn = np.sum(nodes * nodes, axis=1)
    best = np.empty((len(pts), 2), np.int64)
    for s in range(0, len(pts), 1024):
        p = pts[s:s + 1024]
        d = nn[None, :] - 2.0 * p @ nodes.T
        two = np.argpartition(d, 1, axis=1)[:, :2]
        best[s:s + 1024] = two
    ia, ja = np.divmod(best[:, 0], cols)
    ib, jb = np.divmod(best[:, 1], cols)
    di, dj = np.abs(ia - ib), np.abs(ja - jb)
    if wrap[0]:
        di = np.minimum(di, rows - di)
    if wrap[1]:
        dj = np.minimum(dj, cols - dj)
    return float(np.mean((di > 1) | (dj > 1)))

"""Preview image of a fitted grid: the 3D wireframe seen from two viewpoints side by side,
rasterised with numpy (anti-aliased by bilinear splatting of sub-pixel samples along each edge).

Left: azimuth 30 deg, elevation 25 deg; right: azimuth 120 deg, elevation 65 deg (z is up). Both use
the same orthographic scale. Edges along u are blue, edges along v orange, flagged edges (e.g.
shortcuts) red and thicker; nearer edges are drawn darker. Input samples are faint grey dots.
"""

from __future__ import annotations

import numpy as np

from osmap_cli.surface.metrics import grid_edges

VIEWS = ((30.0, 25.0), (120.0, 65.0))  # (azimuth, elevation) in degrees
U_COLOUR = np.array([0.10, 0.30, 0.85])
V_COLOUR = np.array([0.95, 0.50, 0.05])
FLAG_COLOUR = np.array([0.90, 0.05, 0.05])
POINT_COLOUR = np.array([0.55, 0.55, 0.55])


def _rotation(azimuth: float, elevation: float) -> np.ndarray:
    """Rows: screen right, screen up, towards the viewer."""
    a, e = np.radians(azimuth), np.radians(elevation)
    right = np.array([-np.sin(a), np.cos(a), 0.0])
    toward = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    up = np.cross(toward, right)
    return np.stack([right, up, toward])


def _splat(ink: np.ndarray, x: np.ndarray, y: np.ndarray, w: np.ndarray) -> None:
    """Add weights w at sub-pixel positions (x, y) with bilinear footprints."""
    h, wid = ink.shape
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = x - x0, y - y0
    for dx, dy, f in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)),
                      (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        xi, yi = x0 + dx, y0 + dy
        ok = (xi >= 0) & (xi < wid) & (yi >= 0) & (yi < h)
        np.add.at(ink, (yi[ok], xi[ok]), (w * f)[ok])


def _draw_segments(ink, p, q, weight, step=0.35):
    """Splat samples every `step` pixels along each segment p[i] -> q[i] (pixel coordinates,
    third column depth weight)."""
    length = np.linalg.norm(q[:, :2] - p[:, :2], axis=1)
    n = np.maximum(np.ceil(length / step).astype(np.int64), 1)
    seg = np.repeat(np.arange(len(p)), n + 1)
    t = np.concatenate([np.linspace(0.0, 1.0, k + 1) for k in n]) if len(n) else np.zeros(0)
    pts = p[seg] + t[:, None] * (q[seg] - p[seg])
    w = weight * pts[:, 2] * (length[seg] / (n[seg] + 1))  # ink per pixel of line ~ weight
    _splat(ink, pts[:, 0], pts[:, 1], w)


def render_preview(grid_xyz: np.ndarray, wrap: tuple[bool, bool], points=None, flagged=None,
                   size: int = 480, point_count: int = 6000, seed: int = 0) -> np.ndarray:
    """(size, 2 * size, 3) float32 RGB in [0, 1]: two views of the grid side by side.

    flagged: optional boolean per edge of metrics.grid_edges (drawn red)."""
    rows, cols = grid_xyz.shape[:2]
    nodes = grid_xyz.reshape(-1, 3).astype(np.float64)
    edges = grid_edges(rows, cols, wrap)
    n_u = rows * (cols if wrap[1] and cols > 2 else cols - 1)
    along_u = np.arange(len(edges)) < n_u
    flagged = np.zeros(len(edges), bool) if flagged is None else np.asarray(flagged, bool)
    cloud = None
    if points is not None and len(points):
        pts = np.asarray(points, np.float64)
        if len(pts) > point_count:
            pts = pts[np.random.default_rng(seed).choice(len(pts), point_count, replace=False)]
        cloud = pts
    allp = nodes if cloud is None else np.concatenate([nodes, cloud])
    centre = 0.5 * (allp.min(0) + allp.max(0))
    radius = max(float(np.max(np.linalg.norm(allp - centre, axis=1))), 1e-12)
    scale = 0.46 * size / radius
    image = np.ones((size, 2 * size, 3), np.float32)
    for v, (az, el) in enumerate(VIEWS):
        rot = _rotation(az, el)

        def to_px(p, rot=rot, v=v):
            s = (p - centre) @ rot.T
            near = 0.35 + 0.65 * (s[:, 2] / radius + 1.0) / 2.0  # 1 = nearest
            return np.stack([size / 2 + scale * s[:, 0] + v * size,
                             size / 2 - scale * s[:, 1], near], 1)

        ink = np.zeros((4, size, 2 * size))
        if cloud is not None:
            c = to_px(cloud)
            _splat(ink[3], c[:, 0], c[:, 1], 0.25 * np.ones(len(c)))
        px = to_px(nodes)
        for layer, mask, weight in ((0, along_u & ~flagged, 0.9), (1, ~along_u & ~flagged, 0.9),
                                    (2, flagged, 1.6)):
            if mask.any():
                _draw_segments(ink[layer], px[edges[mask, 0]], px[edges[mask, 1]], weight)
        # keep each view inside its own half
        ink[:, :, : v * size] = 0.0
        ink[:, :, (v + 1) * size:] = 0.0
        absorb = np.zeros((size, 2 * size, 3))
        for layer, colour in enumerate((U_COLOUR, V_COLOUR, FLAG_COLOUR, POINT_COLOUR)):
            absorb += np.minimum(ink[layer], 1.5)[..., None] * (1.0 - colour)[None, None]
        half = slice(v * size, (v + 1) * size)
        image[:, half] = np.clip(1.0 - absorb[:, half], 0.0, 1.0)
    image[:, size - 1: size + 1] = 0.75  # divider
    return image

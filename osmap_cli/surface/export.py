"""Writing the fitted grid: OBJ (quads + UVs) and PLY (quads + per-vertex u, v), atomically.

OBJ: one `v` per node (row-major: node (i, j) is vertex i * cols + j + 1), one `vt` per grid
corner with u = j / (cols - 1) and v = i / (rows - 1) on an open axis, u = j / cols on a wrapped
axis with an extra column of texture coordinates at u = 1 (so the wrap faces get a seam in UV
instead of a texture smeared backwards across the whole map); one `f` per quad, corners
(i, j), (i, j+1), (i+1, j+1), (i+1, j), wrap faces included on wrapped axes.
PLY (ascii): the same vertices with per-vertex properties u, v (no seam duplication, so wrap faces
interpolate across the seam) and the same quad faces.
"""

from __future__ import annotations

import io
import os

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.output import check_parent, write_bytes
from osmap_cli.surface.metrics import grid_quads


def check_output_path(path: str, option: str, extensions: tuple[str, ...]) -> None:
    """Fail before any work if the path cannot be written (extension, directory)."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in extensions:
        raise OsmapError(f"{option} {path}: unsupported output extension {ext or '(none)'!r} "
                         f"(use {', '.join(extensions)})")
    if os.path.isdir(path):
        raise OsmapError(f"{option} {path}: is an existing directory")
    check_parent(path, f"{option} {path}")


def grid_writer(path: str, grid_xyz: np.ndarray, wrap: tuple[bool, bool], header: str = ""):
    """write(temp) for Outputs.stage: the grid as OBJ or PLY by PATH's extension."""
    text = (ply_text if path.lower().endswith(".ply") else obj_text)(grid_xyz, wrap, header)
    return lambda temp: write_bytes(temp, text.encode("utf-8"))


def _uv_axis(n: int, wrapped: bool) -> np.ndarray:
    return np.arange(n + 1) / n if wrapped else np.arange(n) / (n - 1)


def obj_text(grid_xyz: np.ndarray, wrap: tuple[bool, bool], header: str = "") -> str:
    rows, cols = grid_xyz.shape[:2]
    out = io.StringIO()
    for line in header.splitlines():
        out.write(f"# {line}\n")
    out.write(f"# grid {cols}x{rows} (u x v), wrap u={wrap[1]} v={wrap[0]}\n")
    np.savetxt(out, grid_xyz.reshape(-1, 3), fmt="v %.7g %.7g %.7g")
    us, vs = _uv_axis(cols, wrap[1]), _uv_axis(rows, wrap[0])
    tc = np.stack(np.meshgrid(us, vs), -1).reshape(-1, 2)  # row-major over (len(vs), len(us))
    np.savetxt(out, tc, fmt="vt %.7g %.7g")
    quads = grid_quads(rows, cols, wrap)
    # texture-coordinate index of each corner: unwrapped (i, j) in the (len(vs), len(us)) table
    qi, qj = np.divmod(quads[:, 0], cols)
    ti = np.stack([qi, qi, qi + 1, qi + 1], 1)
    tj = np.stack([qj, qj + 1, qj + 1, qj], 1)
    tindex = ti * len(us) + tj
    v1, t1 = quads + 1, tindex + 1
    face = np.empty((len(quads), 8), np.int64)
    face[:, 0::2], face[:, 1::2] = v1, t1
    np.savetxt(out, face, fmt="f %d/%d %d/%d %d/%d %d/%d")
    return out.getvalue()


def ply_text(grid_xyz: np.ndarray, wrap: tuple[bool, bool], header: str = "") -> str:
    rows, cols = grid_xyz.shape[:2]
    quads = grid_quads(rows, cols, wrap)
    uu, vv = np.meshgrid(_uv_axis(cols, wrap[1])[:cols], _uv_axis(rows, wrap[0])[:rows])
    out = io.StringIO()
    out.write("ply\nformat ascii 1.0\n")
    for line in header.splitlines():
        out.write(f"comment {line}\n")
    out.write(f"element vertex {rows * cols}\nproperty float x\nproperty float y\n"
              "property float z\nproperty float u\nproperty float v\n"
              f"element face {len(quads)}\nproperty list uchar int vertex_indices\nend_header\n")
    vert = np.concatenate([grid_xyz.reshape(-1, 3), uu.reshape(-1, 1), vv.reshape(-1, 1)], 1)
    np.savetxt(out, vert, fmt="%.7g %.7g %.7g %.7g %.7g")
    np.savetxt(out, quads, fmt="4 %d %d %d %d")
    return out.getvalue()

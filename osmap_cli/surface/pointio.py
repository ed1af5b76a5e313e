"""Reading surface samples: point clouds (PLY, XYZ, NPY, OBJ without faces) and meshes (OBJ or
PLY with faces, sampled uniformly by area), with the checks that make a bad input a one-line
OsmapError naming the file.

- .ply (ascii or binary) and .obj: read by trimesh (osmap_cli.carving.meshio.read_geometry); the
  vertices are the points, and faces (polygons triangulated) make it a mesh.
- .xyz / .txt / .pts / .csv: one point per line, the first three numbers (space or comma
  separated); blank lines and lines starting with # are skipped.
- .npy: an (n, 3) array of numbers.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numpy as np

from osmap_cli.errors import OsmapError

POINT_EXTENSIONS = (".ply", ".xyz", ".txt", ".pts", ".csv", ".npy", ".obj")


@dataclass
class Surface:
    """What was read: vertices (n, 3) and, for a mesh, triangles (m, 3) into them."""

    vertices: np.ndarray
    triangles: np.ndarray | None = None

    @property
    def is_mesh(self) -> bool:
        return self.triangles is not None and len(self.triangles) > 0


def _name(path) -> str:
    return os.fsdecode(os.fspath(path))


# ---------------------------------------------------------------------------------- PLY, OBJ
def _read_mesh_file(path) -> Surface:
    """A PLY or OBJ file read by trimesh (osmap_cli.carving.meshio): its vertices, and its
    faces (polygons triangulated) when it has any."""
    from osmap_cli.carving.meshio import read_geometry

    vertices, triangles, _ = read_geometry(path, (".ply", ".obj"))
    return Surface(vertices, triangles if len(triangles) else None)


# ------------------------------------------------------------------------------------ text, npy
_SPLIT = re.compile(r"[\s,;]+")


def _read_xyz(path) -> Surface:
    name = _name(path)
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except UnicodeDecodeError:
        raise OsmapError(f"{name}: not a text point file (it is not UTF-8 text)") from None
    rows = []
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s.startswith("#") or s.startswith("//"):
            continue
        tok = [t for t in _SPLIT.split(s) if t][:3]
        try:
            if len(tok) < 3:
                raise ValueError
            rows.append([float(t) for t in tok])
        except ValueError:
            raise OsmapError(f"{name}: line {lineno}: expected three numbers x y z, got "
                             f"{s[:60]!r}") from None
    return Surface(np.array(rows, np.float64).reshape(-1, 3))


def _read_npy(path) -> Surface:
    name = _name(path)
    try:
        arr = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as e:
        raise OsmapError(f"{name}: not a readable .npy array ({str(e).splitlines()[0]})") \
            from None
    if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "iuf":
        raise OsmapError(f"{name}: expected a numeric (n, 3) array, got dtype "
                         f"{getattr(arr, 'dtype', type(arr))}")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise OsmapError(f"{name}: expected an (n, 3) array of points, got shape {arr.shape}")
    return Surface(arr.astype(np.float64))


READERS = {".ply": _read_mesh_file, ".xyz": _read_xyz, ".txt": _read_xyz, ".pts": _read_xyz,
           ".csv": _read_xyz, ".npy": _read_npy, ".obj": _read_mesh_file}


def read_surface(path) -> Surface:
    """Read a point cloud or mesh by extension; OsmapError for anything wrong with the file."""
    name = _name(path)
    ext = os.path.splitext(name)[1].lower()
    if ext not in READERS:
        raise OsmapError(f"{name}: unknown input extension {ext or '(none)'!r} "
                         f"(use {', '.join(POINT_EXTENSIONS)})")
    if not os.path.exists(name):
        raise OsmapError(f"{name}: no such file")
    if os.path.isdir(name):
        raise OsmapError(f"{name}: is a directory, not a point file")
    if os.path.getsize(name) == 0:
        raise OsmapError(f"{name}: the file is empty")
    try:
        surf = READERS[ext](path)
    except OSError as e:
        raise OsmapError(f"{name}: cannot read ({e.strerror or e})") from None
    bad = ~np.all(np.isfinite(surf.vertices), axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        raise OsmapError(f"{name}: {int(bad.sum())} point(s) have NaN or infinite coordinates "
                         f"(first: point {first})")
    if len(surf.vertices) == 0:
        raise OsmapError(f"{name}: contains no points")
    return surf


# ------------------------------------------------------------------------------------- sampling
def triangle_areas(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def sample_mesh(name: str, vertices, triangles, n: int, rng: np.random.Generator) -> np.ndarray:
    """n points uniformly by area on the triangles."""
    areas = triangle_areas(vertices, triangles)
    total = areas.sum()
    if not np.isfinite(total) or total <= 1e-12 * max(1.0, np.ptp(vertices) ** 2):
        raise OsmapError(f"{name}: the mesh has zero area (all faces are degenerate)")
    tri = rng.choice(len(triangles), n, p=areas / total)
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    w = np.stack([1.0 - s, s * (1.0 - r2), s * r2], 1)
    corners = vertices[triangles[tri]]  # (n, 3, 3)
    return np.einsum("nk,nkd->nd", w, corners)


def check_points(name: str, points: np.ndarray, nodes: int) -> None:
    """Enough distinct points for the map, and not all coincident or collinear."""
    distinct = len(np.unique(points, axis=0)) if len(points) <= 2_000_000 else len(points)
    if distinct < nodes:
        raise OsmapError(f"{name}: {distinct} distinct points is fewer than the {nodes} map "
                         "nodes (use a smaller --grid or more points)")
    centred = points - points.mean(0)
    s = np.linalg.svd(centred[:: max(1, len(points) // 200_000)], compute_uv=False)
    scale = max(1.0, float(np.abs(points).max()))
    if s[0] <= 1e-9 * scale:
        raise OsmapError(f"{name}: all points coincide, there is no surface to fit")
    if s[1] <= 1e-6 * s[0]:
        raise OsmapError(f"{name}: the points are collinear, there is no surface to fit")

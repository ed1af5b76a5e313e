"""A triangle mesh as carve sees it, and the checks that make a bad one a one-line OsmapError.

Vertices carry at most one UV each (a file's vertices are split where its UVs are, as trimesh
reads them); the topology (edges, normals, the atlas) is that of the vertices merged by
position, so UV seams do not cut the surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.errors import OsmapError

__all__ = ["Mesh", "check_mesh", "merged", "smooth_normals"]

UV_TOLERANCE = 1e-6  # UVs this far outside [0, 1] are still taken as inside


@dataclass(frozen=True)
class Mesh:
    """vertices float64 (n, 3); faces int64 (m, 3); uv float64 (n, 2) or None (v up, as in
    OBJ and trimesh); name: what the mesh came from, for messages."""

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray | None = None
    name: str = "mesh"

    def with_uv(self, vertices, faces, uv) -> Mesh:
        return Mesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int64),
                    np.asarray(uv, np.float64), self.name)


def merged(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions (k, 3), faces (m, 3) into them, index (n,) of each vertex's position): the
    vertices merged where their coordinates are equal."""
    positions, index = np.unique(mesh.vertices, axis=0, return_inverse=True)
    index = index.reshape(-1)
    return positions, index[mesh.faces], index


def _edge_use(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unique undirected edges (e, 2), how many faces use each)."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    return np.unique(edges, axis=0, return_counts=True)


def check_mesh(mesh: Mesh, need_uv: bool) -> None:
    """Raise OsmapError for a mesh carve cannot use: no triangles, NaN or infinite vertices or
    UVs, non-manifold edges, UVs outside [0, 1] (when NEED_UV: they are the layout baked)."""
    name = mesh.name
    if len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise OsmapError(f"{name}: the mesh has no triangles")
    bad = ~np.all(np.isfinite(mesh.vertices), axis=1)
    if bad.any():
        raise OsmapError(f"{name}: {int(bad.sum())} vertices have NaN or infinite coordinates "
                         f"(first: vertex {int(np.argmax(bad))})")
    if float(np.ptp(mesh.vertices, axis=0).max()) <= 0.0:
        raise OsmapError(f"{name}: all vertices are at one point, there is no surface")
    positions, faces, _ = merged(mesh)
    edges, uses = _edge_use(faces)
    shared = uses > 2
    if shared.any():
        a, b = positions[edges[np.argmax(shared)]]
        raise OsmapError(f"{name}: the mesh is not manifold: {int(shared.sum())} edges are "
                         f"shared by more than two triangles (first: {_point(a)} to "
                         f"{_point(b)}); repair it first")
    if need_uv and mesh.uv is not None:
        if not np.all(np.isfinite(mesh.uv)):
            raise OsmapError(f"{name}: the UVs hold NaN or infinite values (--atlas makes a "
                             "new layout)")
        outside = np.any((mesh.uv < -UV_TOLERANCE) | (mesh.uv > 1.0 + UV_TOLERANCE), axis=1)
        if outside.any():
            raise OsmapError(f"{name}: {int(outside.sum())} UVs lie outside [0, 1] (a baked "
                             "map needs one layout inside the square; --atlas makes a new one)")


def _point(p) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in p) + ")"


def smooth_normals(mesh: Mesh) -> np.ndarray:
    """float64 (n, 3) unit vertex normals: the area-weighted face normals around each merged
    position (the same on both sides of a UV seam); (0, 0, 1) where they cancel out."""
    positions, faces, index = merged(mesh)
    a, b, c = (positions[faces[:, k]] for k in range(3))
    face_normals = np.cross(b - a, c - a)  # length: twice the area
    sums = np.zeros_like(positions)
    for k in range(3):
        np.add.at(sums, faces[:, k], face_normals)
    length = np.linalg.norm(sums, axis=1, keepdims=True)
    up = np.zeros_like(sums)
    up[:, 2] = 1.0
    unit = np.where(length > 0, sums / np.where(length > 0, length, 1.0), up)
    return unit[index]

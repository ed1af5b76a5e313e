"""Baking a volume onto a mesh: `carve(mesh, volume, options)`.

Every texel of the UV layout that a triangle covers (its centre inside the triangle) gets the 3D
point it maps to (barycentric rasterisation in UV space), carried into the volume by the
placement (osmap_cli.carving.placement) and sampled there (trilinear, or tricubic). Each UV island
is then grown by `padding` texels: a texel next to an island takes the nearest point of its
neighbour's triangle, so the colour at an island's border continues outwards and mip-maps
show no seams. Texels no island reaches take the mean colour. With `vertex_colors` the volume
is sampled at the vertices instead. The work per texel does not depend on the mesh, and the
memory is that of the map (a triangle index per texel and the colours).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from osmap_cli.carving.mesh import Mesh, check_mesh, smooth_normals
from osmap_cli.carving.options import CarveOptions
from osmap_cli.carving.placement import material_transform, overrun
from osmap_cli.carving.volume import as_volume
from osmap_cli.errors import OsmapError

__all__ = ["CarveResult", "carve", "texel_corners"]


@dataclass(frozen=True)
class CarveResult:
    """What a carve made.

    mesh: the mesh baked, with its UVs (given, or made by the atlas); normals: float64 (n, 3)
    smooth vertex normals; texture: float32 (H, W, C) (None with vertex colours);
    vertex_colors: float32 (n, C) (None with a texture); maps: {NAME: float32 (H, W, C) or
    (n, C)} of the aligned volumes; triangles: int32 (H, W), the triangle each texel was baked
    from after padding (-1: none); covered: bool (H, W), texels inside a triangle;
    transform: float64 (3, 4), object point -> voxel coordinates (q = T[:, :3] p + T[:, 3]);
    warnings: one line each.
    """

    mesh: Mesh
    normals: np.ndarray
    texture: np.ndarray | None
    vertex_colors: np.ndarray | None
    transform: np.ndarray
    triangles: np.ndarray | None = None
    covered: np.ndarray | None = None
    maps: dict = field(default_factory=dict)
    warnings: tuple = ()


def texel_corners(mesh: Mesh, width: int, height: int) -> np.ndarray:
    """float64 (m, 3, 2): each triangle's UVs in texel units (x = u W, y = (1 - v) H; texel
    (r, c) has its centre at (c + 0.5, r + 0.5))."""
    uv = mesh.uv[mesh.faces]
    return np.stack([uv[..., 0] * width, (1.0 - uv[..., 1]) * height], axis=-1)


def _as_mesh(mesh) -> Mesh:
    if isinstance(mesh, Mesh):
        return mesh
    if isinstance(mesh, (str, bytes)) or hasattr(mesh, "__fspath__"):
        from osmap_cli.carving.meshio import read_mesh

        return read_mesh(mesh)
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):  # a trimesh.Trimesh
        uv = getattr(getattr(mesh, "visual", None), "uv", None)
        return Mesh(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64),
                    None if uv is None else np.asarray(uv, np.float64), "mesh")
    parts = tuple(mesh)
    uv = np.asarray(parts[2], np.float64) if len(parts) > 2 and parts[2] is not None else None
    return Mesh(np.asarray(parts[0], np.float64).reshape(-1, 3),
                np.asarray(parts[1], np.int64).reshape(-1, 3), uv, "mesh")


def carve(mesh, volume, options: CarveOptions | None = None, aligned: dict | None = None
          ) -> CarveResult:
    """Bake VOLUME onto MESH.

    mesh: a path (OBJ, PLY, glTF/GLB, STL), a trimesh.Trimesh, a carve Mesh or (vertices,
    faces[, uv]); volume: float (Z, Y, X[, C]) (C 1 to 4) or a path of a volume `osmap solid`
    wrote (its tileable flag is then read from its provenance); options: CarveOptions;
    aligned: {NAME: volume} of the same size, baked through the same texels (material sets).
    Raises OsmapError for a bad mesh or volume.
    """
    from osmap_kernels import carve as kernels

    options = (options or CarveOptions()).validated()
    mesh = _as_mesh(mesh)
    if isinstance(volume, np.ndarray):
        volume = as_volume(volume)
    else:
        from osmap_cli.carving.volume import read_volume_file

        volume, tileable = read_volume_file(str(volume))
        options = options.replace(wrap=options.wrap or tileable)
    aligned = {name: as_volume(v, name) for name, v in (aligned or {}).items()}
    for name, other in aligned.items():
        if other.shape[:3] != volume.shape[:3]:
            raise OsmapError(f"{name}: aligned volume {other.shape[:3]} is not the size of the "
                             f"volume {volume.shape[:3]}")
    needs_layout = not options.vertex_colors
    check_mesh(mesh, need_uv=needs_layout and not options.atlas)
    warnings = []
    if needs_layout and (options.atlas or mesh.uv is None):
        from osmap_cli.carving.atlas import make_atlas

        mesh = make_atlas(mesh, max(options.texture_size), options.padding)
    A, b = material_transform(mesh.vertices, volume.shape, options.scale_mode, options.scale,
                              options.offset, options.angles)
    transform = np.concatenate([A, b[:, None]], axis=1)
    outside = overrun(mesh.vertices @ A.T + b, volume.shape)
    if outside > 0 and not options.wrap:
        warnings.append(f"{mesh.name}: {100 * outside:.1f}% of the vertices lie outside the "
                        "volume and take its border colours (clamped); a smaller --scale, "
                        "an --offset or a tileable volume (--tileable) avoids it")
    normals = smooth_normals(mesh)
    if not needs_layout:
        q = mesh.vertices @ A.T + b
        colours = kernels.sample_points(q, volume, options.wrap, options.cubic)
        maps = {name: kernels.sample_points(q, v, options.wrap, options.cubic)
                for name, v in aligned.items()}
        return CarveResult(mesh, normals, None, colours, transform, maps=maps,
                           warnings=tuple(warnings))

    width, height = options.texture_size
    corners = texel_corners(mesh, width, height)
    tri, overlaps = kernels.rasterise(corners, height, width)
    covered = tri >= 0
    count = int(covered.sum())
    if overlaps:
        warnings.append(f"{mesh.name}: UV islands overlap ({overlaps} texels, "
                        f"{100 * overlaps / max(count, 1):.1f}% of those covered, lie inside "
                        "more than one triangle; the overlapping parts share those texels; "
                        "--atlas makes a layout without overlaps)")
    if count == 0:
        warnings.append(f"{mesh.name}: the UV layout covers no texel centre at "
                        f"{width}x{height}; use a larger --texture-size")
    tri = kernels.dilate(tri, options.padding)
    points = mesh.vertices[mesh.faces]

    def bake(v):
        out = kernels.bake(tri, corners, points, transform, v, options.wrap, options.cubic)
        if count:
            out[tri < 0] = out[covered].mean(axis=0, dtype=np.float64)
        return out

    texture = bake(volume)
    maps = {name: bake(v) for name, v in aligned.items()}
    return CarveResult(mesh, normals, texture, None, transform, tri, covered, maps,
                       tuple(warnings))

"""A UV atlas for a mesh without (usable) UVs, made by xatlas: the surface cut into charts of
little distortion, packed into the square with room for the padding. xatlas is deterministic:
the same mesh gives the same atlas."""

from __future__ import annotations

import numpy as np

from osmap_cli.carving.mesh import Mesh, merged
from osmap_cli.errors import OsmapError

__all__ = ["make_atlas"]


def make_atlas(mesh: Mesh, resolution: int, padding: int) -> Mesh:
    """The mesh with new UVs in [0, 1] (vertices split along the chart seams); RESOLUTION: the
    texture's larger side, PADDING: texels between charts (xatlas sizes the atlas only
    approximately, so it is asked for half as much again)."""
    import xatlas

    positions, faces, _ = merged(mesh)
    atlas = xatlas.Atlas()
    try:
        atlas.add_mesh(positions.astype(np.float32), faces.astype(np.uint32))
        pack = xatlas.PackOptions()
        pack.resolution = int(resolution)
        pack.padding = int(padding + (padding + 1) // 2)
        pack.bilinear = True
        atlas.generate(xatlas.ChartOptions(), pack)
    except (RuntimeError, ValueError) as exc:
        raise OsmapError(f"{mesh.name}: xatlas could not make a UV atlas ({exc})") from None
    if atlas.atlas_count != 1:
        raise OsmapError(f"{mesh.name}: xatlas packed the charts into {atlas.atlas_count} "
                         "atlases; use a larger --texture-size")
    mapping, new_faces, uv = atlas[0]
    return mesh.with_uv(positions[np.asarray(mapping, np.int64)], new_faces,
                        np.asarray(uv, np.float64))

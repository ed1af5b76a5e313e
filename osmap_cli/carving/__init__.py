"""Carving: a solid texture baked onto a real mesh (`osmap carve`).

>>> import numpy as np
>>> from osmap_cli.carving import CarveOptions, carve
>>> z, y, x = np.mgrid[0:8, 0:8, 0:8] / 7.0
>>> volume = np.stack([x, y, z], axis=-1).astype(np.float32)
>>> square = ([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]],
...           [[0, 0], [1, 0], [1, 1], [0, 1]])
>>> result = carve(square, volume, CarveOptions(texture_width=16, texture_height=16))
>>> result.texture.shape, bool(result.covered.all())
((16, 16, 3), True)

Modules: mesh (the Mesh record and its checks), meshio (trimesh reading and writing), atlas
(xatlas), placement (object -> volume coordinates), volume (reading, checking, synthesizing),
bake (the carve itself), preview (a software render), job (one `osmap carve` job). The kernels
load on first use.
"""

from osmap_cli.carving.options import CarveOptions

__all__ = ["CarveOptions", "CarveResult", "carve", "render_preview"]


def __getattr__(name):
    if name in ("CarveResult", "carve"):
        from osmap_cli.carving import bake
        return getattr(bake, name)
    if name == "render_preview":
        from osmap_cli.carving import preview
        return preview.render_preview
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

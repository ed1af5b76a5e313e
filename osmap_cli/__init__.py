"""osmap: texture, solid-texture and surface-grid synthesis with the Oriented and Scalable Map.

The few names a library user needs; each loads its module (and Numba's kernels) on first use,
so ``import osmap_cli`` is cheap.

A texture like an exemplar (float pixels (H, W, C) in [0, 1]):

>>> import numpy as np
>>> import osmap_cli as osmap
>>> exemplar = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)
>>> result = osmap.synthesize(exemplar, osmap.SynthOptions(width=48, height=40, seed=1))
>>> result.pixels.shape, result.positions.shape
((40, 48, 3), (40, 48, 2))

Fill a hole from the rest of an image, or make a photo tile (the other pixels kept bit for bit):

>>> hole = np.zeros((32, 32), bool)
>>> hole[12:20, 10:22] = True
>>> filled = osmap.inpaint(exemplar, hole, osmap.SynthOptions(seed=1))
>>> bool((filled.pixels[~hole] == exemplar[~hole]).all())
True
>>> osmap.make_tileable(exemplar, border=6).pixels.shape
(32, 32, 3)

A solid texture whose slices along x, y and z look like it (one exemplar per axis or one for all):

>>> volume = osmap.synthesize_solid([exemplar], osmap.SolidOptions(width=16, height=16,
...                                 depth=16, seed=1, levels=1, coarse_iterations=1))
>>> volume.voxels.shape
(16, 16, 16, 3)

The volume carved into a mesh (a path, a trimesh.Trimesh or (vertices, faces[, uv])): a texture
map baked on its UV layout (one is made with xatlas when it has none), an osmap.CarveResult:

>>> square = ([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]],
...           [[0, 0], [1, 0], [1, 1], [0, 1]])
>>> carved = osmap.carve(square, volume.voxels, osmap.CarveOptions(texture_width=32,
...                      texture_height=32))
>>> carved.texture.shape
(32, 32, 3)

A quad grid fitted to points on a surface (here 2000 points of a cylinder), and the map itself:

>>> t, z = np.random.default_rng(0).random((2, 2000))
>>> points = np.stack([np.cos(2 * np.pi * t), np.sin(2 * np.pi * t), 3 * z], axis=1)
>>> fit = osmap.fit_surface(points, osmap.FitConfig(grid=(8, 12), wrap="u", steps=3000))
>>> fit.grid_xyz.shape
(8, 12, 3)
>>> som = osmap.OSMap((8, 8), dim=3)
>>> som.init_random(points, seed=0).grid_weights().shape
(8, 8, 3)

Images in and out (any format OpenImageIO reads; PNG, EXR, TIFF, JPEG out, written atomically):

>>> import tempfile, os
>>> path = os.path.join(tempfile.mkdtemp(), "texture.png")
>>> osmap.write_image(path, result.pixels)
>>> osmap.read_image(path).pixels.shape
(40, 48, 3)
"""

__version__ = "0.1.0"

# public name -> (module, attribute)
_API = {
    "synthesize": ("osmap_cli.synth.pipeline", "synthesize"),
    "SynthOptions": ("osmap_cli.synth.options", "SynthOptions"),
    "SynthResult": ("osmap_cli.synth.pipeline", "SynthResult"),
    "inpaint": ("osmap_cli.synth.fill", "inpaint"),
    "make_tileable": ("osmap_cli.synth.fill", "make_tileable"),
    "synthesize_solid": ("osmap_cli.solid.pipeline", "synthesize_solid"),
    "SolidOptions": ("osmap_cli.solid.options", "SolidOptions"),
    "SolidResult": ("osmap_cli.solid.core", "SolidResult"),
    "render_volume": ("osmap_cli.solid.render", "render_volume"),
    "carve": ("osmap_cli.carving.bake", "carve"),
    "CarveOptions": ("osmap_cli.carving.options", "CarveOptions"),
    "CarveResult": ("osmap_cli.carving.bake", "CarveResult"),
    "fit_surface": ("osmap_cli.surface.fit", "fit_surface"),
    "FitConfig": ("osmap_cli.surface.fit", "FitConfig"),
    "OSMap": ("osmap_cli.engine", "OSMap"),
    "Schedule": ("osmap_cli.engine", "Schedule"),
    "Orientation": ("osmap_cli.engine", "Orientation"),
    "read_image": ("osmap_cli.imageio", "read_image"),
    "write_image": ("osmap_cli.imageio", "write_image"),
    "OsmapError": ("osmap_cli.errors", "OsmapError"),
}

__all__ = sorted(_API)


def __getattr__(name):
    if name in _API:
        import importlib

        module, attribute = _API[name]
        return getattr(importlib.import_module(module), attribute)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(_API))

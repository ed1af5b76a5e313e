"""Solid (3D) texture synthesis: `osmap solid`.

>>> from osmap_cli.solid import SolidOptions, synthesize_solid
>>> result = synthesize_solid([exemplar], SolidOptions(width=64, height=64, depth=64, seed=1))
>>> result.voxels.shape, result.source.shape
((64, 64, 64, 3), (64, 64, 64, 3))

The pipeline (Numba kernels) loads on first use, so option validation and `--help` stay fast.
"""

from osmap_cli.solid.options import SolidOptions

__all__ = ["SolidOptions", "SolidResult", "render_volume", "synthesize_solid"]


def __getattr__(name):
    if name in ("SolidResult", "synthesize_solid"):
        from osmap_cli.solid import pipeline
        return getattr(pipeline, name)
    if name == "render_volume":
        from osmap_cli.solid import render
        return render.render_volume
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

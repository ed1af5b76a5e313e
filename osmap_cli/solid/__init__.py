"""Solid (3D) texture synthesis: `osmap solid`.

>>> from osmap_cli.solid import SolidOptions, synthesize_solid
>>> result = synthesize_solid([exemplar], SolidOptions(width=64, height=64, depth=64, seed=1))
>>> result.voxels.shape, result.source.shape
((64, 64, 64, 3), (64, 64, 64, 3))

The public face is `SolidOptions`, `synthesize_solid`, `SolidResult`, `render_volume` and the
method table `METHODS`; the modules behind it are private. The pipeline (Numba kernels) loads
on first use, so option validation and `--help` stay fast.

How a volume is made (one job a module):
- options: SolidOptions, every option and tunable, validated before any work;
- pipeline: synthesize_solid: the level plan (plan_levels: each level halves the volume's
  sides that stay >= 16 voxels, so thin volumes get a pyramid too), the exemplar pyramids, a
  SolidTask, then the method's run; --orientation makes the material axis-aligned and turns it;
- methods: METHODS[name], the table of methods (name, one-line summary, what --quality does,
  the module that implements it);
- core: the shared records: SolidTask (exemplars, ex_of_axis, pyramids, the volume's shape per
  level, tileable, seed), SolidLevel (one level's exemplar data built once: images padded and
  stacked, search features, k-NN table of similar positions, valid bounds lo/hi, variance,
  window side, PCA basis) and SolidResult; window_level / pixel_level build a SolidLevel;
- optimise: the Kopf et al. texture optimisation, coarse to fine, with optional sharpening;
  layout: the OS-Map's layout of the coarsest volume; upsample: positions and colours from one
  level to the next;
- method_osmap, method_kopf, method_legacy: one method each;
- job, formats, volumeio, orient, preview, render: one `osmap solid` job, the output formats,
  their writers and readers, turned volumes, previews, re-rendering from --uv-out.

A method is a module osmap_cli/solid/method_NAME.py with two names, plus one row in METHODS:
- `Options`: a frozen dataclass, the method's options record, built by
  `Options.from_solid(solid_options)` with keywords; it applies --quality (what fast and high
  mean for this method; say it in the row's `quality` text too);
- `run(task: SolidTask, options: Options, progress=None) -> SolidResult`: anything from the
  task's exemplars, pyramids and level shapes to the voxels (Z, Y, X, C) and each voxel's
  source (axis, row, col) in the exemplars; `progress(fraction)` as work finishes.
Nothing obliges a method to run coarse to fine: it may analyse the exemplars, build its own
volume and call the optimisation once. Its tunables are SolidOptions fields (preset keys and
`--tuning` flags come from them); its `Options` reads the ones it uses.

The optimisation is a function of its inputs only: `optimise(task, levels, start, opt)` with
`levels` a list of SolidLevel (finest first), `start` the coarsest level's window positions
(int32 (3, Z, Y, X, 2): the OS-Map's layout, random positions or a method's own) and `opt` an
`Optimisation` record. Guide channels fit this shape: exemplar-side channels enter each level's
window vectors (build the SolidLevel from the colours and the weighted channels), volume-side
channels the search's query next to the volume's colours; the averaging keeps the colours only.
"""

from osmap_cli.solid.methods import METHODS
from osmap_cli.solid.options import SolidOptions

__all__ = ["METHODS", "SolidOptions", "SolidResult", "render_volume", "synthesize_solid"]


def __getattr__(name):
    if name == "synthesize_solid":
        from osmap_cli.solid import pipeline
        return pipeline.synthesize_solid
    if name == "SolidResult":
        from osmap_cli.solid import core
        return core.SolidResult
    if name == "render_volume":
        from osmap_cli.solid import render
        return render.render_volume
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

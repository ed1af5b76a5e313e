"""The synthesis pipeline: pyramid -> organise (OS-Map, coarsest level) -> refine at every level
-> render. `synthesize` is the library entry point behind `osmap synth`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.synth.options import SynthOptions
from osmap_cli.synth.organise import organise
from osmap_cli.synth.refine import refine, upsample
from osmap_cli.synth.render import render, render_settings
from osmap_cli.texture.features import appearance_features
from osmap_cli.texture.levels import level_count
from osmap_cli.texture.pyramid import build_pyramid, level_shapes

# guided synthesis sweeps the coarsest level this many times more: the guide's regions form
# there, out of an OS-Map layout that ignored the guide (the coarsest level is the cheapest)
GUIDED_COARSE_FACTOR = 3
MIN_LEVEL_SIZE = 8  # the coarsest exemplar and output levels keep at least this many pixels a side


@dataclass(frozen=True)
class SynthResult:
    """pixels: float32 (H, W, C) like the exemplar; positions: float32 (H, W, 2) exemplar
    (row, col) of every output pixel."""

    pixels: np.ndarray
    positions: np.ndarray
    jacobian: np.ndarray | None = None  # float32 (H, W, 2, 2) with control fields, else None


def valid_box(shape, jac: np.ndarray, radius: int):
    """Exemplar positions whose whole matching window stays inside the exemplar (lo, hi)."""
    reach = radius * np.abs(jac).sum(axis=1)
    margin = np.minimum(np.ceil(reach), (np.array(shape) - 1) // 2)
    lo = margin.astype(np.float64)
    hi = np.array(shape, np.float64) - 1 - margin
    return lo, hi


def synthesize(exemplar: np.ndarray, options: SynthOptions, progress=None,
               fields=None, guide=None, target_guide=None) -> SynthResult:
    """Synthesize a texture like `exemplar` (float32 (h, w, C), any channels, alpha included).

    `progress`, if given, is called with a fraction of the total work as stages finish.
    `fields` (osmap_cli.fields.ControlFields, optional) varies the orientation and scale per
    output pixel on top of the options' (method osmap only).
    `target_guide` (float (H', W'), any size: resized to the output) makes the output follow it
    where the exemplar follows `guide` (float (h, w), the exemplar's size; default: the
    exemplar's blurred luminance, osmap_cli.synth.guide.auto_guide, and then target_guide is
    stretched to 0..1 like it), with weight
    options.guide_weight (method osmap only).
    """
    opts = options.validated().with_quality()
    exemplar = np.ascontiguousarray(exemplar, np.float32)
    if fields is not None and opts.method != "osmap":
        raise ValueError("control fields need method 'osmap'")
    if guide is not None and target_guide is None:
        raise ValueError("a guide needs a target_guide")
    if target_guide is not None:
        if opts.method != "osmap":
            raise ValueError("guided synthesis needs method 'osmap'")
        if guide is None:
            # luminance against luminance: both stretched to 0..1
            from osmap_cli.synth.guide import auto_guide, stretch
            guide = auto_guide(exemplar)
            target_guide = stretch(target_guide)
        guide = np.asarray(guide, np.float32)
        if guide.shape != exemplar.shape[:2]:
            raise ValueError(f"guide is {guide.shape[1]}x{guide.shape[0]}, the exemplar "
                             f"{exemplar.shape[1]}x{exemplar.shape[0]}: they must match")
        opts = opts.replace(coarse_sweeps=opts.coarse_sweeps * GUIDED_COARSE_FACTOR)
    if opts.method == "paper":
        from osmap_cli.synth.paper import synthesize_paper
        pos = synthesize_paper(exemplar.shape[:2], opts, progress=progress)
        return SynthResult(render(exemplar, pos), pos)

    out_shape = (opts.height, opts.width)
    levels = level_count([exemplar.shape[:2]], out_shape, opts.levels, min_size=MIN_LEVEL_SIZE)
    pyramid = build_pyramid(exemplar, levels)
    shapes = level_shapes(out_shape, levels)
    jac = opts.jacobian()
    if fields is not None:
        # the OS-Map lays out the coarsest level with one Jacobian summarising the fields;
        # the refinement then follows the per-pixel field at every level
        angle, scale = fields.representative(opts.orientation, opts.scale)
        jac = opts.replace(orientation=angle, scale=scale).jacobian()
    wrap = opts.tileable

    def jacobian_field(shape):
        if fields is None:
            return np.broadcast_to(jac.astype(np.float32), (*shape, 2, 2)).copy()
        return fields.jacobian_field(shape, opts.orientation, opts.scale, opts.anisotropy)

    work = [opts.coarse_sweeps + 1] + [opts.sweeps] * (levels - 1)
    total = float(sum(work)) or 1.0

    def advance(units):
        if progress is not None:
            progress(units / total)

    guides = [None] * levels
    if target_guide is not None:
        from osmap_cli.synth.guide import guide_levels
        guides = list(zip(guide_levels(guide, exemplar.shape[:2], levels),
                          guide_levels(target_guide, out_shape, levels)))
    pos = None
    for level in range(levels - 1, -1, -1):
        image = pyramid[level]
        feat = appearance_features([image], opts.feature_dims)[0]
        jac_field = jacobian_field(shapes[level])
        reach = jac if fields is None else np.abs(jac_field).max(axis=(0, 1))
        lo, hi = valid_box(image.shape[:2], reach, opts.patch_radius)
        if pos is None:
            pos = organise(image.shape[:2], shapes[level], jac, lo, hi, opts, wrap=wrap,
                           seed=opts.seed)
            if fields is None and np.allclose(jac, np.eye(2)):
                pos = np.rint(pos)
            advance(1)
            sweeps = opts.coarse_sweeps
        else:
            pos = upsample(pos, shapes[level], jac_field, lo, hi)
            sweeps = opts.sweeps
        pos = refine(pos, feat, jac_field, lo, hi, sweeps, opts, wrap=wrap, seed=opts.seed,
                     salt=level, level_scale=2 ** level,
                     coarsest_scale=2 ** (levels - 1), progress=advance, guides=guides[level])
    pixels = render(exemplar, pos, jac_field, *render_settings(opts))
    return SynthResult(pixels, pos, None if fields is None else jac_field)

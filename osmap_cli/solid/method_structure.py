"""Method structure (the default): the 3D structure first, then the appearance.

The exemplars are analysed (osmap_cli.solid.structure.analysis): separate particles (stones,
chips, cells), layers (grain, rings, sediment), veins (swirled bands), a phase field (mottled
regions) or none of these. The structure found is built in 3D at the exemplar's scale
(particles by stereology by simulation, layers as the bands of a displaced planar or
cylindrical field, veins as the bands of a warped turbulent field, phase fields as a truncated
Gaussian field), then the Kopf et al. optimisation fills in the appearance with the
structure as guide channels of every slice window, starting from the OS-Map's layout of the
coarsest volume, with method osmap's colour and exemplar-position histogram weights and its
sharpening passes at the coarser levels (`fill_sharpen`); finally each phase's colours, and
each particle's colours, are matched to the exemplar's, the exemplar's residual detail
added (`fill_detail`: copied from each voxel's source pixel to particles and layers, as noise
along the sheets to veins, `vein_detail`), and the whole
volume's colours moved `final_histogram` of the way to the exemplar's distribution. An
exemplar with none of these structures is made by method osmap.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from osmap_cli.solid import method_osmap
from osmap_cli.solid.core import SolidResult, SolidTask
from osmap_cli.solid.layout import Layout
from osmap_cli.solid.optimise import Optimisation, Polish, quality_scaled
from osmap_cli.solid.structure.cells import soften_walls
from osmap_cli.solid.structure.fill import Fill, fill
from osmap_cli.solid.structure.method import add_detail, build_structure, finish, plan
from osmap_cli.solid.structure.sheared import sheared_exemplars
from osmap_cli.texture.histogram import match_quantiles

if TYPE_CHECKING:
    from osmap_cli.solid.options import SolidOptions


@dataclass(frozen=True)
class Options:
    """What to build (structure, phases), how to fill it (Fill) and the method used when the
    exemplar shows no structure (method osmap's options)."""

    structure: str
    phases: int
    fill: Fill
    final_histogram: float  # how far the final colours move to the exemplar's distribution
    fallback: method_osmap.Options

    @classmethod
    def from_solid(cls, opts: SolidOptions) -> Options:
        iterations, knn = quality_scaled(opts.quality, opts.kopf_iterations, opts.knn)
        fallback = method_osmap.Options.from_solid(opts)
        sharpening = replace(fallback.optimisation.sharpening, passes=opts.fill_sharpen)
        return cls(
            structure=opts.structure, phases=opts.phases,
            fill=Fill(
                window=opts.kopf_window, dims=opts.kopf_dims, knn=knn,
                optimisation=Optimisation(
                    stride=opts.kopf_stride, iterations=iterations, r=opts.kopf_r,
                    colour_histogram=opts.histogram_weight,
                    position_histogram=opts.position_weight, upsample_render=True,
                    sharpening=sharpening,
                    polish=Polish(iterations=opts.polish, guides=bool(opts.polish_guides),
                                  label_mismatch=opts.polish_labels,
                                  discrete=bool(opts.polish_discrete))),
                layout=Layout(steps_per_node=opts.som_steps_per_node,
                              sigma_max=opts.som_sigma_max, anisotropy=opts.som_anisotropy),
                clip=opts.guide_clip, guide_weight=opts.guide_weight,
                phase_match=opts.phase_match, detail=opts.fill_detail,
                vein_detail=opts.vein_detail, vein_grain=opts.vein_grain),
            final_histogram=opts.final_histogram,
            fallback=fallback)


def _fill_labels(found, wrap: bool) -> list:
    """The exemplars' particle masks as the fill reads them: the split lines between touching
    profiles belong to the particles (the volume parts its particles by real gaps, which must
    take the exemplar's gap colours, not the stone colours of a split line)."""
    return [replace(a.reader, split=False).particle_mask(im, wrap).astype(np.int64)
            for a, im in zip(found.analyses, found.images)]


def final_colours(voxels: np.ndarray, images, amount: float) -> np.ndarray:
    """The finished voxels within the exemplars' colour range, moved `amount` of the way to
    their colour distribution."""
    pixels = np.concatenate([im.reshape(-1, im.shape[2]) for im in images])
    # the detail added to a colour near the exemplar's darkest or lightest leaves its range
    voxels = np.clip(voxels, pixels.min(0), pixels.max(0))
    # the per-phase matching moves the low-pass only; this one gives back the exemplar's
    # extreme colours that the optimisation's averaging loses
    return match_quantiles(voxels, pixels, amount)


def run(task: SolidTask, options: Options, progress=None) -> SolidResult:
    started = time.perf_counter()
    found = plan(task.images, task.ex_of_axis, options.structure, options.phases, task.seed,
                 task.tileable, probe_cap=max(task.shapes[0]))
    if found.kind == "none":
        result = method_osmap.run(task, options.fallback, progress)
        return SolidResult(result.voxels, result.source, tuple(found.report()),
                           found.summary())
    built = build_structure(found, task.shapes[0], task.seed, task.tileable)
    structure_seconds = time.perf_counter() - started
    task, found, unsheared = sheared_exemplars(task, found)
    if found.kind == "particles":
        found = replace(found, ex_labels=_fill_labels(found, task.tileable))
    voxels, source = fill(task, found.ex_labels, found.ex_identity, built.labels,
                          built.identity, options.fill, progress)
    voxels = finish(voxels, found, built, options.fill.phase_match, task.tileable)
    voxels = add_detail(voxels, source, found, built, task.exemplars(0), task.ex_of_axis,
                        options.fill.detail, task.seed, task.tileable, options.fill.vein_detail,
                        options.fill.vein_grain)
    voxels = final_colours(soften_walls(voxels, built.walls, task.tileable), found.images,
                           options.final_histogram)
    source = unsheared(source)
    seconds = time.perf_counter() - started
    report = (*found.report(), f"structure step {structure_seconds:.1f} s of "
              f"{seconds:.1f} s (analysis and model {found.seconds:.1f} s)")
    return SolidResult(voxels, source, report, found.summary())

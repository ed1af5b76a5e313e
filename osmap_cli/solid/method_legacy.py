"""Method legacy: search + mode over appearance-space features (boxy; kept for comparison and
for presets structured and smooth).

Per level: the OS-Map lays out the coarsest volume; then each iteration searches, per voxel and
axis, the exemplar position whose in-plane neighbourhood best matches the volume's
(osmap_kernels.solid.search_pass), and gives each voxel the proposal of highest density among
its in-plane neighbours' (colour_pass); finer levels start from the upsampled sources. The
result is rendered from the sources, blended across seams (blend_render).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from osmap_cli.solid.core import SolidResult, SolidTask, pixel_level
from osmap_cli.solid.layout import Layout, organise
from osmap_cli.solid.upsample import upsample_linear, upsample_positions, upsample_source
from osmap_cli.texture.histogram import match_quantiles
from osmap_cli.texture.occupancy import occupancy
from osmap_kernels.solid import (
    ColourParams,
    SearchParams,
    blend_render,
    colour_pass,
    gather_sources,
    search_pass,
    usage_counts,
)

if TYPE_CHECKING:
    from osmap_cli.solid.options import SolidOptions

EXHAUSTIVE_ITERATIONS = 2  # coarsest level: exhaustive search first, then propagation
# ... unless voxels x exemplar pixels exceed this (only with few --levels on a large exemplar:
# the level plan otherwise keeps the coarsest level far below it)
EXHAUSTIVE_BUDGET = 2**25


@dataclass(frozen=True)
class Options:
    """The legacy method's tunables (SolidOptions, the fields without a kopf_ or sharpen
    prefix)."""

    patch_radius: int
    iterations: int  # per finer level
    coarse_iterations: int
    knn: int
    random_candidates: int
    feature_dims: int
    feature_radius: int
    mode_bandwidth: float
    mode_radius: int
    mode_power: float
    occupancy: float
    across: float
    search_occupancy: float
    seam: float
    coarse_seam: float
    histogram: float
    smooth_upsample: float
    blend: float
    layout: Layout

    @classmethod
    def from_solid(cls, opts: SolidOptions) -> Options:
        """The record for --quality: fast: one iteration per finer level, half the coarsest
        level's, at most one candidate of each kind; high: one iteration more per level, two more
        at the coarsest, two more candidates of each kind."""
        iterations, coarse, knn, rand = (opts.iterations, opts.coarse_iterations, opts.knn,
                                         opts.random_candidates)
        if opts.quality == "fast":
            iterations, coarse, knn, rand = 1, max(1, coarse // 2), min(knn, 1), min(rand, 1)
        elif opts.quality == "high":
            iterations, coarse, knn, rand = iterations + 1, coarse + 2, knn + 2, rand + 2
        return cls(
            patch_radius=opts.patch_radius, iterations=iterations, coarse_iterations=coarse,
            knn=knn, random_candidates=rand, feature_dims=opts.feature_dims,
            feature_radius=opts.feature_radius, mode_bandwidth=opts.mode_bandwidth,
            mode_radius=opts.mode_radius, mode_power=opts.mode_power,
            occupancy=opts.occupancy, across=opts.across,
            search_occupancy=opts.search_occupancy, seam=opts.seam,
            coarse_seam=opts.coarse_seam, histogram=opts.histogram,
            smooth_upsample=opts.smooth_upsample, blend=opts.blend,
            layout=Layout(steps_per_node=opts.som_steps_per_node,
                          sigma_max=opts.som_sigma_max, anisotropy=opts.som_anisotropy))


def colour_to_features(images, feats):
    """float64 (C + 1, F): the affine map from colour to appearance features, fitted by least
    squares on the exemplar pixels (exact for colour-only features)."""
    c = np.concatenate([im.reshape(-1, im.shape[2]) for im in images]).astype(np.float64)
    f = np.concatenate([ft.reshape(-1, ft.shape[2]) for ft in feats]).astype(np.float64)
    a = np.concatenate([c, np.ones((len(c), 1))], axis=1)
    return np.linalg.lstsq(a, f, rcond=None)[0]


def run(task: SolidTask, opts: Options, progress=None) -> SolidResult:
    ex_of_axis, wrap, seed = task.ex_of_axis, task.tileable, task.seed
    levels = [pixel_level(task, index, radius=opts.patch_radius, dims=opts.feature_dims,
                          feature_radius=opts.feature_radius, knn=opts.knn)
              for index in range(task.levels)]
    n_ex = len(task.images)
    work = [opts.coarse_iterations * 2] + [opts.iterations] * (task.levels - 1)
    total = float(sum(work))
    done = 0.0
    pos = source = colours = None
    for index in range(task.levels - 1, -1, -1):
        level = levels[index]
        vshape, hw, ex_shapes = level.shape, level.hw, level.ex_shapes
        feats, variance, rr = level.feats, level.variance, (level.window - 1) // 2
        unpadded = [feats[e, :h, :w] for e, (h, w) in enumerate(ex_shapes)]
        coarsest = pos is None
        if coarsest:
            pos = organise(level, ex_of_axis, opts.layout, tileable=wrap, seed=seed)
            iterations = opts.coarse_iterations
            cost = np.ones((3, *vshape), np.float32)
            source = np.zeros((*vshape, 3), np.int32)
            vol = np.zeros((*vshape, feats.shape[3]), np.float32)
            colour_pass(pos, cost, feats, ex_of_axis, np.ones((n_ex, *hw), np.float32),
                        ColourParams(radius=opts.mode_radius, wrap=wrap,
                                     bandwidth2=opts.mode_bandwidth * variance, power=0.0, eps=1.0,
                                     lam=0.0, across=0.0), vol.copy(), source, vol)
        else:
            pos = upsample_positions(pos, vshape, level.lo, level.hi, ex_of_axis)
            source = upsample_source(source, vshape, ex_shapes, ex_of_axis)
            vol = gather_sources(source, feats, ex_of_axis)
            if opts.smooth_upsample:
                colours = upsample_linear(colours, vshape, wrap)
                m = colour_to_features(level.images, unpadded)
                smooth = (colours @ m[:-1] + m[-1]).astype(np.float32)
                vol = np.ascontiguousarray(vol + opts.smooth_upsample * (smooth - vol))
            iterations = opts.iterations
        cparams = ColourParams(radius=opts.mode_radius, wrap=wrap,
                               bandwidth2=opts.mode_bandwidth * variance, power=opts.mode_power,
                               eps=1e-3 * variance * (2 * rr + 1) ** 2, lam=opts.occupancy,
                               across=opts.across)
        # seam penalty unit: a whole window's feature variance, shared among the 8 neighbours.
        # The coarser levels' penalty sets the copy layout every finer level refines, the
        # finest level's how fragmented the rendered copies are (docs/solid.md)
        seam = opts.seam if index == 0 else opts.coarse_seam
        seam_unit = seam * variance * (2 * rr + 1) ** 2 / 8.0
        exhaustive = coarsest and math.prod(vshape) * math.prod(hw) <= EXHAUSTIVE_BUDGET
        reference = (np.concatenate([f.reshape(-1, f.shape[2]) for f in unpadded])
                     if opts.histogram else None)
        for it in range(iterations):
            sparams = SearchParams(radius=rr, wrap=wrap, n_random=opts.random_candidates,
                                   exhaustive=exhaustive and it < EXHAUSTIVE_ITERATIONS,
                                   lo=level.lo, hi=level.hi, lam=opts.search_occupancy,
                                   seed=np.uint64(seed), salt=np.uint64(index * 1000 + it),
                                   seam=seam_unit)
            occ = occupancy(usage_counts(source, ex_of_axis, n_ex, *hw), source[..., 0].size)
            new_pos = np.empty_like(pos)
            cost = np.empty((3, *vshape), np.float32)
            vol = match_quantiles(vol, reference, opts.histogram)
            search_pass(vol, pos, new_pos, cost, feats, ex_of_axis, level.knn, occ, sparams)
            pos = new_pos
            new_source = np.empty_like(source)
            searched, vol = vol, np.empty_like(vol)
            colour_pass(pos, cost, feats, ex_of_axis, occ, cparams, searched, new_source, vol)
            source = new_source
            done += 2 if coarsest else 1
            if progress is not None:
                progress(done / total)
        colours = gather_sources(source, level.stacked, ex_of_axis)
    full = levels[0].stacked
    if opts.blend == 0.0:
        return SolidResult(gather_sources(source, full, ex_of_axis), source)
    bparams = cparams._replace(bandwidth2=opts.blend * variance)
    return SolidResult(blend_render(pos, cost, levels[0].feats, full, ex_of_axis, source,
                                    bparams), source)

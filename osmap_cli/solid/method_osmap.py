"""Method osmap (the default): the OS-Map lays out the coarsest volume's window positions, then
the texture optimisation of Kopf et al. 2007 runs level by level with centre-weighted windows,
stronger histogram weights and sharpening passes (the densest colour cluster that the slice
families agree on), each finer level starting from the exemplar colours at the upsampled
positions; finally the colours are moved towards the exemplar's histogram."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from osmap_cli.solid.core import SolidResult, SolidTask
from osmap_cli.solid.layout import Layout, organise
from osmap_cli.solid.optimise import (
    Optimisation,
    Sharpening,
    optimise,
    quality_scaled,
    window_levels,
)
from osmap_cli.texture.histogram import match_quantiles

if TYPE_CHECKING:
    from osmap_cli.solid.options import SolidOptions


@dataclass(frozen=True)
class Options:
    """The window features, the OS-Map layout, the optimisation and the final histogram
    match."""

    window: int
    dims: int
    knn: int
    layout: Layout
    optimisation: Optimisation
    final_histogram: float  # how far the final colours move to the exemplar's distribution

    @classmethod
    def from_solid(cls, opts: SolidOptions) -> Options:
        iterations, knn = quality_scaled(opts.quality, opts.kopf_iterations, opts.knn)
        sharpening = Sharpening(
            passes=opts.sharpen, levels=opts.sharpen_levels, finest=bool(opts.sharpen_finest),
            final=bool(opts.sharpen_final), bandwidth=opts.sharpen_bandwidth,
            steps=opts.sharpen_steps, cross=opts.sharpen_cross > 0,
            pick_support=opts.pick_support)
        return cls(
            window=opts.kopf_window, dims=opts.kopf_dims, knn=knn,
            layout=Layout(steps_per_node=opts.som_steps_per_node, sigma_max=opts.som_sigma_max,
                          anisotropy=opts.som_anisotropy),
            optimisation=Optimisation(
                stride=opts.kopf_stride, iterations=iterations, r=opts.kopf_r,
                colour_histogram=opts.histogram_weight, position_histogram=opts.position_weight,
                falloff=opts.window_falloff, upsample_render=bool(opts.upsample_render),
                sharpening=sharpening),
            final_histogram=opts.final_histogram)


def run(task: SolidTask, options: Options, progress=None) -> SolidResult:
    levels = window_levels(task, window=options.window, dims=options.dims, knn=options.knn)
    start = organise(levels[-1], task.ex_of_axis, options.layout, tileable=task.tileable,
                     seed=task.seed)
    voxels, source = optimise(task, levels, start, options.optimisation, progress)
    finest = levels[0].stacked
    voxels = match_quantiles(voxels, finest.reshape(-1, finest.shape[3]),
                             options.final_histogram)
    return SolidResult(voxels, source)

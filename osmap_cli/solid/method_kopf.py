"""Method kopf: the texture optimisation of Kopf et al. 2007 as published, from random
positions (flat windows, plain IRLS mean, colour and exemplar-position histogram weights of the
same strength, no sharpening)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from osmap_cli.solid.core import SolidResult, SolidTask
from osmap_cli.solid.optimise import (
    Optimisation,
    optimise,
    quality_scaled,
    random_positions,
    window_levels,
)

if TYPE_CHECKING:
    from osmap_cli.solid.options import SolidOptions


@dataclass(frozen=True)
class Options:
    """The window features and the optimisation (SolidOptions kopf_*, knn)."""

    window: int
    dims: int
    knn: int
    optimisation: Optimisation

    @classmethod
    def from_solid(cls, opts: SolidOptions) -> Options:
        iterations, knn = quality_scaled(opts.quality, opts.kopf_iterations, opts.knn)
        return cls(window=opts.kopf_window, dims=opts.kopf_dims, knn=knn,
                   optimisation=Optimisation(
                       stride=opts.kopf_stride, iterations=iterations, r=opts.kopf_r,
                       colour_histogram=opts.kopf_histogram,
                       position_histogram=opts.kopf_histogram))


def run(task: SolidTask, options: Options, progress=None) -> SolidResult:
    levels = window_levels(task, window=options.window, dims=options.dims, knn=options.knn)
    start = random_positions(levels[-1], task.ex_of_axis, task.seed)
    return SolidResult(*optimise(task, levels, start, options.optimisation, progress))

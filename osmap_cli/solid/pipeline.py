"""`synthesize_solid`, the library entry point behind `osmap solid`: options checked, the
volume's level plan and the exemplar pyramids made (a `SolidTask`), then the chosen method's
`run` (osmap_cli.solid.methods); a turned volume (--orientation) is made axis-aligned and
sampled turned.
"""

from __future__ import annotations

import numpy as np

from osmap_cli.solid.core import SolidResult, SolidTask
from osmap_cli.solid.methods import METHODS
from osmap_cli.solid.options import SolidOptions
from osmap_cli.solid.orient import is_turned, turn_volume
from osmap_cli.texture.levels import level_count
from osmap_cli.texture.pyramid import build_pyramid, half_size

__all__ = ["SolidResult", "plan_levels", "synthesize_solid"]

MIN_COARSE = 16  # the coarsest exemplar level keeps at least this many pixels a side, and a
#                  volume side is halved only while it keeps at least this many voxels


def plan_levels(exemplar_shapes, shape, wanted: int) -> list[tuple[int, int, int]]:
    """The volume's (Z, Y, X) at each pyramid level, finest first: `wanted` levels, fewer when
    one more halving would take the smallest exemplar side or the volume's longest side below
    MIN_COARSE. Each level halves every side that stays >= MIN_COARSE and keeps the others, so
    a thin volume (8x8x1024) still gets a coarse level small enough for an exhaustive search
    (a cube is halved on every side, the same plan as a single size would give)."""
    levels = level_count(exemplar_shapes, (max(shape),), wanted, min_size=MIN_COARSE,
                         round_up=False)
    shapes = [tuple(shape)]
    for _ in range(levels - 1):
        shapes.append(tuple(half_size((n, n))[0] if n // 2 >= MIN_COARSE else n
                            for n in shapes[-1]))
    return shapes


def synthesize_solid(exemplars, options: SolidOptions, progress=None) -> SolidResult:
    """A volume like the exemplars: one float32 (h, w, C) image for every axis, or a list of
    three (x, y, z) with equal channel counts. `progress(fraction)` is called as levels finish.
    """
    opts = options.validated()  # validated: method is a row of METHODS
    if is_turned(opts.angles):
        # the material axis-aligned in a box that holds the turned volume, then sampled turned
        z, y, x = opts.synthesis_shape()
        material = synthesize_solid(exemplars, options.replace(
            width=x, height=y, depth=z, rotate_x=0.0, rotate_y=0.0, rotate_z=0.0), progress)
        return SolidResult(*turn_volume(material.voxels, material.source, opts.shape,
                                        opts.angles))
    if len(exemplars) == 1:
        images, ex_of_axis = [exemplars[0]], np.zeros(3, np.int64)
    else:
        images, ex_of_axis = list(exemplars), np.arange(3, dtype=np.int64)
    images = [np.ascontiguousarray(im, np.float32) for im in images]
    shapes = plan_levels([im.shape[:2] for im in images], opts.shape, opts.levels)
    task = SolidTask(images=images, ex_of_axis=ex_of_axis,
                     pyramids=[build_pyramid(im, len(shapes)) for im in images], shapes=shapes,
                     tileable=opts.tileable, seed=opts.seed)
    method = METHODS[opts.method]
    return method.run(task, method.options.from_solid(opts), progress)

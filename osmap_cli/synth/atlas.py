"""Several exemplars of one material in one synthesis (`osmap synth EX --also EX2 ...`).

The exemplars are packed side by side into one atlas, far enough apart (and at offsets aligned
to the coarsest level) that no pyramid level mixes two of them; every position whose matching
window would leave its own exemplar is forbidden to the search (the LevelConstraint of
osmap_cli.synth.constraints, nothing pinned). The OS-Map lays out the coarsest level from the
allowed positions of all of them, the refinement draws candidates from all of them, and the
occupancy penalty spreads the output over all of them.

>>> result = synthesize_several([a, b, c], SynthOptions(width=256, height=256))
>>> result.exemplar_index   # int (H, W): which exemplar each pixel came from
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from osmap_cli.synth.constraints import LevelConstraint, dilate, mask_pyramid
from osmap_cli.synth.options import SynthOptions
from osmap_cli.synth.organise import organise
from osmap_cli.synth.pipeline import (
    MIN_LEVEL_SIZE,
    LevelLoop,
    SynthResult,
    run_levels,
    uniform_jacobian,
    valid_box,
)
from osmap_cli.synth.render import render, render_settings
from osmap_cli.texture.levels import level_count
from osmap_cli.texture.pyramid import build_pyramid, level_shapes

__all__ = ["Atlas", "SeveralResult", "pack", "snap", "synthesize_several"]


@dataclass(frozen=True)
class Atlas:
    """pixels float32 (h, w, C); origins and shapes (row, col) of each exemplar in it."""

    pixels: np.ndarray
    origins: tuple
    shapes: tuple

    def inside(self, first: int = 0) -> np.ndarray:
        """bool (h, w): the atlas pixels that belong to an exemplar (to exemplar `first` and
        those after it)."""
        mask = np.zeros(self.pixels.shape[:2], bool)
        for (y, x), (h, w) in zip(self.origins[first:], self.shapes[first:]):
            mask[y:y + h, x:x + w] = True
        return mask

    def index(self, positions: np.ndarray) -> np.ndarray:
        """int (H, W): the exemplar each position (row, col) lies in (-1: none)."""
        out = np.full(positions.shape[:2], -1, np.int64)
        rows, cols = positions[..., 0], positions[..., 1]
        for i, ((y, x), (h, w)) in enumerate(zip(self.origins, self.shapes)):
            hit = (rows > y - 0.5) & (rows < y + h - 0.5) & (cols > x - 0.5) & (cols < x + w - 0.5)
            out[hit] = i
        return out

    def locate(self, positions: np.ndarray):
        """(index, local): `index` as above, and float32 (H, W, 2) positions relative to their
        exemplar's origin."""
        index = self.index(positions)
        origins = np.array(self.origins, np.float32)
        return index, (positions - origins[np.maximum(index, 0)]).astype(np.float32)


@dataclass(frozen=True)
class SeveralResult(SynthResult):
    """SynthResult whose positions are atlas positions, plus which exemplar each pixel came
    from and the exemplar-local positions."""

    exemplar_index: np.ndarray | None = None
    local_positions: np.ndarray | None = None


def pack(exemplars, levels: int, radius: int) -> Atlas:
    """The exemplars (float32 (h_i, w_i, C), same C) in one row, at column offsets that are
    multiples of 2^(levels-1), with gaps wide enough that even at the coarsest level a matching
    window never reaches two of them; the gaps hold the exemplars' mean colour."""
    step = 2 ** (levels - 1)
    gap = (radius + 3) * step
    origins, x = [], 0
    for ex in exemplars:
        origins.append((0, x))
        x = int(math.ceil((x + ex.shape[1] + gap) / step) * step)
    height = max(ex.shape[0] for ex in exemplars)
    width = origins[-1][1] + exemplars[-1].shape[1]
    mean = np.mean([ex.reshape(-1, ex.shape[2]).mean(0) for ex in exemplars], axis=0)
    pixels = np.empty((height, width, exemplars[0].shape[2]), np.float32)
    pixels[:] = mean
    for (y, x), ex in zip(origins, exemplars):
        pixels[y:y + ex.shape[0], x:x + ex.shape[1]] = ex
    return Atlas(pixels, tuple(origins), tuple(ex.shape[:2] for ex in exemplars))


def snap(pos: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """pos with every position outside `allowed` moved to the nearest allowed pixel (the
    OS-Map's weights interpolate between exemplars, and so can land in the gaps)."""
    rows, cols = np.nonzero(allowed)
    points = np.stack([rows, cols], 1).astype(np.float32)
    iy = np.clip(np.rint(pos[..., 0]).astype(int), 0, allowed.shape[0] - 1)
    ix = np.clip(np.rint(pos[..., 1]).astype(int), 0, allowed.shape[1] - 1)
    out = pos.copy()
    for y, x in zip(*np.nonzero(~allowed[iy, ix])):
        nearest = np.argmin(((points - pos[y, x]) ** 2).sum(1))
        out[y, x] = points[nearest] + (pos[y, x] - np.rint(pos[y, x]))
    return out


def synthesize_several(exemplars, options: SynthOptions, progress=None) -> SeveralResult:
    """A texture drawing from every exemplar of the list (float32 (h_i, w_i, C), same C).
    Method osmap, no control fields; scale, orientation, anisotropy and tileable apply."""
    opts = options.validated().with_quality()
    if opts.method != "osmap":
        raise ValueError("several exemplars need method 'osmap'")
    exemplars = [np.ascontiguousarray(ex, np.float32) for ex in exemplars]
    if len({ex.shape[2] for ex in exemplars}) != 1:
        raise ValueError("the exemplars have different numbers of channels")
    out_shape = (opts.height, opts.width)
    levels = level_count([ex.shape[:2] for ex in exemplars], out_shape, opts.levels,
                         min_size=MIN_LEVEL_SIZE)
    jac = opts.jacobian()
    reach = int(np.ceil(opts.patch_radius * np.abs(jac).sum(axis=1).max()))
    atlas = pack(exemplars, levels, max(reach, opts.patch_radius))
    pyramid = build_pyramid(atlas.pixels, levels)
    outside = mask_pyramid(~atlas.inside(), levels)
    shapes = level_shapes(out_shape, levels)

    def bounds(level, shape, jac_field):
        return valid_box(shape, jac, opts.patch_radius)

    def constraint(level, lo, hi):
        # a window must stay inside its own exemplar: its centre at least `reach` pixels in;
        # occupancy is relative to uniform use of the exemplars, not of the whole atlas
        return LevelConstraint(np.zeros(shapes[level], bool),
                               np.zeros((*shapes[level], 2), np.float32),
                               dilate(outside[level], reach),
                               float((~outside[level]).mean()))

    def start(level, lo, hi, constraint):
        # the OS-Map's winner-search window follows one exemplar's extent, not the atlas'
        extent = tuple(max(-(-s[k] // 2 ** level) for s in atlas.shapes) for k in (0, 1))
        allowed = ~constraint.forbidden
        pos = organise(extent, shapes[level], jac, lo, hi, opts, wrap=opts.tileable,
                       seed=opts.seed, allowed=allowed)
        if np.allclose(jac, np.eye(2)):
            pos = np.rint(pos)
        return snap(pos, allowed)

    loop = LevelLoop(pyramid, shapes, uniform_jacobian(jac), bounds, start,
                     constraint=constraint)
    pos, jac_field, _ = run_levels(loop, opts, progress)
    pixels = render(atlas.pixels, pos, jac_field, *render_settings(opts))
    index, local = atlas.locate(pos)
    return SeveralResult(pixels, pos, None, index, local)

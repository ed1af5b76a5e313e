"""Several exemplars of one material in one synthesis (`osmap synth EX --also EX2 ...`).

The exemplars are packed side by side into one atlas, far enough apart (and at offsets aligned
to the coarsest level) that no pyramid level mixes two of them; every position whose matching
window would leave its own exemplar is forbidden to the search (an AtlasConstraint, nothing
pinned). The OS-Map lays out the coarsest level over exemplar-local positions and each of its
copies goes to one exemplar (place_copies); the refinement draws candidates from all of them,
and the occupancy penalty spreads the output over all of them.

>>> result = synthesize_several([a, b, c], SynthOptions(width=256, height=256))
>>> result.exemplar_index   # int (H, W): which exemplar each pixel came from
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

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
from osmap_cli.synth.regular import atlas_phase, resolve_lattice, wrapped
from osmap_cli.synth.render import render, render_settings
from osmap_cli.texture.features import appearance_features, feature_variance
from osmap_cli.texture.levels import level_count
from osmap_cli.texture.pyramid import build_pyramid, level_shapes
from osmap_kernels.regions import copy_region_ids

__all__ = ["Atlas", "AtlasConstraint", "SeveralResult", "pack", "place_copies", "snap",
           "synthesize_several"]

# coarsest-level copies of the OS-Map layout: positions that continue each other to within this
# many pixels go to one exemplar together (0, the exact copies, splits the OS-Map's near-copies
# between exemplars: 39-43 % of the start's neighbours broken instead of 25-30 % on
# bricks_dark_red; 2: 1.11x a single synthesis instead of 1.04x there, docs/fill.md)
START_TOLERANCE = 1.0


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


@dataclass(frozen=True)
class AtlasConstraint(LevelConstraint):
    """The LevelConstraint of an atlas level. Its `pin` (which the refinement calls after every
    pass and after every whole-copy alignment, osmap_kernels.regions.align_regions) also takes
    back an alignment shift that moved a copy onto forbidden positions: the alignment knows the
    atlas' bounding box only, not its gaps, and at the coarse levels shifted 7-23 % of the
    pixels there, which the next pass then broke up pixel by pixel (a single exemplar's box
    stops such shifts)."""

    jacobian: np.ndarray | None = None  # float32 (2, 2)
    wrap: bool = False
    memory: dict = field(default_factory=dict)  # the positions of the previous call

    def pin(self, pos: np.ndarray) -> np.ndarray:
        pos = super().pin(pos)
        prev = self.memory.get("pos")
        if prev is not None and prev.shape == pos.shape:
            h, w = self.forbidden.shape
            iy = np.clip(np.rint(pos[..., 0]).astype(np.int64), 0, h - 1)
            ix = np.clip(np.rint(pos[..., 1]).astype(np.int64), 0, w - 1)
            moved = (pos != prev).any(-1)
            bad = self.forbidden[iy, ix] & moved
            if bad.any():
                # the whole copy that moved there goes back (its pixels that moved)
                ids, count = copy_region_ids(np.ascontiguousarray(pos, np.float32),
                                             uniform_jacobian(self.jacobian)(pos.shape[:2]),
                                             self.wrap)
                hit = np.zeros(count, bool)
                hit[ids[bad]] = True
                back = hit[ids] & moved
                pos[back] = prev[back]
        self.memory["pos"] = pos.copy()
        return pos


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
        return AtlasConstraint(np.zeros(shapes[level], bool),
                               np.zeros((*shapes[level], 2), np.float32),
                               dilate(outside[level], reach),
                               float((~outside[level]).mean()),
                               jacobian=np.asarray(jac, np.float32), wrap=opts.tileable)

    def start(level, lo, hi, constraint):
        box = np.zeros(constraint.forbidden.shape, bool)
        box[int(np.ceil(lo[0])):int(np.floor(hi[0])) + 1,
            int(np.ceil(lo[1])):int(np.floor(hi[1])) + 1] = True
        return place_copies(atlas, level, shapes[level], jac, ~constraint.forbidden & box, opts)

    # the refinement's seam unit is the feature variance of the whole atlas, which the flat gaps
    # lower (by 15-21 % on bricks_dark_red and water_caustics): scale it back to the exemplars' own
    ratios = []
    for image, out in zip(pyramid, outside):
        feat = appearance_features([image], opts.feature_dims)[0]
        inside = np.mean(np.sum(np.square(feat[~out], dtype=np.float64), axis=1))
        ratios.append(float(inside) / feature_variance([feat]))
    opts = opts.replace(seam=opts.seam * float(np.mean(ratios)))
    # the first exemplar's lattice, each exemplar's copies in step with it
    lattice = resolve_lattice(opts.lattice, exemplars[0])
    out_lattice = None
    if lattice is not None and opts.tileable:
        out_lattice = wrapped(lattice, out_shape, jac, opts.max_copy or min(out_shape))
        lattice = lattice if out_lattice is not None else None

    def lattice_phase(level):
        return atlas_phase(lattice, exemplars, atlas.origins, pyramid[level].shape[:2], level)

    loop = LevelLoop(pyramid, shapes, uniform_jacobian(jac), bounds, start,
                     constraint=constraint, lattice=lattice, out_lattice=out_lattice,
                     lattice_phase=lattice_phase)
    pos, jac_field, _ = run_levels(loop, opts, progress)
    pixels = render(atlas.pixels, pos, jac_field, *render_settings(opts))
    index, local = atlas.locate(pos)
    return SeveralResult(pixels, pos, None, lattice, index, local)


def continuing_regions(pos: np.ndarray, jac: np.ndarray, wrap: bool, tol: float):
    """(ids int64 (H, W), count): the 4-connected regions of pixels whose positions continue
    each other to within `tol` pixels (|S[q] - S[p] - J (q - p)| <= tol on each axis), numbered
    in the scan order of their first pixels (osmap_kernels.regions.copy_region_ids)."""
    return copy_region_ids(np.ascontiguousarray(pos, np.float32),
                           uniform_jacobian(jac)(pos.shape[:2]), wrap,
                           float(np.nextafter(tol, np.inf)))


def place_copies(atlas: Atlas, level: int, out_shape, jac, allowed, opts) -> np.ndarray:
    """The coarsest level's positions (atlas positions of `level`, float (H, W, 2)): one OS-Map
    over exemplar-local positions (the positions allowed in any exemplar, all exemplars
    overlaid at one origin), as a single-exemplar synthesis lays out its exemplar; then each of
    its copies (continuing_regions) placed in one exemplar, those in which most of its positions
    are allowed, the one furthest behind its share of the allowed positions (the copies taken
    in a random order).

    (An OS-Map trained on the atlas itself mixes the exemplars pixel by pixel: its neighbourhood
    updates average positions of different exemplars, which land in a third one; 66 % of the
    neighbours then came from different exemplars, and the refinement left twice the copy
    borders of a single-exemplar synthesis.)"""
    scale = 2 ** level
    origins = [(y // scale, x // scale) for y, x in atlas.origins]
    extents = [tuple(-(-s[k] // scale) for k in (0, 1)) for s in atlas.shapes]
    frame = tuple(max(e[k] for e in extents) for k in (0, 1))
    own = []  # bool frame: the local positions allowed in each exemplar
    for (y, x), (h, w) in zip(origins, extents):
        mask = np.zeros(frame, bool)
        mask[:h, :w] = allowed[y:y + h, x:x + w]
        own.append(mask)
    union = np.logical_or.reduce(own)
    rows, cols = np.nonzero(union)
    lo = np.array([rows.min(), cols.min()], np.float64)
    hi = np.array([rows.max(), cols.max()], np.float64)
    pos = organise(frame, out_shape, jac, lo, hi, opts, wrap=opts.tileable, seed=opts.seed,
                   allowed=union)
    if np.allclose(jac, np.eye(2)):
        pos = np.rint(pos)
    ids, count = continuing_regions(pos, np.asarray(jac, np.float64), opts.tileable,
                                    START_TOLERANCE)
    sizes = np.bincount(ids.ravel(), minlength=count).astype(np.float64)
    iy = np.clip(np.rint(pos[..., 0]).astype(np.int64), 0, frame[0] - 1)
    ix = np.clip(np.rint(pos[..., 1]).astype(np.int64), 0, frame[1] - 1)
    fits = np.stack([np.bincount(ids.ravel(), mask[iy, ix].ravel().astype(np.float64),
                                 minlength=count) for mask in own], axis=1)
    target = np.array([mask.sum() for mask in own], np.float64)
    target /= target.sum()
    rng = np.random.default_rng(opts.seed)
    choice = np.zeros(count, np.int64)
    assigned = np.zeros(len(own))
    for region in rng.permutation(count):
        deficit = target * (assigned.sum() + sizes[region]) - assigned
        # ties (equal deficits, at the start) broken at random
        deficit += 1e-9 * rng.random(len(own))
        deficit[fits[region] < fits[region].max()] = -np.inf
        k = int(np.argmax(deficit))
        choice[region] = k
        assigned[k] += sizes[region]
    offset = np.array(origins, np.float64)[choice[ids]]
    return snap((pos + offset).astype(np.float32), allowed)

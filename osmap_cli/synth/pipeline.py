"""The synthesis pipeline: pyramid -> organise (OS-Map, coarsest level) -> refine at every level
-> render. `synthesize` is the library entry point behind `osmap synth`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from osmap_cli.synth.ahead import LevelsAhead, Meanwhile, level_inputs
from osmap_cli.synth.lattice import Lattice
from osmap_cli.synth.options import SynthOptions
from osmap_cli.synth.organise import organise
from osmap_cli.synth.refine import refine, upsample
from osmap_cli.synth.regular import (
    RegionLattices,
    guide_regions,
    level_labels,
    level_lattice,
    region_lattices,
    resolve_lattice,
    wrapped,
)
from osmap_cli.synth.render import render, render_settings
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
    # the lattice the output keeps (--lattice), one per region of a painted exemplar guide, or None
    lattice: Lattice | RegionLattices | None = None


@dataclass(frozen=True)
class LevelLoop:
    """What a coarse-to-fine run needs besides the options: `osmap synth`, `--also` (an atlas)
    and `inpaint` / `tileable` (pinned pixels) differ only in these (see run_levels).

    pyramid: the source images, finest first; out_shapes: the output (H, W) of each level.
    jacobian_field(out_shape) -> float32 (H, W, 2, 2).
    bounds(level, source_shape, jac_field) -> (lo, hi), the positions a candidate may take.
    constraint(level, lo, hi) -> LevelConstraint or None (pinned pixels, forbidden positions).
    start(level, lo, hi, constraint) -> the coarsest level's positions float (H, W, 2).
    guides: per level (exemplar guide, output guide), or None (guided synthesis).
    rounds: refinements per level; round r > 0 computes its features from
    restyle(level, previous round's source image, pos) (a hole matched against its own fill).
    lattice: the exemplar's lattice (osmap_cli.synth.lattice.Lattice, finest level) or None;
    find_lattice() -> the lattice instead, asked for once the coarsest level's start is laid
    out (found meanwhile on another thread: synthesize's automatic lattice);
    out_lattice: the output's when it differs (tileable: osmap_cli.synth.regular.wrapped);
    lattice_phase(level) -> the level's exemplar phase map (an atlas;
    osmap_cli.synth.regular.atlas_phase); pinned_phase: the output's lattice phase is 0
    (pinned pixels at their own positions), else the field's.
    """

    pyramid: list
    out_shapes: list
    jacobian_field: Callable
    bounds: Callable
    start: Callable
    constraint: Callable | None = None
    guides: list | None = None
    rounds: int = 1
    restyle: Callable | None = None
    lattice: Lattice | None = None
    find_lattice: Callable | None = None
    out_lattice: Lattice | None = None
    lattice_phase: Callable | None = None
    pinned_phase: bool = False


def run_levels(loop: LevelLoop, opts: SynthOptions, progress=None):
    """The pyramid levels, coarsest first: start (or upsample the coarser level's positions,
    then pin), then `loop.rounds` refinements of opts.sweeps (opts.coarse_sweeps at the
    coarsest level) coherence sweeps. Returns (positions, the finest level's jacobian field,
    its constraint). `progress` gets fractions of the whole work."""
    levels = len(loop.pyramid)
    total = float(1 + loop.rounds * (opts.coarse_sweeps + opts.sweeps * (levels - 1))) or 1.0

    def advance(units):
        if progress is not None:
            progress(units / total)

    def frame(level):
        jac = loop.jacobian_field(loop.out_shapes[level])
        return (jac, *loop.bounds(level, loop.pyramid[level].shape[:2], jac))

    # the exemplar's features and k-NN table of every level are computed ahead, on a helper
    # thread, while the main thread trains the OS-Map and refines the coarser levels (ahead.py)
    ahead = LevelsAhead(opts)
    try:
        frames = {}
        for level in range(levels - 1, -1, -1):
            frames[level] = frame(level)
            ahead.submit(level, loop.pyramid[level], *frames[level][1:])
            if level == levels - 1:
                ahead.load_kernels()
        return _levels(loop, opts, levels, frames, ahead, advance)
    finally:
        ahead.close()


def _levels(loop: LevelLoop, opts: SynthOptions, levels: int, frames: dict, ahead, advance):
    """run_levels' loop over the levels, coarsest first (`frames`: each level's (jacobian field,
    lo, hi), submitted; each is dropped as its level starts)."""
    pos = constraint = None
    exemplar_lattice = loop.lattice
    for level in range(levels - 1, -1, -1):
        image = loop.pyramid[level]
        jac_field, lo, hi = frames.pop(level)
        constraint = None if loop.constraint is None else loop.constraint(level, lo, hi)
        if pos is None:
            pos = loop.start(level, lo, hi, constraint)
            ahead.trained()
            advance(1)
            sweeps = opts.coarse_sweeps
        else:
            pos = upsample(pos, loop.out_shapes[level], jac_field, lo, hi)
            if constraint is not None:
                pos = constraint.pin(pos)
            sweeps = opts.sweeps
        if loop.find_lattice is not None and level == levels - 1:
            exemplar_lattice = loop.find_lattice()
        lattice = None
        if exemplar_lattice is not None:
            phases = None if loop.lattice_phase is None else loop.lattice_phase(level)
            lattice = level_lattice(exemplar_lattice, 2 ** level, jac_field[0, 0], pos, lo, hi,
                                    phases, pinned_phase=loop.pinned_phase,
                                    output=loop.out_lattice)
            if lattice is not None:
                pos = lattice.snap(pos, lo, hi)
                if constraint is not None:
                    pos = constraint.pin(pos)
        for round_ in range(loop.rounds):
            if round_:
                image = loop.restyle(level, image, pos)
                feat, knn = level_inputs(image, lo, hi, opts)
            else:
                feat, knn = ahead.take(level)
            pos = refine(pos, feat, jac_field, lo, hi, sweeps, opts, wrap=opts.tileable,
                         seed=opts.seed, salt=level + 100 * round_, level_scale=2 ** level,
                         coarsest_scale=2 ** (levels - 1), progress=advance,
                         constraint=constraint, lattice=lattice, knn=knn,
                         guides=None if loop.guides is None else loop.guides[level])
    return pos, jac_field, constraint


def uniform_jacobian(jac: np.ndarray) -> Callable:
    """A LevelLoop.jacobian_field: the same 2x2 Jacobian at every pixel of every level."""
    def field(shape):
        return np.broadcast_to(np.asarray(jac, np.float32), (*shape, 2, 2)).copy()
    return field


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
    options.guide_weight (method osmap only). A `guide` painted in a few values (a map of
    materials, osmap_cli.synth.regular.guide_regions) makes each value's region a material of
    its own: its own OS-Map layout at the start and its own lattice (or none).
    """
    opts = options.validated().with_quality()
    exemplar = np.ascontiguousarray(exemplar, np.float32)
    if fields is not None and opts.method != "osmap":
        raise ValueError("control fields need method 'osmap'")
    if guide is not None and target_guide is None:
        raise ValueError("a guide needs a target_guide")
    painted = guide is not None
    regions = None
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
        regions = guide_regions(guide) if painted and opts.method == "osmap" else None
    found = None
    if regions is not None and opts.lattice == "auto" and fields is None:
        lattice = _region_lattices(opts, exemplar, regions)
    elif (opts.lattice == "auto" and opts.method == "osmap" and fields is None
          and not opts.tileable):
        # found while the coarsest level's OS-Map trains, which does not use it
        lattice, found = None, Meanwhile(resolve_lattice, opts.lattice, exemplar)
    else:
        lattice = _lattice(opts, exemplar, fields is not None)
    if opts.method == "paper":
        from osmap_cli.synth.paper import synthesize_paper
        pos = synthesize_paper(exemplar.shape[:2], opts, progress=progress)
        return SynthResult(render(exemplar, pos), pos)

    out_shape = (opts.height, opts.width)
    levels = level_count([exemplar.shape[:2]], out_shape, opts.levels, min_size=MIN_LEVEL_SIZE)
    jac = opts.jacobian()
    if fields is not None:
        # the OS-Map lays out the coarsest level with one Jacobian summarising the fields;
        # the refinement then follows the per-pixel field at every level
        angle, scale = fields.representative(opts.orientation, opts.scale)
        jac = opts.replace(orientation=angle, scale=scale).jacobian()

    def jacobian_field(shape):
        if fields is None:
            return uniform_jacobian(jac)(shape)
        return fields.jacobian_field(shape, opts.orientation, opts.scale, opts.anisotropy)

    def bounds(level, shape, jac_field):
        reach = jac if fields is None else np.abs(jac_field).max(axis=(0, 1))
        return valid_box(shape, reach, opts.patch_radius)

    def start(level, lo, hi, constraint):
        if regions is not None:
            pos = _regional_start(regions, pyramid[level].shape[:2], guides[level][1],
                                  2 ** level, jac, lo, hi, opts)
        else:
            pos = organise(pyramid[level].shape[:2], shapes[level], jac, lo, hi, opts,
                           wrap=opts.tileable, seed=opts.seed)
        if fields is None and np.allclose(jac, np.eye(2)):
            pos = np.rint(pos)
        return pos

    guides = None
    if target_guide is not None:
        from osmap_cli.synth.guide import guide_levels
        values = None if regions is None else regions[0]
        guides = list(zip(guide_levels(guide, exemplar.shape[:2], levels, values),
                          guide_levels(target_guide, out_shape, levels, values)))
    pyramid = build_pyramid(exemplar, levels)
    shapes = level_shapes(out_shape, levels)
    out_lattice = None
    if isinstance(lattice, RegionLattices) and opts.tileable:
        lattice = _wrapped_regions(lattice, out_shape, jac, opts.max_copy or min(out_shape))
    elif lattice is not None and opts.tileable:
        out_lattice = wrapped(lattice, out_shape, jac, opts.max_copy or min(out_shape))
        lattice = lattice if out_lattice is not None else None
    pos, jac_field, _ = run_levels(LevelLoop(pyramid, shapes, jacobian_field, bounds, start,
                                             guides=guides, lattice=lattice,
                                             find_lattice=None if found is None else found.result,
                                             out_lattice=out_lattice), opts, progress)
    if found is not None:
        lattice = found.result()
    pixels = render(exemplar, pos, jac_field, *render_settings(opts))
    return SynthResult(pixels, pos, None if fields is None else jac_field, lattice)


def _lattice(opts: SynthOptions, exemplar: np.ndarray, fields: bool) -> Lattice | None:
    """The lattice `opts.lattice` asks for; vectors given by hand need what a lattice needs
    (method osmap, no control fields), auto finds none without it."""
    given = opts.lattice not in ("auto", "off")
    if opts.method != "osmap" or fields:
        if given:
            what = "--method paper" if opts.method != "osmap" else "control fields"
            raise ValueError(f"--lattice {opts.lattice} does not combine with {what} (a "
                             "lattice needs one orientation and scale for the whole output)")
        return None
    return resolve_lattice(opts.lattice, exemplar)


def _region_lattices(opts: SynthOptions, exemplar: np.ndarray, regions
                     ) -> RegionLattices | None:
    """With an exemplar guide painted in a few values (a map of materials: `regions`,
    guide_regions' answer), a lattice per region, each read from that region alone: the
    several-material exemplar's lattice belongs to one material at most, and a material
    beside it keeps its own (or none)."""
    per_region = region_lattices(opts.lattice, exemplar, regions)
    return per_region if per_region.any() else None


def _wrapped_regions(lattice: RegionLattices, out_shape, jac, span: float
                     ) -> RegionLattices | None:
    """A tileable output's lattice per region (`wrapped`): a region whose lattice does not fit
    a whole number of times across the output keeps none."""
    outputs = tuple(None if lat is None else wrapped(lat, out_shape, jac, span)
                    for lat in lattice.lattices)
    lattices = tuple(lat if out is not None else None
                     for lat, out in zip(lattice.lattices, outputs))
    kept = RegionLattices(lattice.values, lattice.labels, lattices, outputs)
    return kept if kept.any() else None


def _regional_start(regions, source_shape, target, level_scale: int, jac, lo, hi,
                    opts: SynthOptions) -> np.ndarray:
    """The coarsest level's positions for an exemplar guide painted in a few values: an OS-Map
    layout of each region's own positions (as if synthesizing that material alone), each
    output pixel taking the layout of the region whose value is nearest its target guide. A
    layout of the whole exemplar would mix the materials in its copies, and the guided sweeps
    would then cut each half out of them in small pieces."""
    values, labels = regions
    labels = level_labels(labels, level_scale)
    nearest = np.abs(np.asarray(target, np.float64)[..., None]
                     - np.asarray(values)[None, None, :]).argmin(axis=2)
    pos = np.zeros((*target.shape, 2), np.float32)
    missing = np.ones(target.shape, bool)
    for r in range(len(values)):
        allowed = labels == r
        box = allowed[int(np.ceil(lo[0])):int(hi[0]) + 1, int(np.ceil(lo[1])):int(hi[1]) + 1]
        if not (nearest == r).any() or not box.any():
            continue
        rows, cols = np.flatnonzero(allowed.any(axis=1)), np.flatnonzero(allowed.any(axis=0))
        shape = (rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1)
        # the region's own valid box: its copies stop at its edges, as a material's alone do
        # at the exemplar's, instead of running into the next material
        first, last = np.array([rows[0], cols[0]]), np.array([rows[-1], cols[-1]])
        edge = np.array(labels.shape) - 1
        box_lo = np.minimum(np.maximum(lo, first + lo), hi)
        box_hi = np.maximum(np.minimum(hi, last - (edge - hi)), box_lo)
        inside = allowed[int(np.ceil(box_lo[0])):int(box_hi[0]) + 1,
                         int(np.ceil(box_lo[1])):int(box_hi[1]) + 1]
        if not inside.any():  # too small at this level for a window of its own
            continue
        layout = organise(shape, target.shape, jac, box_lo, box_hi, opts, wrap=opts.tileable,
                          seed=opts.seed, allowed=allowed)
        pos[nearest == r] = layout[nearest == r]
        missing &= nearest != r
    if missing.any():  # a region with no position of its own at this level
        whole = organise(source_shape, target.shape, jac, lo, hi, opts, wrap=opts.tileable,
                         seed=opts.seed)
        pos[missing] = whole[missing]
    return pos

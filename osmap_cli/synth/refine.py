"""Refine: coherence sweeps on the position field, and upsampling between pyramid levels."""

from __future__ import annotations

import math

import numpy as np

from osmap_cli.synth.options import SynthOptions
from osmap_cli.texture.features import feature_variance
from osmap_cli.texture.occupancy import occupancy
from osmap_cli.texture.references import SYNTH_REFERENCES as MAX_KNN_REFERENCES
from osmap_cli.texture.references import similar_positions
from osmap_kernels.coherence import RefineParams, refine_pass, usage_counts
from osmap_kernels.lattice import NO_LATTICE
from osmap_kernels.regions import AlignParams, align_regions, copy_region_areas

# Whole-copy shifts are judged on the 3x3 neighbourhoods across a copy's border: as good as the
# matching window (5x5) on the 11 development exemplars, at a quarter of the cost.
ALIGN_RADIUS = 1
# guide cost of a whole mismatch (guide difference 1) at guide_weight 1, in window feature
# variances: 0.75 times a random window's expected SSD (2 variances). On the two-material test
# (tests/test_guide.py, seeds 1-3) weight 1 keeps 97-100 % of each half in its material with
# texmetrics coherence 1.2-1.8x unguided; twice this unit gave 100 % but 1.4-1.8x; 0.6 of it
# let the larger copies spill over 8-28 % of the other half
GUIDE_UNIT = 1.5
# unguided: the kernel's guide arrays (not read when the guide weight is 0)
_NO_GUIDE = np.zeros((1, 1), np.float32)


def refine(pos: np.ndarray, feat: np.ndarray, jac_field: np.ndarray, lo, hi, sweeps: int,
           opts: SynthOptions, *, wrap: bool, seed: int, salt: int, level_scale: int = 1,
           coarsest_scale: int = 1, progress=None, constraint=None, guides=None,
           lattice=None, knn=None) -> np.ndarray:
    """`sweeps` red-black coherence sweeps over pos (H, W, 2); returns the new field.

    `constraint` (osmap_cli.synth.constraints.LevelConstraint, optional) pins some pixels to
    known positions and forbids some exemplar positions (inpainting, tileable photos).
    `guides` (optional): this level's (exemplar guide float32 (h, w), output guide float32
    (H, W)); each candidate then costs opts.guide_weight * (guide difference)^2 more, in units of
    a whole window's feature variance (osmap_cli.synth.guide).
    `lattice` (osmap_cli.synth.regular.LevelLattice, optional): every candidate is snapped to a
    position consistent with the lattice, and whole copies move only along it (pos should be
    consistent already: LevelLattice.snap).
    `knn` (optional): feat's k-NN table (knn_candidates), when it is computed already."""
    # C order whatever made pos (upsample's arithmetic keeps a strided layout): the kernels then
    # compile, load and run for one array layout only
    pos = np.ascontiguousarray(pos, np.float32)
    if knn is None:
        knn = knn_candidates(feat, lo, hi, opts)
    # seam penalty unit: a whole window's feature variance, shared among the 8 neighbours
    variance = feature_variance([feat])
    window = (2 * opts.patch_radius + 1) ** 2
    seam = float(opts.seam) * variance * window / 8.0
    gex = gout = _NO_GUIDE
    guide = 0.0
    if guides is not None and opts.guide_weight > 0:
        gex, gout = (np.ascontiguousarray(g, np.float32) for g in guides)
        guide = GUIDE_UNIT * float(opts.guide_weight) * variance * window
    # max_copy is a side in finest-level pixels; this level's pixels are level_scale times larger
    max_area = (opts.max_copy / level_scale) ** 2 if opts.max_copy > 0 else np.inf
    area = np.zeros(pos.shape[:2], np.float32)
    for sweep in range(sweeps):
        occ = _occupancy(pos, feat.shape[:2], constraint)
        lam = float(opts.occupancy)
        if constraint is not None:
            occ, lam = constraint.penalise(occ, lam)
        for parity in (0, 1):
            params = RefineParams(
                radius=opts.patch_radius, lam=lam, wrap=wrap,
                lo=_pair(lo), hi=_pair(hi), n_random=opts.random_candidates, seed=np.uint64(seed),
                salt=np.uint64(salt * 1000 + sweep * 2 + parity), parity=parity,
                seam=seam, max_area=float(max_area), guide=guide)
            if math.isfinite(max_area):
                area = copy_region_areas(pos if constraint is None else constraint.unlinked(pos),
                                         jac_field, wrap)
            out = pos.copy()
            if lattice is None:
                refine_pass(pos, out, feat, jac_field, knn, occ, area, gex, gout, params)
            else:
                refine_pass(pos, out, feat, jac_field, knn, occ, area, gex, gout, params,
                            lattice.params, lattice.phase_map, lattice.table, lattice.regions)
            pos = out if constraint is None else constraint.pin(out)
        if opts.align > 0 and sweep < sweeps - 1:
            # the last sweep settles the borders of the copies' final placement
            pos = align_regions(pos, feat, jac_field, AlignParams(
                radius=ALIGN_RADIUS, wrap=wrap, lo=np.asarray(lo, np.float64),
                hi=np.asarray(hi, np.float64), seam=seam, max_area=float(max_area),
                reach=align_reach(opts.align, level_scale, coarsest_scale),
                lattice=NO_LATTICE if lattice is None else lattice.params))
            if lattice is not None and lattice.regional:
                # shifts were free (each region its own lattice): back onto each one's
                pos = lattice.snap(pos, lo, hi)
            if constraint is not None:
                pos = constraint.pin(pos)
        if progress is not None:
            progress(1)
    return pos


def knn_candidates(feat: np.ndarray, lo, hi, opts: SynthOptions) -> np.ndarray:
    """The k-NN table of feat's positions inside [lo, hi] that refine's kernel reads."""
    knn = similar_positions(feat, lo, hi, opts.knn, MAX_KNN_REFERENCES)
    if opts.knn == 0:
        knn = np.ascontiguousarray(knn[:, :, :0])  # one array layout for the kernel
    return knn


def _occupancy(pos: np.ndarray, source_shape, constraint) -> np.ndarray:
    """The occupancy of the exemplar (h, w) by pos, or by the positions `constraint` counts.
    A function of its own so that nothing keeps this sweep's pos alive into the next (at
    4096x4096 one position field is 128 MiB)."""
    used, samples = ((pos, pos.shape[0] * pos.shape[1]) if constraint is None else
                     constraint.counted(pos, source_shape[0] * source_shape[1]))
    return occupancy(usage_counts(used, *source_shape), samples)


def _pair(values) -> tuple[float, float]:
    """A (row, col) bound as a tuple of two floats for a kernel's parameter record: read there
    without the atomic reference counting that an array field costs on every access."""
    return float(values[0]), float(values[1])


def align_reach(align: int, level_scale: int, coarsest_scale: int) -> int:
    """Whole-copy shifts tried at a level: up to `align` pixels at the coarsest level, half as
    many at each finer one (at least 1): the coarser levels have already placed the copies to
    within a pixel or two there (measured: the same quality as the full reach at every level,
    for a fraction of the cost at large sizes)."""
    if align == 0:
        return 0
    return max(1, align * level_scale // max(coarsest_scale, 1))


def upsample(pos: np.ndarray, out_shape, jac_field: np.ndarray, lo, hi) -> np.ndarray:
    """Positions for the next finer level: 2 S[p // 2] + J (p mod 2), kept inside [lo, hi]."""
    H, W = out_shape
    ys = np.minimum(np.arange(H) // 2, pos.shape[0] - 1)
    xs = np.minimum(np.arange(W) // 2, pos.shape[1] - 1)
    dy = (np.arange(H) - 2 * ys).astype(np.float32)
    dx = (np.arange(W) - 2 * xs).astype(np.float32)
    coarse = pos[ys][:, xs]
    offset = (jac_field[..., :, 0] * dy[:, None, None] + jac_field[..., :, 1] * dx[None, :, None])
    fine = 2.0 * coarse + offset
    fine[..., 0] = np.clip(fine[..., 0], lo[0], hi[0])
    fine[..., 1] = np.clip(fine[..., 1], lo[1], hi[1])
    return fine.astype(np.float32)

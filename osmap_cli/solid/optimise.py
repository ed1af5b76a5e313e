"""Texture optimisation over the three slice neighbourhoods of every voxel (Kopf et al. 2007),
coarse to fine, with the optional sharpening passes of method osmap.

Per level (a `SolidLevel` of n x n windows, osmap_cli.solid.core.window_level): search (every
window centre and axis: the nearest exemplar window in the level's PCA space), then optimise
(every voxel: the IRLS-weighted mean, exponent r, of the colours the covering windows of all
three axes place on it, each weight divided by the colour and exemplar-position histogram excess
of the pixel it proposes). With `Sharpening`, the last passes of a level give each voxel the
single exemplar colour that the windows agree on (docs/solid.md, "Method"). With `Polish`, more
iterations follow the finest level's, with the guides and the label constraint weakened.

`optimise` reads only its arguments: the levels, the coarsest level's starting positions and an
`Optimisation` record, so a method can hand it levels built differently (extra channels in the
windows, say) or start it from its own layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.solid.core import SolidLevel, SolidTask, window_level
from osmap_cli.solid.upsample import upsample_linear, upsample_positions
from osmap_kernels.kopf import (
    KopfAverage,
    KopfSearch,
    fill_positions,
    kopf_average,
    kopf_average_labelled,
    kopf_cluster,
    kopf_cluster_labelled,
    kopf_pick,
    kopf_search,
    position_counts,
)

HIST_BINS = 16
EPS = 1e-6


@dataclass(frozen=True)
class Sharpening:
    """Passes that give each voxel one exemplar colour instead of the windows' mean."""

    passes: int  # the last `passes` iterations of a level sharpen
    levels: int  # at the finest `levels` levels only
    finest: bool  # the finest level sharpens too
    final: bool  # ... including its last iteration (else the volume is its average)
    bandwidth: float  # mean shift within this squared colour distance (relative to the colour
    #                   variance) of the densest proposal; 0: pick the best-agreeing window
    steps: int  # mean-shift steps from the weighted mean instead; 0: densest cluster
    cross: bool  # a proposal's density counts only the other two slice families'
    pick_support: int  # bandwidth 0: half-size of the area a window must agree over


@dataclass(frozen=True)
class Polish:
    """Iterations after the finest level's, from its volume and positions (method structure:
    the structure is set by then, so the windows may match the exemplar more freely)."""

    iterations: int  # 0: none
    guides: bool = False  # the windows keep their guide channels (else colours only)
    label_mismatch: float = 1.0  # the label constraint's weight in the averaging (1: none)
    discrete: bool = False  # the last iteration copies each voxel's heaviest proposal


@dataclass(frozen=True)
class Optimisation:
    """What the optimisation reads (methods osmap and kopf build it from SolidOptions)."""

    stride: int  # window centres every `stride` voxels in each plane
    iterations: int  # search + average iterations per level
    r: float  # robust norm exponent: IRLS weight = distance ** (r - 2)
    colour_histogram: float  # strength of the colour histogram weight (0: none)
    position_histogram: float  # strength of the exemplar-position histogram weight
    falloff: float = 0.0  # window centre weighting exp(-falloff d^2 / (n/2)^2); 0: flat
    upsample_render: bool = False  # a finer level starts from the exemplar colours at the
    #                                upsampled positions (else the coarser volume interpolated)
    sharpening: Sharpening | None = None
    polish: Polish | None = None  # more iterations at the finest level, the structure set


def quality_scaled(quality: str, iterations: int, knn: int) -> tuple[int, int]:
    """(iterations per level, similar-position candidates) for --quality: fast: one iteration
    and at most one candidate; high: one iteration and two candidates more."""
    if quality == "fast":
        return 1, min(knn, 1)
    if quality == "high":
        return iterations + 1, knn + 2
    return iterations, knn


def window_levels(task: SolidTask, *, window: int, dims: int, knn: int) -> list[SolidLevel]:
    """Every level of the task as n x n windows (osmap_cli.solid.core.window_level)."""
    return [window_level(task, index, window=window, dims=dims, knn=knn)
            for index in range(task.levels)]


def colour_weights(vol, images, ex_of_axis, strength: float) -> np.ndarray:
    """float32 (E, H, W): 1 / (1 + strength * sum over channels of the volume's relative excess
    in the colour bin of each exemplar pixel) (Kopf et al.: minority colours are not averaged
    away)."""
    used = sorted(set(int(e) for e in ex_of_axis))
    ref = np.concatenate([images[e].reshape(-1, images.shape[3]) for e in used])
    lo, hi = ref.min(axis=0), ref.max(axis=0)
    span = np.maximum(hi - lo, 1e-6)
    flat = vol.reshape(-1, vol.shape[3])
    excess = np.zeros(images.shape[:3], np.float64)
    for ch in range(images.shape[3]):
        def bins(values, ch=ch):
            return np.clip(((values - lo[ch]) / span[ch] * HIST_BINS).astype(np.int64), 0,
                           HIST_BINS - 1)
        h_ex = np.bincount(bins(ref[:, ch]), minlength=HIST_BINS) / len(ref)
        h_vol = np.bincount(bins(flat[:, ch]), minlength=HIST_BINS) / len(flat)
        ratio = np.maximum(h_vol / np.maximum(h_ex, 1e-9) - 1.0, 0.0)
        excess += ratio[bins(images[..., ch])]
    return (1.0 / (1.0 + strength * excess)).astype(np.float32)


def position_weights(pos, stride: int, n: int, ex_of_axis, ex_hw, strength: float):
    """float32 (E, H, W) for ex_hw = (E, H, W): 1 / (1 + strength * relative over-use of each
    exemplar pixel by the volume's n x n window matches) (the exemplar-position histogram)."""
    counts = position_counts(pos, stride, n, ex_of_axis, *ex_hw).astype(np.float64)
    used = counts > 0
    expected = counts.sum() / max(int(used.sum()), 1)
    return (1.0 / (1.0 + strength * np.maximum(counts / expected - 1.0, 0.0))).astype(np.float32)


def random_positions(level: SolidLevel, ex_of_axis, seed: int) -> np.ndarray:
    """int32 (3, Z, Y, X, 2): uniform valid window centres (Kopf's random initialisation)."""
    rng = np.random.default_rng(seed)
    pos = np.empty((3, *level.shape, 2), np.int32)
    for a in range(3):
        e = ex_of_axis[a]
        for j in range(2):
            pos[a, ..., j] = rng.integers(level.lo[e, j], level.hi[e, j] + 1, level.shape)
    return pos


def optimise(task: SolidTask, levels: list[SolidLevel], start: np.ndarray,
             opt: Optimisation, progress=None, guides=None, initial=None, labels=None):
    """(voxels float32 (Z, Y, X, C), source int32 (Z, Y, X, 3)) of the finest level: the
    levels (finest first, one per task level) optimised from the coarsest, whose window centres
    start at `start` int32 (3, Z, Y, X, 2). `guides`: per level (finest first), float32
    (3, Z, Y, X, G): guide channels every slice family's windows carry beside the colours (the
    levels' search features then cover colours and guides alike; their `stacked` images, which
    are averaged, the colours only). `initial`: the coarsest volume's colours for the first
    search (default: the average of the start positions' windows). `labels`: per level (finest
    first), None or (volume int32 (Z, Y, X), exemplars int32 (E, H, W), mismatch): the
    averaging and the sharpening weigh proposals from exemplar pixels of another label
    `mismatch` times as much (kernels' kopf_average_labelled, kopf_cluster_labelled; the
    pick of bandwidth 0 reads no labels)."""
    ex_of_axis = task.ex_of_axis
    total = float(len(levels) * opt.iterations)
    done = 0.0
    pos = vol = source = prev = None
    for index in range(len(levels) - 1, -1, -1):
        level = levels[index]
        n, imgs, vshape = level.window, level.stacked, level.shape
        search = dict(size=n, stride=opt.stride, wrap=task.tileable, n_random=0, lo=level.lo,
                      hi=level.hi, seed=np.uint64(task.seed))
        off = np.arange(n, dtype=np.float64) - n // 2
        window = np.exp(-opt.falloff * (off[:, None] ** 2 + off[None, :] ** 2)
                        / max((n / 2.0) ** 2, 1.0))
        average = KopfAverage(size=n, stride=opt.stride, wrap=task.tileable, window=window)
        dist = np.ones((3, *vshape), np.float32)
        flat_weights = np.ones(imgs.shape[:3], np.float32)
        coarsest = pos is None
        source = np.empty((*vshape, 3), np.int32)
        if coarsest:
            pos = start
        else:
            filled = np.empty_like(pos)
            fill_positions(pos, opt.stride, prev.lo, prev.hi, ex_of_axis, filled)
            pos = upsample_positions(filled, vshape, level.lo, level.hi, ex_of_axis)
        if coarsest and initial is not None:
            vol = np.ascontiguousarray(initial, np.float32)
        elif coarsest or opt.upsample_render:
            # a finer level starts from its own exemplar detail at the upsampled positions,
            # not from the coarser volume blurred by interpolation (a blurred start makes the
            # search prefer smooth exemplar areas: features grow)
            vol = np.empty((*vshape, imgs.shape[3]), np.float32)
            kopf_average(pos, dist, imgs, ex_of_axis, flat_weights, average, vol, source)
        else:
            vol = upsample_linear(vol, vshape, task.tileable)
        for it in range(opt.iterations):
            params = KopfSearch(exhaustive=coarsest and it == 0,
                                salt=np.uint64(index * 1000 + it), **search)
            guide = guides[index] if guides is not None else None
            constraint = labels[index] if labels is not None else None
            vol, pos, source = _iterate(task, level, vol, pos, dist, guide, constraint, opt,
                                        params, average, _sharpens(opt, index, it))
            done += 1
            if progress is not None:
                progress(done / total)
        prev = level
    if opt.polish is not None and opt.polish.iterations > 0:
        guide = guides[0] if guides is not None else None
        constraint = labels[0] if labels is not None else None
        vol, source = polish(task, levels[0], vol, pos, dist, guide, constraint, opt, average,
                             search)
    return np.ascontiguousarray(vol, np.float32), np.ascontiguousarray(source, np.int32)


def polish(task: SolidTask, level: SolidLevel, vol, pos, dist, guide, constraint,
           opt: Optimisation, average, search):
    """(voxels, source) after `opt.polish.iterations` more iterations at the finest level,
    from its volume and window positions: the structure is set, so the windows may now match
    the exemplar more freely (guides off, label constraint weaker), and with `discrete` the
    last one gives each voxel its heaviest proposal's exemplar colour (Chen and Wang 2010's
    discrete solver) instead of the mean."""
    spec = opt.polish
    if not spec.guides and guide is not None:
        level = window_level(task, 0, window=level.window, dims=level.basis.shape[1],
                             knn=level.knn.shape[3])
        guide = None
    if constraint is not None:
        constraint = (constraint[0], constraint[1], spec.label_mismatch)
        if spec.label_mismatch >= 1.0:
            constraint = None
    source = None
    for it in range(spec.iterations):  # salts apart from the finest level's 0 .. iterations
        params = KopfSearch(exhaustive=False, salt=np.uint64(900 + it), **search)
        vol, pos, source = _iterate(task, level, vol, pos, dist, guide, constraint, opt,
                                    params, average, False)
    if spec.discrete:
        e = np.asarray(task.ex_of_axis)[source[..., 0]]
        vol = level.stacked[e, source[..., 1], source[..., 2]]
    return vol, source


def _iterate(task: SolidTask, level: SolidLevel, vol, pos, dist, guide, constraint,
             opt: Optimisation, params: KopfSearch, average: KopfAverage, sharpen: bool):
    """One search + average (+ sharpening) iteration: (voxels, positions, source)."""
    ex_of_axis = task.ex_of_axis
    imgs, n = level.stacked, level.window
    if guide is None:
        guide = np.zeros((3, 1, 1, 1, 0), np.float32)
    new_pos = np.empty_like(pos)
    kopf_search(vol, guide, pos, new_pos, dist, level.feats, level.basis, level.mean,
                ex_of_axis, level.knn, params)
    pos = new_pos
    weights = np.ones(imgs.shape[:3], np.float32)
    if opt.colour_histogram > 0:
        weights = weights * colour_weights(vol, imgs, ex_of_axis, opt.colour_histogram)
    if opt.position_histogram > 0:
        weights = weights * position_weights(pos, opt.stride, n, ex_of_axis, imgs.shape[:3],
                                             opt.position_histogram)
    averaged = np.empty_like(vol)
    source = np.empty((*vol.shape[:3], 3), np.int32)
    eps = EPS * level.basis.shape[0]
    cw = ((dist.astype(np.float64) + eps) ** ((opt.r - 2.0) / 2.0)).astype(np.float32)
    if constraint is None:
        kopf_average(pos, cw, imgs, ex_of_axis, weights, average, averaged, source)
    else:
        kopf_average_labelled(pos, cw, imgs, ex_of_axis, weights, average, constraint[1],
                              constraint[0], constraint[2], averaged, source)
    if not sharpen:
        return averaged, pos, source
    sharp = np.empty_like(vol)
    s = opt.sharpening
    if s.bandwidth > 0 and constraint is not None:
        kopf_cluster_labelled(pos, cw, imgs, ex_of_axis, weights, average,
                              s.bandwidth * level.variance, s.steps, s.cross, constraint[1],
                              constraint[0], constraint[2], sharp, source)
    elif s.bandwidth > 0:
        kopf_cluster(pos, cw, imgs, ex_of_axis, weights, average, s.bandwidth * level.variance,
                     s.steps, s.cross, sharp, source)
    else:
        kopf_pick(pos, imgs, ex_of_axis, averaged, average, s.pick_support, sharp, source)
    return sharp, pos, source


def _sharpens(opt: Optimisation, level: int, it: int) -> bool:
    """Whether iteration `it` of `level` (0: finest) ends with a sharpening pass."""
    s = opt.sharpening
    if s is None or s.passes == 0:
        return False
    last = level == 0 and it == opt.iterations - 1
    return (level < s.levels and it >= opt.iterations - s.passes and (s.final or not last)
            and (level > 0 or s.finest))

"""The appearance of a structured volume: Kopf et al.'s slice-window texture optimisation, coarse
to fine, with guide channels (Kaspar et al. 2015's idea in 3D): every window carries, beside its
colours, the structure as its slice shows it (the in-plane distance to the nearest phase
boundary, clipped; the identity of the particle or phase: the mean colour of its source), and
the exemplar carries the same channels computed from its segmentation. Every voxel so takes
exemplar colour from the same kind of place: inside a stone near its rim, mid-vein, matrix.
Then each phase's colours are quantile-matched to the exemplar's pixels of that phase.

>>> voxels, source = fill(exemplars, ex_of_axis, ex_labels, ex_identity, labels, identity,
...                       FillParams(seed=1))
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.solid.kopf import (
    colour_weights,
    level_valid,
    pca_features,
    random_positions,
)
from osmap_cli.solid.pipeline import _stack, upsample_positions
from osmap_cli.solid.structure.measures import squared_distance
from osmap_cli.texture.pyramid import build_pyramid, resize
from osmap_cli.texture.references import similar_positions
from osmap_kernels.kopf import (
    KopfAverage,
    KopfSearch,
    fill_positions,
    kopf_average,
    kopf_cluster,
    position_counts,
)
from osmap_kernels.structure_fill import guided_search

MAX_KNN_REFERENCES = 4096
EPS = 1e-6
PLANE_AXES = ((0, 1), (0, 2), (1, 2))
REGION_VOXELS = 64.0  # volume dims (z, y, x) spanning family 0, 1, 2's slices


@dataclass(frozen=True)
class FillParams:
    """levels: pyramid levels; window: side n of the slice windows; iterations per level;
    stride: window centres every `stride` voxels; dims: PCA dimensions; knn: similar-position
    candidates; clip: the distance guide saturates this many pixels from a boundary;
    guide_weight: the guide channels' weight relative to the colours; colour / position:
    histogram weight strengths; r: robust norm exponent; layout: the coarsest positions from
    a given layout (the OS-Map's) instead of random ones."""

    seed: int = 0
    wrap: bool = False
    levels: int = 3
    window: int = 6
    iterations: int = 4
    stride: int = 2
    dims: int = 24
    knn: int = 2
    clip: float = 4.0
    guide_weight: float = 1.0
    colour: float = 1.0
    position: float = 3.0
    r: float = 0.8
    sharpen: int = 0  # the last `sharpen` iterations of every level take the densest cluster
    bandwidth: float = 0.25  # ... of proposals within this squared colour distance (x variance)
    sharpen_finest: bool = False  # ... at the finest level too


def distance_guide(labels: np.ndarray, axes, wrap: bool, clip: float) -> np.ndarray:
    """float32: the distance (within the subspace of `axes`) from every cell to the nearest cell
    of another label, measured between cell centres less half a cell, clipped, over `clip`."""
    out = np.zeros(labels.shape, np.float64)
    for value in np.unique(labels):
        inside = labels == value
        if inside.all():
            out[inside] = clip
            continue
        d = np.sqrt(squared_distance(~inside, wrap, axes))
        out[inside] = d[inside]
    return (np.minimum(np.maximum(out - 0.5, 0.0), clip) / clip).astype(np.float32)


def _coarse_labels(labels: np.ndarray, factor: int) -> np.ndarray:
    """Every factor-th cell (its centre sample): labels of a coarser level."""
    if factor == 1:
        return labels
    off = factor // 2
    return labels[tuple(slice(off, None, factor) for _ in range(labels.ndim))]


def _block_mean(values: np.ndarray, shape) -> np.ndarray:
    """values (Z, Y, X, C) averaged over blocks to `shape` (Z', Y', X')."""
    out = values
    for d, n in enumerate(shape):
        m = out.shape[d]
        if m == n:
            continue
        edges = np.linspace(0, m, n + 1).round().astype(int)
        out = np.add.reduceat(out, edges[:-1], axis=d) / np.diff(edges).reshape(
            [-1 if k == d else 1 for k in range(out.ndim)])
    return out.astype(np.float32)


def _level_shapes(shape, levels):
    shapes = [tuple(shape)]
    for _ in range(levels - 1):
        shapes.append(tuple(max(1, (n + 1) // 2) for n in shapes[-1]))
    return shapes


def fill(exemplars, ex_of_axis, ex_labels, ex_identity, labels, identity, params: FillParams,
         layout=None, progress=None):
    """(voxels float32 (Z, Y, X, C), source int32 (Z, Y, X, 3)).

    exemplars: float32 (H, W, C) images (one per distinct exemplar; ex_of_axis maps the three
    slice families to them); ex_labels / ex_identity: their segmentation (int (H, W)) and
    identity channels (float32 (H, W, I)); labels / identity: the volume's (Z, Y, X) and
    (Z, Y, X, I). layout(shape, ex_shapes, lo, hi): the coarsest positions, or None."""
    p = params
    n_ex = len(exemplars)
    shapes = _level_shapes(labels.shape, p.levels)
    pyramids = [build_pyramid(im, p.levels) for im in exemplars]
    colour_var = float(np.concatenate([im.reshape(-1, im.shape[2]) for im in exemplars])
                       .var(axis=0).sum()) + 1e-12
    scale = p.guide_weight * np.sqrt(colour_var)  # guide units: about the colours' spread
    total = float(p.levels * p.iterations)
    done = 0.0
    pos = vol = source = prev_lo = prev_hi = None
    for level in range(p.levels - 1, -1, -1):
        factor = 2 ** level
        level_images = [pyr[level] for pyr in pyramids]
        ex_shapes = [im.shape[:2] for im in level_images]
        hw = (max(s[0] for s in ex_shapes), max(s[1] for s in ex_shapes))
        n = min(p.window, min(min(s) for s in ex_shapes) - 2)
        # exemplar guides at this level
        ex_guides = []
        for e, im in enumerate(level_images):
            lab = _resample_labels(ex_labels[e], im.shape[:2])
            dist = distance_guide(lab, (0, 1), p.wrap, p.clip)
            ident = resize(ex_identity[e].astype(np.float32), *im.shape[:2])
            ex_guides.append(np.concatenate([dist[..., None], ident], 2) * scale)
        augmented = [np.concatenate([im, g], 2).astype(np.float32)
                     for im, g in zip(level_images, ex_guides)]
        vshape = shapes[level]
        vlab = _coarse_labels(labels, factor)[:vshape[0], :vshape[1], :vshape[2]]
        vident = _block_mean(identity, vshape)
        guide = np.empty((3, *vshape, 1 + identity.shape[3]), np.float32)
        for a in range(3):
            guide[a, ..., 0] = distance_guide(vlab, PLANE_AXES[a], p.wrap, p.clip) * scale
            guide[a, ..., 1:] = vident * scale
        imgs = _stack(level_images, hw)
        lo, hi = level_valid(ex_shapes, n)
        feats, basis, mean = pca_features(augmented, n, p.dims, hw, p.seed + level)
        knn = np.zeros((n_ex, hw[0], hw[1], p.knn, 2), np.int32)
        for e in range(n_ex):
            if p.knn:
                knn[e] = similar_positions(feats[e], lo[e], hi[e], p.knn, MAX_KNN_REFERENCES)
        avg_p = KopfAverage(n, p.stride, p.wrap, np.ones((n, n)))
        eps = EPS * basis.shape[0]
        power = (p.r - 2.0) / 2.0
        dist = np.ones((3, *vshape), np.float32)
        coarsest = pos is None
        if coarsest:
            pos = layout(vshape, ex_shapes, lo, hi) if layout is not None else None
            if pos is None:
                pos = random_positions(vshape, lo, hi, ex_of_axis, p.seed)
            # the first search sees the structure and the identity colours only
            vol = _identity_colour(vident, ex_identity, exemplars)
            source = np.zeros((*vshape, 3), np.int32)
        else:
            filled = np.empty_like(pos)
            fill_positions(pos, p.stride, prev_lo, prev_hi, ex_of_axis, filled)
            pos = upsample_positions(filled, vshape, lo, hi, ex_of_axis)
            vol = np.empty((*vshape, imgs.shape[3]), np.float32)
            source = np.empty((*vshape, 3), np.int32)
            kopf_average(pos, dist, imgs, ex_of_axis, np.ones(imgs.shape[:3], np.float32),
                         avg_p, vol, source)
        for it in range(p.iterations):
            search = KopfSearch(size=n, stride=p.stride, wrap=p.wrap,
                                exhaustive=coarsest and it == 0, n_random=0, lo=lo, hi=hi,
                                seed=np.uint64(p.seed), salt=np.uint64(level * 1000 + it))
            new_pos = np.empty_like(pos)
            guided_search(vol, guide, pos, new_pos, dist, feats, basis, mean, ex_of_axis, knn,
                          search)
            pos = new_pos
            weights = np.ones(imgs.shape[:3], np.float32)
            if p.colour > 0:
                weights = weights * colour_weights(vol, imgs, ex_of_axis, p.colour)
            if p.position > 0:
                counts = position_counts(pos, p.stride, n, ex_of_axis, n_ex, hw[0],
                                         hw[1]).astype(np.float64)
                expected = counts.sum() / max(int((counts > 0).sum()), 1)
                weights = weights * (1.0 / (1.0 + p.position * np.maximum(
                    counts / expected - 1.0, 0.0))).astype(np.float32)
            cw = ((dist.astype(np.float64) + eps) ** power).astype(np.float32)
            averaged = np.empty_like(vol)
            if it >= p.iterations - p.sharpen and (level > 0 or p.sharpen_finest):
                kopf_cluster(pos, cw, imgs, ex_of_axis, weights, avg_p,
                             p.bandwidth * colour_var, 0, True, averaged, source)
            else:
                kopf_average(pos, cw, imgs, ex_of_axis, weights, avg_p, averaged, source)
            vol = averaged
            done += 1
            if progress is not None:
                progress(done / total)
        prev_lo, prev_hi = lo, hi
    return np.ascontiguousarray(vol, np.float32), np.ascontiguousarray(source, np.int32)


def _resample_labels(labels: np.ndarray, shape) -> np.ndarray:
    """Labels (H, W) at another size: nearest (pixel centres)."""
    h, w = labels.shape
    rows = np.minimum(((np.arange(shape[0]) + 0.5) * h / shape[0]).astype(int), h - 1)
    cols = np.minimum(((np.arange(shape[1]) + 0.5) * w / shape[1]).astype(int), w - 1)
    return labels[rows][:, cols]


def _identity_colour(vident, ex_identity, exemplars):
    """The colour each voxel's identity stands for: the exemplar pixels' mean colour per
    identity value, regressed linearly (identity -> colour) on the exemplar."""
    ident = np.concatenate([i.reshape(-1, i.shape[2]) for i in ex_identity])
    channels = exemplars[0].shape[2]
    colour = np.concatenate([im.reshape(-1, channels) for im in exemplars])
    a = np.concatenate([ident, np.ones((len(ident), 1))], 1).astype(np.float64)
    m = np.linalg.lstsq(a, colour.astype(np.float64), rcond=None)[0]
    flat = vident.reshape(-1, vident.shape[3]).astype(np.float64)
    out = np.concatenate([flat, np.ones((len(flat), 1))], 1) @ m
    return out.reshape(*vident.shape[:3], channels).astype(np.float32)


def match_phases(voxels: np.ndarray, labels: np.ndarray, exemplars, ex_of_axis, ex_labels,
                 strength: float = 1.0) -> np.ndarray:
    """voxels with each phase's colours quantile-matched to the exemplar pixels of the same
    phase, `strength` of the way: per principal axis of the phase's exemplar colours (matching
    raw channels one by one would break the colours' correlation: a phase holding dark and red
    chips would gain teal ones)."""
    out = voxels.copy()
    used = sorted(set(int(e) for e in ex_of_axis))
    for value in np.unique(labels):
        where = labels == value
        ref = np.concatenate([exemplars[e][ex_labels[e] == value] for e in used])
        if not len(ref):
            continue
        vals = voxels[where].astype(np.float64)
        centre = ref.mean(0)
        _, vecs = np.linalg.eigh(np.cov((ref - centre).T).reshape(ref.shape[1], ref.shape[1]))
        src = (vals - centre) @ vecs
        dst = (ref - centre) @ vecs
        q = (np.arange(len(vals)) + 0.5) / len(vals)
        matched = np.empty_like(src)
        for c in range(src.shape[1]):
            order = np.argsort(src[:, c], kind="stable")
            matched[order, c] = np.quantile(dst[:, c], q)
        matched = matched @ vecs.T + centre
        out[where] = vals + strength * (matched - vals)
    return out



def match_regions(voxels: np.ndarray, regions: np.ndarray, targets: np.ndarray,
                  strength: float = 1.0, lo=None, hi=None) -> np.ndarray:
    """voxels with every region's mean colour moved to its target (regions int (Z, Y, X),
    -1: left alone; targets (R, C)): a stone keeps one colour through the whole volume, as its
    source profile has, while the fill's texture inside it stays. Regions smaller than a
    window (REGION_VOXELS) move less (their mean is mostly their rim's); the result is kept
    within lo .. hi per channel."""
    flat = regions.ravel()
    keep = flat >= 0
    if not keep.any():
        return voxels
    count = len(targets)
    vals = voxels.reshape(-1, voxels.shape[-1])
    area = np.maximum(np.bincount(flat[keep], minlength=count), 1)
    means = np.stack([np.bincount(flat[keep], vals[keep, c], count) / area
                      for c in range(vals.shape[1])], 1)
    weight = strength * np.minimum(1.0, area / REGION_VOXELS)
    shift = np.zeros_like(vals)
    shift[keep] = ((targets - means) * weight[:, None])[flat[keep]]
    out = vals + shift
    if lo is not None:
        out = np.clip(out, lo, hi)
    return out.reshape(voxels.shape).astype(np.float32)

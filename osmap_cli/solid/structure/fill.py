"""The appearance of a structured volume: the slice-window texture optimisation (Kopf et al.
2007, osmap_cli.solid.optimise) with guide channels, the idea of Kaspar et al. 2015 in 3D: every
window carries, beside its colours, the structure as its slice shows it (the in-plane distance
to the nearest phase boundary, clipped; the identity of the particle or phase: the mean colour
of its source), and the exemplar windows carry the same channels computed from its
segmentation. Every voxel so takes exemplar colour from the same kind of place: inside a stone
near its rim, mid-vein, matrix. The guides steer the search only; the structure is kept by a
constraint in the averaging: a voxel weighs the colours proposed from exemplar pixels of its
own label far above the others (label_mismatch), so the 8 x 8 windows that cover a 1-voxel gap
between stones cannot average it away. Then each phase's colours are quantile-matched to the
exemplar's pixels of that phase and each particle's mean colour to its source profile's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.solid.core import SolidTask, common_shape, stack, window_level
from osmap_cli.solid.layout import Layout, organise
from osmap_cli.solid.optimise import Optimisation, optimise
from osmap_cli.solid.structure.measures import squared_distance
from osmap_cli.texture.pyramid import resize

PLANE_AXES = ((0, 1), (0, 2), (1, 2))  # volume dims (z, y, x) spanning family 0, 1, 2's slices
REGION_VOXELS = 64.0  # a particle this small moves its mean colour only partly (see regions)
QUANTILES = 257  # points of each phase's quantile mapping


@dataclass(frozen=True)
class Fill:
    """window / dims / knn: the window levels; optimisation: the Optimisation record; layout:
    the OS-Map's (its training steps 0: a random start); clip: the distance guide saturates
    this many pixels from a boundary; guide_weight: the guide channels against the colours;
    phase_match: how far each phase's colours (and each particle's mean) move to the
    exemplar's; label_mismatch: the label constraint's weight (1: none); identity_start: the
    coarsest level's first search starts from the structure's identity colours (else from
    the average of the OS-Map layout's windows, as method osmap); detail: the residual
    detail's strength after the colour matching (residual_detail; 0: none); vein_detail: how
    veins take it (noise: noise_detail, copy: residual_detail, none); vein_grain: the in-sheet
    blur (voxels) that draws veins' fine band out along the sheets (0: fitted)."""

    window: int
    dims: int
    knn: int
    optimisation: Optimisation
    layout: Layout
    clip: float = 4.0
    guide_weight: float = 1.0
    phase_match: float = 1.0
    label_mismatch: float = 0.01
    identity_start: bool = True
    detail: float = 0.0
    vein_detail: str = "noise"
    vein_grain: float = 0.0


def distance_guide(labels: np.ndarray, axes, wrap: bool, clip: float) -> np.ndarray:
    """float32 in [0, 1]: the distance (within the subspace of `axes`) from every cell to the
    nearest cell of another label, between cell centres less half a cell, clipped, over `clip`."""
    out = np.zeros(labels.shape, np.float64)
    for value in np.unique(labels):
        inside = labels == value
        if inside.all():
            out[inside] = clip
            continue
        d = np.sqrt(squared_distance(~inside, wrap, axes))
        out[inside] = d[inside]
    return (np.minimum(np.maximum(out - 0.5, 0.0), clip) / clip).astype(np.float32)


def centre_samples(labels: np.ndarray, shape) -> np.ndarray:
    """labels (a volume or an image) sampled at the centres of a coarser grid of `shape`."""
    idx = [np.minimum(((np.arange(m) + 0.5) * n / m).astype(int), n - 1)
           for n, m in zip(labels.shape, shape)]
    return labels[np.ix_(*idx)]


def block_mean(values: np.ndarray, shape) -> np.ndarray:
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


def exemplar_channels(task: SolidTask, ex_labels, ex_identity, clip, scale):
    """Per level (finest first), per exemplar: float32 (h, w, 1 + I) guide channels."""
    out = []
    for level in range(task.levels):
        channels = []
        for e, im in enumerate(task.exemplars(level)):
            shape = im.shape[:2]
            dist = distance_guide(centre_samples(ex_labels[e], shape), (0, 1), task.tileable,
                                  clip)
            ident = resize(np.ascontiguousarray(ex_identity[e], np.float32), *shape)
            channels.append(np.concatenate([dist[..., None], ident], 2) * scale)
        out.append(channels)
    return out


def volume_guides(task: SolidTask, labels, identity, clip, scale):
    """Per level (finest first): float32 (3, Z, Y, X, 1 + I), each slice family's guides."""
    out = []
    for vshape in task.shapes:
        lab = centre_samples(labels, vshape)
        ident = block_mean(identity, vshape)
        guide = np.empty((3, *vshape, 1 + identity.shape[3]), np.float32)
        for a in range(3):
            guide[a, ..., 0] = distance_guide(lab, PLANE_AXES[a], task.tileable, clip) * scale
            guide[a, ..., 1:] = ident * scale
        out.append(guide)
    return out


def identity_colours(ident: np.ndarray, ex_identity, images) -> np.ndarray:
    """The colour each identity stands for: a linear map identity -> colour fitted on the
    exemplar pixels, applied to `ident` (Z, Y, X, I)."""
    src = np.concatenate([i.reshape(-1, i.shape[2]) for i in ex_identity]).astype(np.float64)
    dst = np.concatenate([im.reshape(-1, im.shape[2]) for im in images]).astype(np.float64)
    a = np.concatenate([src, np.ones((len(src), 1))], 1)
    m = np.linalg.lstsq(a, dst, rcond=None)[0]
    flat = ident.reshape(-1, ident.shape[-1]).astype(np.float64)
    out = np.concatenate([flat, np.ones((len(flat), 1))], 1) @ m
    return out.reshape(*ident.shape[:-1], dst.shape[1]).astype(np.float32)


def label_constraint(task: SolidTask, ex_labels, labels, mismatch: float):
    """Per level (finest first): (volume labels int32 (Z, Y, X), exemplar labels int32
    (E, H, W), mismatch), optimise's `labels`; None with mismatch 1 (no constraint)."""
    if mismatch >= 1.0:
        return None
    out = []
    for level in range(task.levels):
        images = task.exemplars(level)
        ex = stack([centre_samples(lb, im.shape[:2]).astype(np.int32)
                    for lb, im in zip(ex_labels, images)], common_shape(images))
        vol = centre_samples(labels, task.shapes[level]).astype(np.int32)
        out.append((np.ascontiguousarray(vol), ex, float(mismatch)))
    return out


def fill(task: SolidTask, ex_labels, ex_identity, labels, identity, params: Fill,
         progress=None):
    """(voxels float32 (Z, Y, X, C), source int32 (Z, Y, X, 3)) of the task's finest level.

    ex_labels / ex_identity: the segmentation (int (h, w)) and identity channels (float32
    (h, w, I)) of each exemplar at full size; labels / identity: the volume's (Z, Y, X) and
    (Z, Y, X, I) at the finest level."""
    images = task.images
    variance = float(np.concatenate([im.reshape(-1, im.shape[2]) for im in images])
                     .var(axis=0).sum()) + 1e-12
    scale = params.guide_weight * np.sqrt(variance)  # guides in units of the colours' spread
    channels = exemplar_channels(task, ex_labels, ex_identity, params.clip, scale)
    levels = [window_level(task, level, window=params.window, dims=params.dims, knn=params.knn,
                           channels=channels[level]) for level in range(task.levels)]
    guides = volume_guides(task, labels, identity, params.clip, scale)
    start = organise(levels[-1], task.ex_of_axis, params.layout, tileable=task.tileable,
                     seed=task.seed)
    coarse = (identity_colours(block_mean(identity, task.shapes[-1]), ex_identity, images)
              if params.identity_start else None)
    constraint = label_constraint(task, ex_labels, labels, params.label_mismatch)
    return optimise(task, levels, start, params.optimisation, progress, guides, coarse,
                    constraint)


def match_phases(voxels: np.ndarray, labels: np.ndarray, coverage: np.ndarray, exemplars,
                 ex_of_axis, ex_labels, nyquist: bool = False, wrap: bool = False) -> np.ndarray:
    """voxels with each phase's colours quantile-matched to the exemplar pixels of the same
    phase: per principal axis of the phase's exemplar colours (matching raw channels one by one
    would break the colours' correlation: a phase holding dark and red chips would gain teal
    ones). Each phase's mapping is fitted on its own voxels (labels) and applied to every voxel
    in proportion to the phase's share of it (coverage (Z, Y, X, K)): boundaries keep their
    antialiasing and thin phases (gaps, veins) their full contrast. The mapping reads and maps
    the colours without their highest frequency (without_nyquist), which passes unmapped: the
    fill's window lattice (centres every 2 voxels) leaves a faint 2-voxel hatching on wide
    uniform regions, and the mapping, stretching a nearly uniform phase's narrow spread onto the
    exemplar's, would turn it into a grid of dark dots (the exemplar's rarest colours).
    nyquist: map that frequency too (particles: a 1-voxel gap between stones is structure, and
    its contrast must be the exemplar's gaps'; layers: their fine grain). wrap: the volume is
    periodic (its filter wraps, so the wrap stays seamless)."""
    detail = None
    if not nyquist:
        smooth = without_nyquist(voxels, 3, wrap)
        detail = voxels - smooth
        exemplars = [without_nyquist(np.asarray(im, np.float32), 2) for im in exemplars]
        voxels = smooth
    flat = voxels.reshape(-1, voxels.shape[-1]).astype(np.float64)
    lab = labels.ravel()
    cover = coverage.reshape(-1, coverage.shape[-1])
    out = np.zeros_like(flat)
    total = np.zeros(len(flat))
    used = sorted(set(int(e) for e in ex_of_axis))
    q = np.linspace(0.0, 1.0, QUANTILES)
    for value in range(cover.shape[1]):
        ref = np.concatenate([exemplars[e][ex_labels[e] == value] for e in used])
        mine = flat[lab == value]
        if len(ref) < 2 or len(mine) < 2:
            continue
        ref = ref.astype(np.float64)
        centre = ref.mean(0)
        _, vecs = np.linalg.eigh(np.atleast_2d(np.cov((ref - centre).T)))
        src = np.quantile((mine - centre) @ vecs, q, axis=0)
        dst = np.quantile((ref - centre) @ vecs, q, axis=0)
        share = cover[:, value]
        near = share > 0
        rotated = (flat[near] - centre) @ vecs
        mapped = np.stack([np.interp(rotated[:, c], src[:, c], dst[:, c])
                           for c in range(rotated.shape[1])], 1) @ vecs.T + centre
        out[near] += share[near, None] * mapped
        total[near] += share[near]
    keep = total > 0
    out[keep] /= total[keep, None]
    out[~keep] = flat[~keep]
    out = out.reshape(voxels.shape)
    return (out if detail is None else out + detail).astype(np.float32)


def without_nyquist(values: np.ndarray, dims: int, wrap: bool = False) -> np.ndarray:
    """values (the first `dims` axes spatial) filtered by the binomial [1, 2, 1] / 4 along each
    spatial axis (edges mirrored, or wrapped with `wrap`): the 2-sample period is removed
    exactly, longer ones kept."""
    out = values.astype(np.float32)
    for axis in range(dims):
        n = out.shape[axis]
        if n < 3:
            continue
        before = np.take(out, np.r_[n - 1 if wrap else 1, np.arange(n - 1)], axis)
        after = np.take(out, np.r_[np.arange(1, n), 0 if wrap else n - 2], axis)
        out = 0.25 * before + 0.5 * out + 0.25 * after
    return out


def match_regions(voxels: np.ndarray, regions: np.ndarray, targets: np.ndarray,
                  share: np.ndarray, lo, hi) -> np.ndarray:
    """voxels with every region's mean colour moved to its target (regions int (Z, Y, X),
    -1: none; targets (R, C)), each voxel in proportion to the region's share of it: a stone
    keeps one colour through the whole volume, as its source profile has, while the fill's
    texture inside it stays. Regions smaller than REGION_VOXELS move less (their mean is
    mostly their rim's); the result stays within lo .. hi per channel."""
    flat = regions.ravel()
    keep = flat >= 0
    if not keep.any():
        return voxels
    count = len(targets)
    vals = voxels.reshape(-1, voxels.shape[-1])
    area = np.maximum(np.bincount(flat[keep], minlength=count), 1)
    means = np.stack([np.bincount(flat[keep], vals[keep, c], count) / area
                      for c in range(vals.shape[1])], 1)
    weight = np.minimum(1.0, area / REGION_VOXELS)
    shift = np.zeros_like(vals)
    shift[keep] = ((targets - means) * weight[:, None])[flat[keep]]
    shift *= share.reshape(-1, 1)
    return np.clip(vals + shift, lo, hi).reshape(voxels.shape).astype(np.float32)

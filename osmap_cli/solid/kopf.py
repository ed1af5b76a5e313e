"""Texture optimisation over the three slice neighbourhoods of every voxel (Kopf et al. 2007),
coarse to fine, and the sharpened variant behind the default `osmap solid` method.

Per level: search (every window centre and axis: the nearest exemplar window in a PCA space of
the n x n windows), then optimise (every voxel: the IRLS-weighted mean, r = kopf_r, of the
colours the covering windows of all three axes place on it, each weight divided by the colour
and exemplar-position histogram excess of the pixel it proposes). `method="kopf"` runs just
that, from random positions. The default (`method="osmap"`) starts from the OS-Map's layout of
the coarsest volume and ends every level with `sharpen` passes in which each voxel takes the
single exemplar colour whose window agrees best with the averaged volume around it, then a
per-channel histogram match of the colours (docs/solid.md, "Method").
"""

from __future__ import annotations

import numpy as np

from osmap_cli.solid.options import SolidOptions
from osmap_cli.texture.references import similar_positions
from osmap_kernels.kopf import (
    KopfAverage,
    KopfSearch,
    fill_positions,
    kopf_average,
    kopf_cluster,
    kopf_pick,
    kopf_search,
    position_counts,
)

MAX_PCA_SAMPLES = 20000
MAX_KNN_REFERENCES = 4096
HIST_BINS = 16
EPS = 1e-6


def window_half(n: int) -> tuple[int, int]:
    """Offsets -h0 .. h1 of an n x n window."""
    return n // 2, n - 1 - n // 2


def window_vectors(image: np.ndarray, n: int) -> np.ndarray:
    """float64 (h - n + 1, w - n + 1, n * n * C): every whole window, (row, col, channel)
    order; entry [i, j] is the window centred at (i + n // 2, j + n // 2)."""
    view = np.lib.stride_tricks.sliding_window_view(image, (n, n), axis=(0, 1))
    view = np.moveaxis(view, 2, 4)  # (., ., n, n, C)
    return view.reshape(view.shape[0], view.shape[1], -1).astype(np.float64)


def pca_features(images, n: int, dims: int, hw, seed: int):
    """(feats (E, H, W, D) float32 of the window centred at each valid pixel, basis (n*n*C, D),
    mean): one PCA basis for all exemplars, fitted on at most MAX_PCA_SAMPLES windows."""
    vectors = [window_vectors(im, n) for im in images]
    flat = np.concatenate([v.reshape(-1, v.shape[2]) for v in vectors])
    if len(flat) > MAX_PCA_SAMPLES:
        pick = np.random.default_rng(seed).choice(len(flat), MAX_PCA_SAMPLES, replace=False)
        sample = flat[np.sort(pick)]
    else:
        sample = flat
    mean = sample.mean(axis=0)
    centred = sample - mean
    cov = centred.T @ centred / max(len(sample) - 1, 1)
    _, eigvec = np.linalg.eigh(cov)
    basis = eigvec[:, ::-1][:, :min(dims, cov.shape[0])]
    basis *= np.where(basis[np.abs(basis).argmax(axis=0), range(basis.shape[1])] < 0, -1, 1)
    h0, _ = window_half(n)
    feats = np.zeros((len(images), hw[0], hw[1], basis.shape[1]), np.float32)
    for e, v in enumerate(vectors):
        proj = (v.reshape(-1, v.shape[2]) - mean) @ basis
        feats[e, h0:h0 + v.shape[0], h0:h0 + v.shape[1]] = proj.reshape(*v.shape[:2], -1)
    return (feats, np.ascontiguousarray(basis, np.float64),
            np.ascontiguousarray(mean, np.float64))


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


def position_weights(pos, opts, ex_of_axis, n_ex, hw, strength: float) -> np.ndarray:
    """float32 (E, H, W): 1 / (1 + strength * relative over-use of each exemplar pixel by the
    volume's window matches) (the exemplar-position histogram)."""
    counts = position_counts(pos, opts.kopf_stride, opts.kopf_window, ex_of_axis, n_ex,
                             hw[0], hw[1]).astype(np.float64)
    used = counts > 0
    expected = counts.sum() / max(int(used.sum()), 1)
    return (1.0 / (1.0 + strength * np.maximum(counts / expected - 1.0, 0.0))).astype(np.float32)


def match_colours(vol: np.ndarray, images, ex_of_axis) -> np.ndarray:
    """vol with each channel quantile-mapped onto the exemplars' pixels (ties by voxel order)."""
    used = sorted(set(int(e) for e in ex_of_axis))
    flat = vol.reshape(-1, vol.shape[3])
    out = np.empty_like(flat)
    q = (np.arange(len(flat)) + 0.5) / len(flat)
    for ch in range(flat.shape[1]):
        ref = np.concatenate([images[e][..., ch].ravel() for e in used])
        order = np.argsort(flat[:, ch], kind="stable")
        out[order, ch] = np.quantile(ref, q).astype(np.float32)
    return np.ascontiguousarray(out.reshape(vol.shape))


def random_positions(shape, lo, hi, ex_of_axis, seed: int) -> np.ndarray:
    """int32 (3, Z, Y, X, 2): uniform valid window centres (Kopf's random initialisation)."""
    rng = np.random.default_rng(seed)
    pos = np.empty((3, *shape, 2), np.int32)
    for a in range(3):
        e = ex_of_axis[a]
        for j in range(2):
            pos[a, ..., j] = rng.integers(lo[e, j], hi[e, j] + 1, shape)
    return pos


def level_valid(ex_shapes, n: int):
    """lo, hi (E, 2) int64: the window centres that keep an n x n window inside."""
    h0, h1 = window_half(n)
    lo = np.array([[h0, h0]] * len(ex_shapes), np.int64)
    hi = np.array([[s[0] - 1 - h1, s[1] - 1 - h1] for s in ex_shapes], np.int64)
    return lo, hi


def optimise(images, ex_of_axis, opts: SolidOptions, shapes, pyramids, stack, organise_fn,
             upsample_positions, upsample_linear, progress=None):
    """(voxels float32 (Z, Y, X, C), source int32 (Z, Y, X, 3)) for the levels in `shapes`
    (finest first); pyramids[e][level] the exemplar levels; stack(arrays, hw) pads and stacks.
    organise_fn(shape, ex_shapes, lo, hi) gives the coarsest positions (None: random)."""
    levels = len(shapes)
    n_ex = len(images)
    sharpen = opts.sharpen if opts.method == "osmap" else 0
    hist = opts.histogram_weight if opts.method == "osmap" else opts.kopf_histogram
    hist_pos = opts.position_weight if opts.method == "osmap" else opts.kopf_histogram
    total = float(levels * opts.kopf_iterations)
    done = 0.0
    pos = vol = source = prev_lo = prev_hi = None
    for level in range(levels - 1, -1, -1):
        level_images = [p[level] for p in pyramids]
        ex_shapes = [im.shape[:2] for im in level_images]
        hw = (max(s[0] for s in ex_shapes), max(s[1] for s in ex_shapes))
        n = min(opts.kopf_window, min(min(s) for s in ex_shapes) - 2)
        imgs = stack(level_images, hw)
        flat = np.concatenate([im.reshape(-1, im.shape[2]) for im in level_images])
        variance = float(flat.var(axis=0).sum()) + 1e-12
        lo, hi = level_valid(ex_shapes, n)
        feats, basis, mean = pca_features(level_images, n, opts.kopf_dims, hw, opts.seed + level)
        k = opts.knn
        knn = np.zeros((n_ex, hw[0], hw[1], k, 2), np.int32)
        for e in range(n_ex):
            if k:
                knn[e] = similar_positions(feats[e], lo[e], hi[e], k, MAX_KNN_REFERENCES)
        vshape = shapes[level]
        search_p = dict(size=n, stride=opts.kopf_stride, wrap=opts.tileable, n_random=0,
                        lo=lo, hi=hi, seed=np.uint64(opts.seed))
        off = np.arange(n, dtype=np.float64) - n // 2
        falloff = opts.window_falloff if opts.method == "osmap" else 0.0
        window = np.exp(-falloff * (off[:, None] ** 2 + off[None, :] ** 2)
                        / max((n / 2.0) ** 2, 1.0))
        avg_p = KopfAverage(n, opts.kopf_stride, opts.tileable, window)
        eps = EPS * basis.shape[0]
        power = (opts.kopf_r - 2.0) / 2.0
        dist = np.ones((3, *vshape), np.float32)
        coarsest = pos is None
        if coarsest:
            organised = organise_fn(vshape, ex_shapes, lo, hi)
            pos = organised if organised is not None else random_positions(
                vshape, lo, hi, ex_of_axis, opts.seed)
            vol = np.empty((*vshape, imgs.shape[3]), np.float32)
            source = np.empty((*vshape, 3), np.int32)
            kopf_average(pos, dist, imgs, ex_of_axis, np.ones(imgs.shape[:3], np.float32),
                         avg_p, vol, source)
        else:
            filled = np.empty_like(pos)
            fill_positions(pos, opts.kopf_stride, prev_lo, prev_hi, ex_of_axis, filled)
            pos = upsample_positions(filled, vshape, lo, hi, ex_of_axis)
            source = np.empty((*vshape, 3), np.int32)
            if opts.upsample_render and opts.method == "osmap":
                # the finer level starts from its own exemplar detail at the upsampled
                # positions, not from the coarser volume blurred by interpolation (a blurred
                # start makes the search prefer smooth exemplar areas: features grow)
                vol = np.empty((*vshape, imgs.shape[3]), np.float32)
                kopf_average(pos, dist, imgs, ex_of_axis, np.ones(imgs.shape[:3], np.float32),
                             avg_p, vol, source)
            else:
                vol = upsample_linear(vol, vshape, opts.tileable)
        for it in range(opts.kopf_iterations):
            params = KopfSearch(exhaustive=coarsest and it == 0,
                                salt=np.uint64(level * 1000 + it), **search_p)
            new_pos = np.empty_like(pos)
            kopf_search(vol, pos, new_pos, dist, feats, basis, mean, ex_of_axis, knn, params)
            pos = new_pos
            weights = np.ones(imgs.shape[:3], np.float32)
            if hist > 0:
                weights = weights * colour_weights(vol, imgs, ex_of_axis, hist)
            if hist_pos > 0:
                weights = weights * position_weights(pos, opts, ex_of_axis, n_ex, hw, hist_pos)
            averaged = np.empty_like(vol)
            cw = ((dist.astype(np.float64) + eps) ** power).astype(np.float32)
            kopf_average(pos, cw, imgs, ex_of_axis, weights, avg_p, averaged, source)
            vol = averaged
            last = level == 0 and it == opts.kopf_iterations - 1
            if (sharpen and level < opts.sharpen_levels and it >= opts.kopf_iterations - sharpen
                    and (opts.sharpen_final or not last) and (level > 0 or opts.sharpen_finest)):
                sharp = np.empty_like(vol)
                if opts.sharpen_bandwidth > 0:
                    kopf_cluster(pos, cw, imgs, ex_of_axis, weights, avg_p,
                                 opts.sharpen_bandwidth * variance, opts.sharpen_steps,
                                 opts.sharpen_cross > 0, sharp, source)
                else:
                    kopf_pick(pos, imgs, ex_of_axis, averaged, avg_p, opts.pick_support,
                              sharp, source)
                vol = sharp
            done += 1
            if progress is not None:
                progress(done / total)
        prev_lo, prev_hi = lo, hi
    if opts.method == "osmap" and opts.final_histogram > 0:
        matched = match_colours(vol, stack(images, hw), ex_of_axis)
        vol = vol + opts.final_histogram * (matched - vol)
    return np.ascontiguousarray(vol, np.float32), np.ascontiguousarray(source, np.int32)

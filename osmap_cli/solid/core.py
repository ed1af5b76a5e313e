"""The records every solid method shares: what to make (`SolidTask`), one pyramid level's
exemplar data built once (`SolidLevel`), and the result (`SolidResult`).

Two kinds of level, one per kind of search:
- `window_level`: the n x n windows of each exemplar pixel in a PCA space (the texture
  optimisation of Kopf et al. 2007: methods osmap and kopf, osmap_cli.solid.optimise);
- `pixel_level`: each pixel's appearance-space features (Lefebvre and Hoppe 2006; method legacy).
Both carry the k-NN table of similar positions and the valid window centres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.texture.features import (
    appearance_features,
    feature_variance,
    pca_basis,
)
from osmap_cli.texture.references import SOLID_REFERENCES, similar_positions

# the window PCA is fitted on at most this many windows (drawn with the task's seed + level)
MAX_PCA_SAMPLES = 20000


@dataclass(frozen=True)
class SolidTask:
    """What every method is given: the exemplars, their pyramids and the volume's level plan."""

    images: list  # the full-size exemplars, float32 (h_e, w_e, C); one, or x, y, z
    ex_of_axis: np.ndarray  # int64 (3,): the exemplar of the slice family normal to x, y, z
    pyramids: list  # pyramids[e][level]: exemplar e halved `level` times (finest first)
    shapes: list  # the volume's (Z, Y, X) at each level, finest first (pipeline.plan_levels)
    tileable: bool  # the volume wraps around in x, y and z
    seed: int

    @property
    def levels(self) -> int:
        return len(self.shapes)

    def exemplars(self, level: int) -> list:
        """The exemplar images at `level` (0: full size)."""
        return [p[level] for p in self.pyramids]


@dataclass(frozen=True)
class SolidLevel:
    """One pyramid level's exemplar data, built once. E exemplars padded to a common (H, W)."""

    shape: tuple  # the volume's (Z, Y, X) at this level
    images: list  # float32 (h_e, w_e, C) per exemplar
    stacked: np.ndarray  # float32 (E, H, W, C): the images padded (edge) and stacked
    feats: np.ndarray  # float32 (E, H, W, D): each position's search features
    knn: np.ndarray  # int32 (E, H, W, k, 2): similar positions of each position
    lo: np.ndarray  # int64 (E, 2): the smallest valid (row, col) (the window stays inside)
    hi: np.ndarray  # int64 (E, 2): the largest
    variance: float  # of the colours (window level) or of the features (pixel level)
    window: int  # window side n (window level) or neighbourhood side 2r + 1 (pixel level)
    basis: np.ndarray | None = None  # float64 (n*n*C, D): window vector -> feats (window level)
    mean: np.ndarray | None = None  # float64 (n*n*C,): the window vectors' mean

    @property
    def ex_shapes(self) -> list:
        return [im.shape[:2] for im in self.images]

    @property
    def hw(self) -> tuple[int, int]:
        return self.stacked.shape[1:3]


@dataclass(frozen=True)
class SolidResult:
    """voxels: float32 (Z, Y, X, C); source: int32 (Z, Y, X, 3) = (axis, row, col) of the
    exemplar pixel each voxel is copied from (axis 0, 1, 2 = the x, y, z exemplar); with
    `blend` > 0 the voxels on seams are blended, the others are their source pixel exactly."""

    voxels: np.ndarray
    source: np.ndarray
    report: tuple = ()  # what the method found and did, lines for --verbose (structure method)
    provenance: dict | None = None  # a JSON-able record of the same for the output's metadata

    def uv(self) -> np.ndarray:
        """float32 (Z, Y, X, 3): u = exemplar column, v = exemplar row, exemplar index."""
        s = self.source
        return np.stack([s[..., 2], s[..., 1], s[..., 0]], -1).astype(np.float32)


def stack(arrays, shape_hw) -> np.ndarray:
    """Arrays (h_e, w_e, ...) padded (edge) to a common (H, W, ...) and stacked."""
    out = []
    for a in arrays:
        pad = [(0, shape_hw[0] - a.shape[0]), (0, shape_hw[1] - a.shape[1])]
        pad += [(0, 0)] * (a.ndim - 2)
        out.append(np.pad(a, pad, mode="edge"))
    return np.ascontiguousarray(np.stack(out))


def common_shape(images) -> tuple[int, int]:
    """(H, W): the largest height and width of the images."""
    return max(im.shape[0] for im in images), max(im.shape[1] for im in images)


# ---------------------------------------------------------------------------------------------
# window levels (Kopf et al.)


def window_half(n: int) -> tuple[int, int]:
    """Offsets -h0 .. h1 of an n x n window."""
    return n // 2, n - 1 - n // 2


def window_vectors(image: np.ndarray, n: int) -> np.ndarray:
    """float64 (h - n + 1, w - n + 1, n * n * C): every whole window, (row, col, channel)
    order; entry [i, j] is the window centred at (i + n // 2, j + n // 2)."""
    view = np.lib.stride_tricks.sliding_window_view(image, (n, n), axis=(0, 1))
    view = np.moveaxis(view, 2, 4)  # (., ., n, n, C)
    return view.reshape(view.shape[0], view.shape[1], -1).astype(np.float64)


def window_bounds(ex_shapes, n: int):
    """lo, hi (E, 2) int64: the window centres that keep an n x n window inside."""
    h0, h1 = window_half(n)
    lo = np.array([[h0, h0]] * len(ex_shapes), np.int64)
    hi = np.array([[s[0] - 1 - h1, s[1] - 1 - h1] for s in ex_shapes], np.int64)
    return lo, hi


def window_features(images, n: int, dims: int, hw, seed: int):
    """(feats (E, H, W, D) float32 of the window centred at each valid pixel, basis (n*n*C, D),
    mean): one PCA basis for all exemplars, fitted on at most MAX_PCA_SAMPLES windows."""
    vectors = [window_vectors(im, n) for im in images]
    flat = np.concatenate([v.reshape(-1, v.shape[2]) for v in vectors])
    basis, mean = pca_basis(flat, dims, max_samples=MAX_PCA_SAMPLES, seed=seed)
    h0, _ = window_half(n)
    feats = np.zeros((len(images), hw[0], hw[1], basis.shape[1]), np.float32)
    for e, v in enumerate(vectors):
        proj = (v.reshape(-1, v.shape[2]) - mean) @ basis
        feats[e, h0:h0 + v.shape[0], h0:h0 + v.shape[1]] = proj.reshape(*v.shape[:2], -1)
    return (feats, np.ascontiguousarray(basis, np.float64),
            np.ascontiguousarray(mean, np.float64))


def window_level(task: SolidTask, level: int, *, window: int, dims: int, knn: int,
                 channels=None) -> SolidLevel:
    """The level's exemplars as n x n windows (n = `window`, smaller on a tiny exemplar) in a
    `dims`-dimensional PCA space, with `knn` similar positions per window centre. `channels`:
    per exemplar, float32 (h_e, w_e, G) guide channels the windows carry beside the colours
    (the search features cover both; `stacked`, which the optimisation averages, the colours
    only)."""
    images = task.exemplars(level)
    ex_shapes = [im.shape[:2] for im in images]
    hw = common_shape(images)
    n = min(window, min(min(s) for s in ex_shapes) - 2)
    flat = np.concatenate([im.reshape(-1, im.shape[2]) for im in images])
    lo, hi = window_bounds(ex_shapes, n)
    searched = images if channels is None else [
        np.concatenate([im, np.asarray(g, np.float32)], 2) for im, g in zip(images, channels)]
    feats, basis, mean = window_features(searched, n, dims, hw, task.seed + level)
    table = np.zeros((len(images), hw[0], hw[1], knn, 2), np.int32)
    if knn:
        for e in range(len(images)):
            table[e] = similar_positions(feats[e], lo[e], hi[e], knn, SOLID_REFERENCES)
    return SolidLevel(shape=task.shapes[level], images=images, stacked=stack(images, hw),
                      feats=feats, knn=table, lo=lo, hi=hi,
                      variance=float(flat.var(axis=0).sum()) + 1e-12, window=n, basis=basis,
                      mean=mean)


# ---------------------------------------------------------------------------------------------
# pixel levels (appearance space)


def pixel_level(task: SolidTask, level: int, *, radius: int, dims: int, feature_radius: int,
                knn: int) -> SolidLevel:
    """The level's exemplars as appearance-space features (`dims` PCA dimensions of each pixel's
    (2 feature_radius + 1)^2 neighbourhood), valid where a (2 radius + 1)^2 neighbourhood stays
    inside (radius smaller on a tiny exemplar), with `knn` similar positions per pixel."""
    images = task.exemplars(level)
    ex_shapes = [im.shape[:2] for im in images]
    hw = common_shape(images)
    feats = appearance_features(images, dims, feature_radius)
    rr = min(radius, (min(min(s) for s in ex_shapes) - 1) // 2)
    lo = np.array([[rr, rr]] * len(images), np.int64)
    hi = np.array([[s[0] - 1 - rr, s[1] - 1 - rr] for s in ex_shapes], np.int64)
    table = stack([similar_positions(f, lo[e], hi[e], knn, SOLID_REFERENCES)
                   for e, f in enumerate(feats)], hw)
    if knn == 0:
        table = np.ascontiguousarray(table[..., :0, :])
    return SolidLevel(shape=task.shapes[level], images=images, stacked=stack(images, hw),
                      feats=stack(feats, hw), knn=table, lo=lo, hi=hi,
                      variance=max(feature_variance(feats, np.float32), 1e-12), window=2 * rr + 1)

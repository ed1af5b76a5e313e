"""Appearance space (Lefebvre and Hoppe 2006): each pixel described by the PCA projection of its
Gaussian-weighted 5x5 colour neighbourhood, so that matching a few feature vectors compares
whole neighbourhoods."""

from __future__ import annotations

import numpy as np


def neighbourhood_vectors(image: np.ndarray, radius: int) -> np.ndarray:
    """(h, w, (2r+1)^2 * C) Gaussian-weighted neighbourhoods, edges replicated."""
    h, w, c = image.shape
    padded = np.pad(image, ((radius, radius), (radius, radius), (0, 0)), mode="edge")
    offsets = range(-radius, radius + 1)
    sigma = max(radius, 1) * 0.75
    parts = []
    for dy in offsets:
        for dx in offsets:
            weight = np.exp(-(dy * dy + dx * dx) / (2 * sigma * sigma))
            parts.append(weight * padded[radius + dy:radius + dy + h, radius + dx:radius + dx + w])
    return np.concatenate(parts, axis=2)


def appearance_features(images, dims: int = 8, radius: int = 2) -> list[np.ndarray]:
    """float32 (h_e, w_e, dims') features of each image (h_e, w_e, C) in `images`, dims' =
    min(dims, neighbourhood length): one PCA basis fitted on all the images' pixels together,
    so that the features of several exemplars compare (a list of one for one exemplar)."""
    vectors = [neighbourhood_vectors(np.asarray(im, np.float32), radius) for im in images]
    n = vectors[0].shape[2]
    flat = np.concatenate([v.reshape(-1, n) for v in vectors]).astype(np.float64)
    basis, mean = pca_basis(flat, dims)
    return [((v.reshape(-1, n) - mean) @ basis).reshape(*v.shape[:2], -1).astype(np.float32)
            for v in vectors]


def pca_basis(vectors: np.ndarray, dims: int, *, max_samples: int = 0, seed: int = 0):
    """(basis (n, dims'), mean (n,)) float64: the principal axes of vectors (N, n) float64,
    largest variance first, dims' = min(dims, n), each axis' sign fixed (its largest component
    positive) so that features are reproducible across LAPACK builds. max_samples > 0: fitted on
    at most that many vectors, drawn without replacement with `seed` (kept in their order)."""
    if 0 < max_samples < len(vectors):
        pick = np.random.default_rng(seed).choice(len(vectors), max_samples, replace=False)
        vectors = vectors[np.sort(pick)]
    mean = vectors.mean(axis=0)
    centred = vectors - mean
    cov = centred.T @ centred / max(len(vectors) - 1, 1)
    _, eigvec = np.linalg.eigh(cov)
    basis = eigvec[:, ::-1][:, :min(dims, cov.shape[0])]
    basis *= np.where(basis[np.abs(basis).argmax(axis=0), range(basis.shape[1])] < 0, -1, 1)
    return basis, mean


def feature_variance(feats, dtype=np.float64) -> float:
    """The features' variance: the mean squared norm of every feature vector of `feats` (a list
    of (h, w, F) arrays; PCA features have zero mean), the squares summed in `dtype` (synth
    float64, solid float32)."""
    flat = np.concatenate([f.reshape(-1, f.shape[-1]) for f in feats])
    return float(np.mean(np.sum(np.square(flat, dtype=dtype), axis=1)))

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
    mean = flat.mean(axis=0)
    centred = flat - mean
    cov = centred.T @ centred / max(len(flat) - 1, 1)
    _, eigvec = np.linalg.eigh(cov)
    basis = eigvec[:, ::-1][:, :min(dims, n)]
    # fix each axis' sign so features are reproducible across LAPACK builds
    basis *= np.where(basis[np.abs(basis).argmax(axis=0), range(basis.shape[1])] < 0, -1, 1)
    return [((v.reshape(-1, n) - mean) @ basis).reshape(*v.shape[:2], -1).astype(np.float32)
            for v in vectors]


def feature_variance(feats, dtype=np.float64) -> float:
    """The features' variance: the mean squared norm of every feature vector of `feats` (a list
    of (h, w, F) arrays; PCA features have zero mean), the squares summed in `dtype` (synth
    float64, solid float32)."""
    flat = np.concatenate([f.reshape(-1, f.shape[-1]) for f in feats])
    return float(np.mean(np.sum(np.square(flat, dtype=dtype), axis=1)))

"""Appearance space (Lefebvre and Hoppe 2006): each pixel described by the PCA projection of its
Gaussian-weighted 5x5 colour neighbourhood, so that matching a few feature vectors compares
whole neighbourhoods."""

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


def appearance_features(image: np.ndarray, dims: int = 8, radius: int = 2) -> np.ndarray:
    """float32 (h, w, dims') features, dims' = min(dims, neighbourhood length)."""
    vectors = neighbourhood_vectors(np.asarray(image, np.float32), radius)
    h, w, n = vectors.shape
    flat = vectors.reshape(-1, n).astype(np.float64)
    flat -= flat.mean(axis=0)
    cov = flat.T @ flat / max(len(flat) - 1, 1)
    eigval, eigvec = np.linalg.eigh(cov)
    basis = eigvec[:, ::-1][:, :min(dims, n)]
    # fix each axis' sign so features are reproducible across LAPACK builds
    basis *= np.where(basis[np.abs(basis).argmax(axis=0), range(basis.shape[1])] < 0, -1, 1)
    return (flat @ basis).reshape(h, w, -1).astype(np.float32)

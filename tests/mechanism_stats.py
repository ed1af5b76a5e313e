"""Measurements of the OS-Map's mechanisms for the tests (numpy only, no code shared with the
engine or the pipeline): how many times each input item appears in a map, how much of a
position field continues its copy, feature size from the autocorrelation, a structure-tensor
angle, and smooth noise exemplars with known structure."""

from __future__ import annotations

import numpy as np


def label_equal(key: np.ndarray) -> np.ndarray:
    """Labels of the 4-connected regions of equal `key` (H, W): each region gets the smallest
    flat index among its nodes."""
    labels = np.arange(key.size).reshape(key.shape)
    down, right = key[1:] == key[:-1], key[:, 1:] == key[:, :-1]
    while True:
        new = labels.copy()
        new[1:] = np.where(down, np.minimum(new[1:], labels[:-1]), new[1:])
        new[:-1] = np.where(down, np.minimum(new[:-1], labels[1:]), new[:-1])
        new[:, 1:] = np.where(right, np.minimum(new[:, 1:], labels[:, :-1]), new[:, 1:])
        new[:, :-1] = np.where(right, np.minimum(new[:, :-1], labels[:, 1:]), new[:, :-1])
        if np.array_equal(new, labels):
            return labels
        labels = new


def appearances(field: np.ndarray) -> float:
    """The paper's scale measured: over the input items (integer 2D positions) a map holds, the
    mean number of separate places (connected groups of nodes) holding each. A zoomed copy
    holds each item once (in one blob of nodes); s copies at the data's own size, s times."""
    items = np.rint(field).astype(np.int64)
    key = items[..., 0] * 1_000_003 + items[..., 1]
    labels = label_equal(key)
    pairs = np.unique(np.stack([key.ravel(), labels.ravel()], 1), axis=0)
    return float(len(pairs) / len(np.unique(pairs[:, 0])))


def local_jacobians(field: np.ndarray) -> np.ndarray:
    """(H-1, W-1, 2, 2): d field[k] / d map axis a by forward differences."""
    down = np.diff(field, axis=0)[:, :-1]
    right = np.diff(field, axis=1)[:-1]
    return np.stack([down, right], -1).astype(np.float64)


def coherent_fraction(field: np.ndarray, jac: np.ndarray, tolerance: float = 0.5) -> float:
    """Share of the nodes whose local Jacobian is `jac` (each entry within `tolerance`): the
    node continues its neighbours' copy of the exemplar."""
    return float(np.all(np.abs(local_jacobians(field) - jac) < tolerance, axis=(-1, -2)).mean())


def median_magnification(field: np.ndarray) -> float:
    """Median |det| of the local Jacobians: exemplar area per map node (1: the exemplar's own
    size; a zoomed copy far less)."""
    j = local_jacobians(field)
    return float(np.median(np.abs(j[..., 0, 0] * j[..., 1, 1] - j[..., 0, 1] * j[..., 1, 0])))


def correlation_width(image: np.ndarray) -> float:
    """Feature size: the radius (pixels) at which the radially averaged autocorrelation of the
    channel mean (periodic) falls to one half."""
    grey = image.mean(axis=2) if image.ndim == 3 else image
    grey = grey - grey.mean()
    power = np.abs(np.fft.fft2(grey)) ** 2
    auto = np.real(np.fft.ifft2(power))
    auto /= auto[0, 0]
    h, w = grey.shape
    dy = np.minimum(np.arange(h), h - np.arange(h))[:, None]
    dx = np.minimum(np.arange(w), w - np.arange(w))[None]
    ring = np.rint(np.hypot(dy, dx)).astype(np.int64)
    profile = np.bincount(ring.ravel(), auto.ravel()) / np.bincount(ring.ravel())
    i = int(np.argmax(profile < 0.5))
    return float(i - 1 + (profile[i - 1] - 0.5) / (profile[i - 1] - profile[i]))


def gradient_angle(values: np.ndarray) -> float:
    """Dominant gradient direction (degrees in [0, 180)) of a 2D field by its structure tensor,
    measured from axis 0 towards axis 1."""
    g0, g1 = np.gradient(values.astype(np.float64))
    j00, j11, j01 = (g0 * g0).sum(), (g1 * g1).sum(), (g0 * g1).sum()
    return float(np.degrees(0.5 * np.arctan2(2 * j01, j00 - j11)) % 180.0)


def smooth_noise(size: int, sigma_rows: float, sigma_cols: float, seed: int = 0) -> np.ndarray:
    """A periodic grey (size, size, 3) exemplar in [0, 1]: white noise blurred by a Gaussian of
    the given widths along rows and columns (features of a known size and direction)."""
    rng = np.random.default_rng(seed)
    noise = rng.random((size, size))
    freq = np.fft.fftfreq(size)
    gain = np.exp(-2 * np.pi ** 2 * (sigma_rows ** 2 * freq[:, None] ** 2
                                     + sigma_cols ** 2 * freq[None] ** 2))
    smooth = np.real(np.fft.ifft2(np.fft.fft2(noise) * gain))
    smooth = (smooth - smooth.min()) / (smooth.max() - smooth.min())
    return np.repeat(smooth[..., None], 3, 2).astype(np.float32)

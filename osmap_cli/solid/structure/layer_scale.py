"""The feature scale layers show on a volume's own cuts, against the exemplar's segmentation.

A volume holds few bands, so the draw of their sequence moves what its faces show: with the
mean widths fitted (layers.fitted_sequence) a face still reads up to a sixth coarser or finer
from one seed to the next, as the few wide or narrow bands fall. The scale read here is the
spectral centroid (power per log-frequency band, Welch-averaged Hann windows of the
lightness) of each slice family's cuts, coloured by the phases' lightness, over the same
centroid of the exemplar's segmentation coloured alike: 2 ** (exemplar - cuts), 1 the
exemplar's, 2 features twice as large. It is read on a few evenly spaced slices per family of
the antialiased phases the fill is guided by (layers.Bands.coverage), so it costs a few
milliseconds per round.
"""

from __future__ import annotations

import numpy as np

CUTS = 8  # evenly spaced slices per family, the volume's first and last included


def window(side: int) -> int:
    """The spectra's window (px): the largest power of two within half the side, 16 to 128."""
    return int(np.clip(2 ** np.floor(np.log2(max(side, 2) / 2)), 16, 128))


def centroid(images, n: int) -> float:
    """The spectral centroid (log2 cycles per window) of the images' lightness (2D arrays):
    radial power of n x n Hann windows at half-window steps, per log-frequency band."""
    win = np.outer(np.hanning(n), np.hanning(n))
    fy, fx = np.meshgrid(np.fft.fftfreq(n), np.fft.fftfreq(n), indexing="ij")
    ring = np.rint(np.hypot(fy, fx) * n).astype(np.int64).ravel()
    power = np.zeros(ring.max() + 1)
    for image in images:
        for y in range(0, image.shape[0] - n + 1, n // 2):
            for x in range(0, image.shape[1] - n + 1, n // 2):
                patch = image[y:y + n, x:x + n]
                spectrum = np.abs(np.fft.fft2((patch - patch.mean()) * win)) ** 2
                power += np.bincount(ring, spectrum.ravel(), len(power))
    radial = power[1:n // 2 + 1] / np.bincount(ring)[1:n // 2 + 1]
    radial = radial / max(radial.sum(), 1e-300) + 1e-12
    f = np.arange(1, n // 2 + 1)
    return float(np.sum(radial * f * np.log2(f)) / np.sum(radial * f))


def cut_indices(size: int) -> np.ndarray:
    """The slices read along an axis of `size` voxels."""
    return np.unique(np.linspace(0, size - 1, min(CUTS, size)).astype(np.int64))


def face_scales(cut_of, shape, references) -> np.ndarray:
    """(3,) the scale families x, y, z show (NaN for a family that shows no bands):
    cut_of(axis, index) a slice's lightness, references[f] the lightness of the exemplar's
    segmentation family f is compared with."""
    out = np.full(3, np.nan)
    for family in range(3):
        axis = 2 - family
        side = min(s for a, s in enumerate(shape) if a != axis)
        n = window(min(side, *references[family].shape))
        cuts = [cut_of(axis, i) for i in cut_indices(shape[axis])]
        if all(np.ptp(c) < 1e-6 for c in cuts):
            continue
        out[family] = 2.0 ** (centroid([references[family]], n) - centroid(cuts, n))
    return out

"""Smooth random fields for the structure: Gaussian noise filtered to a correlation length or
to a given spectrum (FFT, periodic), generated on a coarse grid where the field is smooth and
interpolated to the volume."""

from __future__ import annotations

import numpy as np

from osmap_cli.solid.upsample import upsample_linear


def spectral_field(shape, amplitude, seed: int) -> np.ndarray:
    """float64 (shape): periodic Gaussian noise whose Fourier amplitudes are `amplitude(kz, ky,
    kx)` (frequencies in cycles per cell, rfft layout), scaled to unit variance."""
    rng = np.random.default_rng(seed)
    white = rng.standard_normal(shape)
    freqs = np.meshgrid(*(np.fft.fftfreq(n) for n in shape[:-1]), np.fft.rfftfreq(shape[-1]),
                        indexing="ij")
    spectrum = np.fft.rfftn(white) * amplitude(*freqs)
    field = np.fft.irfftn(spectrum, s=shape, axes=tuple(range(len(shape))))
    std = field.std()
    return field / std if std > 0 else field


def smooth_noise(shape, length: float, seed: int, wrap: bool = False, along=None,
                 stretch: float = 1.0) -> np.ndarray:
    """float32 (Z, Y, X): unit-variance Gaussian noise with a Gaussian correlation of about
    `length` voxels (`stretch` times that in the direction `along` (z, y, x): below 1, shorter),
    made on a grid min(length, stretch x length) / 4 coarser and interpolated (periodic with
    wrap: the coarse grid divides the volume)."""
    step = max(1.0, min(length, length * stretch) / 4.0)
    if wrap:
        coarse = tuple(max(4, int(round(n / step))) for n in shape)
    else:
        coarse = tuple(max(4, int(np.ceil(n / step)) + 4) for n in shape)
    sigma = [length / (n / c) for n, c in zip(shape, coarse)] if wrap else [length / step] * 3

    def amplitude(kz, ky, kx):
        k = (sigma[0] * kz, sigma[1] * ky, sigma[2] * kx)  # cycles per correlation length
        k2 = k[0] ** 2 + k[1] ** 2 + k[2] ** 2
        if along is not None and stretch != 1.0:
            g = np.asarray(along, np.float64) / np.linalg.norm(along)
            kg = g[0] * k[0] + g[1] * k[1] + g[2] * k[2]
            k2 = k2 + (stretch ** 2 - 1.0) * kg ** 2
        return np.exp(-(np.pi ** 2) * k2)

    field = spectral_field(coarse, amplitude, seed).astype(np.float32)[..., None]
    if wrap:
        return upsample_linear(field, shape, True)[..., 0]
    big = tuple(int(round(c * step)) for c in coarse)
    fine = upsample_linear(field, big, False)[..., 0]
    off = [(b - n) // 2 for b, n in zip(big, shape)]
    return np.ascontiguousarray(fine[off[0]:off[0] + shape[0], off[1]:off[1] + shape[1],
                                     off[2]:off[2] + shape[2]])

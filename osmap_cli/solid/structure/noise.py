"""Smooth random fields for the structure: Gaussian noise filtered to a correlation length or
to a given spectrum (FFT, periodic), generated on a coarse grid where the field is smooth and
interpolated to the volume; and periodic noise that can be read at any point (for warped
turbulence)."""

from __future__ import annotations

import numpy as np

from osmap_cli.solid.upsample import upsample_linear

RADIAL_TOP = np.sqrt(0.5)  # cycles per pixel: the highest radial frequency of a 2D grid
# cycles per voxel: a 3D grid holds every direction up to here only; beyond it the cube's
# corners would favour some directions, so isotropic noise stops here
ISOTROPIC_TOP = 0.5


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


def gaussian_noise_grid(shape, sigma, seed: int) -> np.ndarray:
    """float32 (shape): periodic unit-variance noise with a Gaussian correlation of sigma[d]
    cells along axis d."""

    def amplitude(kz, ky, kx):
        k2 = (sigma[0] * kz) ** 2 + (sigma[1] * ky) ** 2 + (sigma[2] * kx) ** 2
        return np.exp(-(np.pi ** 2) * k2)

    return spectral_field(shape, amplitude, seed).astype(np.float32)


def smooth_noise(shape, length: float, seed: int, wrap: bool = False) -> np.ndarray:
    """float32 (Z, Y, X): unit-variance Gaussian noise with a Gaussian correlation of about
    `length` voxels, made on a grid length / 4 coarser and interpolated (periodic with wrap: the
    coarse grid divides the volume)."""
    step = max(1.0, length / 4.0)
    if wrap:
        coarse = tuple(max(4, int(round(n / step))) for n in shape)
    else:
        coarse = tuple(max(4, int(np.ceil(n / step)) + 4) for n in shape)
    sigma = [length / (n / c) for n, c in zip(shape, coarse)] if wrap else [length / step] * 3
    field = gaussian_noise_grid(coarse, sigma, seed)[..., None]
    if wrap:
        return upsample_linear(field, shape, True)[..., 0]
    big = tuple(int(round(c * step)) for c in coarse)
    fine = upsample_linear(field, big, False)[..., 0]
    off = [(b - n) // 2 for b, n in zip(big, shape)]
    return np.ascontiguousarray(fine[off[0]:off[0] + shape[0], off[1]:off[1] + shape[1],
                                     off[2]:off[2] + shape[2]])


def _bspline_weights(frac: np.ndarray) -> list:
    """The four cubic B-spline weights of the grid points at offsets -1, 0, 1, 2 from a
    point `frac` (0..1) past the second."""
    t = frac
    t2, t3 = t * t, t * t * t
    return [(1 - t) ** 3 / 6, (3 * t3 - 6 * t2 + 4) / 6, (-3 * t3 + 3 * t2 + 3 * t + 1) / 6,
            t3 / 6]


class PeriodicNoise:
    """Unit-variance Gaussian noise with a Gaussian correlation of about `length` voxels,
    periodic over `period` voxels (z, y, x), that can be read at any point (a cubic B-spline
    on a grid `length` / 4 coarse: its gradient is continuous, so level sets of the noise have
    no creases along the grid's planes, as trilinear reading gives them): for noise read at
    warped positions.

    >>> noise = PeriodicNoise((64, 64, 64), 12.0, seed=3)
    >>> values = noise.at(points)          # points (..., 3) in voxels (z, y, x)
    """

    def __init__(self, period, length: float, seed: int):
        coarse = tuple(max(4, int(round(p / max(1.0, length / 4.0)))) for p in period)
        self.step = np.array([p / c for p, c in zip(period, coarse)])
        self.grid = gaussian_noise_grid(coarse, [length / s for s in self.step], seed)

    def at(self, points: np.ndarray) -> np.ndarray:
        """float32 (...): the noise at `points` (..., 3), voxel coordinates (z, y, x)."""
        g = self.grid
        flat = g.ravel()
        pos = points / self.step
        base = np.floor(pos).astype(np.int64)
        frac = (pos - base).astype(np.float32)
        weights = [_bspline_weights(frac[..., d]) for d in range(3)]
        index = [[(base[..., d] + o) % g.shape[d] for o in (-1, 0, 1, 2)] for d in range(3)]
        out = np.zeros(points.shape[:-1], np.float32)
        for a in range(4):
            za = index[0][a] * g.shape[1]
            for b in range(4):
                zb = (za + index[1][b]) * g.shape[2]
                wab = weights[0][a] * weights[1][b]
                for c in range(4):
                    out += wab * weights[2][c] * flat[zb + index[2][c]]
        return out


def slice_matched_spectrum(radial: np.ndarray, side: int = 48, iterations: int = 25):
    """(frequencies, power): an isotropic 3D power spectrum on the bins of `radial` (a 2D radial
    power spectrum on equal bins from 0 to RADIAL_TOP cycles per pixel) whose planar cuts show
    `radial`'s shape. A cut through an isotropic field sums its spectrum along the cut's
    normal, so the 3D spectrum is not the 2D one: it is fitted by multiplicative updates on a
    side^3 grid (the cut's spectrum is linear in the field's, and positive), zero beyond
    ISOTROPIC_TOP."""
    bins = len(radial)
    freqs = (np.arange(bins) + 0.5) * RADIAL_TOP / bins
    f = np.fft.fftfreq(side)
    kz, ky, kx = np.meshgrid(f, f, f, indexing="ij")
    k = np.sqrt(kz ** 2 + ky ** 2 + kx ** 2)
    which = np.minimum((np.sqrt(ky[0] ** 2 + kx[0] ** 2) / RADIAL_TOP * bins).astype(int),
                       bins).ravel()
    count = np.maximum(np.bincount(which, minlength=bins + 1), 1)[:bins]
    target = np.maximum(_smoothed(np.asarray(radial, np.float64)),
                        1e-6 * max(float(np.max(radial)), 1e-30))
    inside = freqs <= ISOTROPIC_TOP
    power = np.where(inside, target, 0.0)
    for _ in range(iterations):
        cut = np.interp(k, freqs, power).sum(0).ravel()
        shown = np.bincount(which, cut, bins + 1)[:bins] / count
        # smoothed and floored: the inversion is ill-posed, and unchecked it makes spikes
        power = np.maximum(_smoothed(power * target / np.maximum(shown, 1e-30)),
                           1e-6 * power.max())
        power[~inside] = 0.0
    return freqs, power


def _smoothed(values: np.ndarray) -> np.ndarray:
    """values filtered by [1, 2, 1] / 4, the ends held."""
    padded = np.concatenate([values[:1], values, values[-1:]])
    return 0.25 * padded[:-2] + 0.5 * padded[1:-1] + 0.25 * padded[2:]


def _stretched(frequencies, power, normal, stretch):
    """The amplitude function of spectral_field for `power` (on `frequencies`) with the
    frequencies within planes perpendicular to `normal` scaled by `stretch`."""
    n = None if normal is None else np.asarray(normal, np.float64) / np.linalg.norm(normal)

    def amplitude(kz, ky, kx):
        k2 = kz ** 2 + ky ** 2 + kx ** 2
        if n is not None and stretch != 1.0:
            along = kz * n[0] + ky * n[1] + kx * n[2]
            k2 = along ** 2 + stretch ** 2 * np.maximum(k2 - along ** 2, 0.0)
        k = np.sqrt(k2)
        return np.where(k <= ISOTROPIC_TOP, np.sqrt(np.interp(k, frequencies, power)), 0.0)

    return amplitude


def oriented_field(shape, frequencies, power, seed: int, normal=None,
                   stretch: float = 1.0) -> np.ndarray:
    """float32 (shape): periodic unit-variance Gaussian noise with the isotropic power spectrum
    `power` (on `frequencies`, cycles per voxel), its correlation `stretch` times longer within
    the planes perpendicular to `normal` (grain lying in those planes; None or 1: isotropic)."""
    return spectral_field(shape, _stretched(frequencies, power, normal, stretch),
                          seed).astype(np.float32)

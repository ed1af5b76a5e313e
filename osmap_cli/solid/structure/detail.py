"""The residual detail of a structured volume (Jagnow et al. 2004: colour, then residual detail):
the band the averaging fill loses, the exemplar's high-pass (the image less its Gaussian blur
of DETAIL_SIGMA), added per phase up to the exemplar's variance of it. Particles and layers copy
it from every voxel's source pixel (residual_detail); veins take it as 3D noise with the
exemplar's spectrum and colours, its grain along the sheets (noise_detail).
"""

from __future__ import annotations

import numpy as np

from osmap_cli.solid.structure.fill import PLANE_AXES
from osmap_cli.solid.structure.noise import (
    RADIAL_TOP,
    face_anisotropy,
    oriented_field,
    slice_matched_spectrum,
)
from osmap_cli.solid.structure.segment import gaussian_blur

DETAIL_SIGMA = 1.0  # pixels: the residual detail is what a Gaussian this wide removes
SPECTRUM_BINS = 32  # radial bins (0 to RADIAL_TOP cycles per pixel) of noise_detail's spectra
STRETCHES = (1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0)  # noise_detail's grain, candidates


def residual_detail(voxels: np.ndarray, source: np.ndarray, images, ex_of_axis, labels,
                    ex_labels, strength: float, wrap: bool = False) -> np.ndarray:
    """voxels with the exemplar's residual detail added (Jagnow et al. 2004: colour, then
    residual detail): every voxel takes the high-pass (the image less its Gaussian blur of
    DETAIL_SIGMA) of its source pixel (source int32 (Z, Y, X, 3) = (axis, row, col)), scaled
    per phase so that the phase's slice high-pass variance reaches `strength` times the
    exemplar's pixels of that phase (a phase the fill already made as detailed gets none).
    The averaging fill loses exactly this band: its wide regions read uniform, coarser than
    the exemplar."""
    if strength <= 0:
        return voxels
    highs = _high_passes(images, wrap)
    ex = np.asarray(ex_of_axis)[source[..., 0]]
    detail = np.zeros_like(voxels)
    for e, high in enumerate(highs):
        sel = ex == e
        if sel.any():
            rows = np.clip(source[..., 1][sel], 0, high.shape[0] - 1)
            cols = np.clip(source[..., 2][sel], 0, high.shape[1] - 1)
            detail[sel] = high[rows, cols]
    own = slice_detail(voxels, wrap)
    added = (detail.astype(np.float64) ** 2).sum(-1)
    used = sorted(set(int(e) for e in ex_of_axis))
    gain = _detail_gain(own, added, highs, used, labels, ex_labels, strength)
    return (voxels + gain[..., None] * detail).astype(np.float32)


def _high_passes(images, wrap: bool) -> list:
    """Every image less its Gaussian blur of DETAIL_SIGMA (float32): the residual detail."""
    return [np.asarray(im, np.float32) - gaussian_blur(im, DETAIL_SIGMA, wrap).astype(np.float32)
            for im in images]


def _detail_gain(own, added, highs, used, labels, ex_labels, strength: float) -> np.ndarray:
    """float32 (Z, Y, X): per phase, the factor on the added detail (its variance per voxel
    `added`) that brings the volume's detail variance (`own` before it) to `strength` times the
    exemplar's high-pass variance in that phase; 0 where the fill already has that much."""
    gain = np.zeros(labels.shape, np.float32)
    for value in np.unique(labels):
        ref = np.concatenate([(highs[e][ex_labels[e] == value] ** 2).sum(-1) for e in used])
        inside = labels == value
        if len(ref) == 0 or not inside.any():
            continue
        want = strength * float(ref.mean()) - float(own[inside].mean())
        have = float(added[inside].mean())
        if want > 0 and have > 0:
            gain[inside] = np.sqrt(want / have)
    return gain


def slice_detail(values: np.ndarray, wrap: bool = False) -> np.ndarray:
    """float64 (Z, Y, X): every voxel's squared high-pass (values less their Gaussian blur of
    DETAIL_SIGMA within a slice), summed over channels, averaged over the three slice families."""
    own = np.zeros(values.shape[:3])
    for axes in PLANE_AXES:
        own += ((values - gaussian_blur(values, DETAIL_SIGMA, wrap, axes)) ** 2).sum(-1) / 3.0
    return own


def _radial_power(high: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The radial power spectrum (SPECTRUM_BINS bins, channels summed, per masked pixel) of a
    high-pass image within mask, its mean within the mask removed, the zero frequency left out."""
    mean = (high * mask[..., None]).sum((0, 1)) / max(float(mask.sum()), 1.0)
    power = (np.abs(np.fft.fft2((high - mean) * mask[..., None], axes=(0, 1))) ** 2).sum(-1)
    fy = np.fft.fftfreq(mask.shape[0])[:, None]
    fx = np.fft.fftfreq(mask.shape[1])[None, :]
    which = np.minimum((np.sqrt(fy ** 2 + fx ** 2) / RADIAL_TOP * SPECTRUM_BINS).astype(int),
                       SPECTRUM_BINS - 1).ravel()
    count = np.bincount(which, minlength=SPECTRUM_BINS)
    sums = np.bincount(which, power.ravel(), SPECTRUM_BINS)
    have = count > 0  # a small exemplar leaves some bins empty: interpolated
    centres = np.arange(SPECTRUM_BINS)
    out = np.interp(centres, centres[have], sums[have] / count[have])
    out[0] = 0.0
    return out / max(float(mask.mean()), 1e-12)


def _anisotropy(high: np.ndarray, labels: np.ndarray) -> float:
    """(l1 - l2) / (l1 + l2) of the central-difference structure tensor of an image's
    luminance, over the pixels whose 3 x 3 neighbourhood is one phase (the phases' own
    texture, not their boundaries): how strongly its gradients share one orientation."""
    lum = high @ np.full(high.shape[2], 1.0 / high.shape[2])
    gy = (lum[2:, 1:-1] - lum[:-2, 1:-1]) / 2
    gx = (lum[1:-1, 2:] - lum[1:-1, :-2]) / 2
    h, w = labels.shape
    inner = np.ones((h - 2, w - 2), bool)
    for dy in range(3):
        for dx in range(3):
            inner &= labels[dy:dy + h - 2, dx:dx + w - 2] == labels[1:-1, 1:-1]
    gy, gx = gy[inner], gx[inner]
    a, b, c = (gy * gy).sum(), (gx * gx).sum(), (gy * gx).sum()
    return float(np.sqrt((a - b) ** 2 + 4 * c * c) / max(a + b, 1e-30))


def noise_detail(voxels: np.ndarray, images, ex_of_axis, labels, ex_labels, strength: float,
                 seed: int, normal=None, wrap: bool = False, grain: float = 0.0) -> np.ndarray:
    """voxels with the exemplar's residual detail (its high-pass: the image less its Gaussian
    blur of DETAIL_SIGMA) given as noise rather than copied: per phase, 3D Gaussian noise whose
    planar cuts show the power spectrum of the phase's high-pass in the exemplar
    (slice_matched_spectrum), coloured by the high-pass's colour covariance, and scaled so that
    the phase's slice high-pass variance reaches `strength` times the exemplar's (as
    residual_detail). Copied detail follows the fill's source pixels, which change with the
    window lattice (every second voxel): on wide uniform regions it prints that lattice as a
    grid; the noise has no lattice and is periodic (it wraps). With `normal` (the sheets' mean
    normal) the noise's correlation is longer within the sheets, by the stretch (STRETCHES)
    whose slices' gradients are as strongly oriented as the exemplar's high-pass: the fine
    streaks run along the veins as the exemplar's do; `grain` > 0 sets that stretch."""
    if strength <= 0:
        return voxels
    highs = _high_passes(images, wrap)
    used = sorted(set(int(e) for e in ex_of_axis))
    shape = voxels.shape[:3]
    phases = []
    for value in np.unique(labels):
        masks = [(ex_labels[e] == value).astype(np.float64) for e in used]
        pixels = np.concatenate([highs[e][m > 0] for e, m in zip(used, masks)])
        if len(pixels) < 2:
            continue
        radial = np.mean([_radial_power(highs[e], m) for e, m in zip(used, masks)
                          if m.sum() >= 2], 0)
        cov = np.atleast_2d(np.cov(pixels.T.astype(np.float64)))
        vals, vecs = np.linalg.eigh(cov)
        root = (vecs * np.sqrt(np.maximum(vals, 0.0))) @ vecs.T
        phases.append((int(value), slice_matched_spectrum(radial), root))
    if not phases:
        return voxels
    stretch = grain if grain > 0 else 1.0
    if normal is not None and grain <= 0:
        want = float(np.mean([_anisotropy(highs[e], ex_labels[e]) for e in used]))
        freqs = phases[0][1][0]  # every phase's spectrum is on the same bins
        power = np.mean([spectrum[1] for _, spectrum, _ in phases], 0)
        stretch = min(STRETCHES, key=lambda s: abs(face_anisotropy(freqs, power, normal, s)
                                                   - want))
    detail = np.zeros(voxels.shape, np.float32)
    channels = voxels.shape[3]
    for value, (freqs, power), root in phases:
        noise = np.stack([oriented_field(shape, freqs, power, seed + 7919 * value + 31 * c,
                                         normal, stretch) for c in range(channels)], -1)
        inside = labels == value
        detail[inside] = (noise[inside] @ root.T).astype(np.float32)
    gain = _detail_gain(slice_detail(voxels, wrap), slice_detail(detail, wrap), highs, used,
                        labels, ex_labels, strength)
    return (voxels + gain[..., None] * detail).astype(np.float32)

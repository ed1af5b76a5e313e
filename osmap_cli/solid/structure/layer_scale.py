"""What a layered volume's bands hold, and the feature scale its own cuts show.

A volume holds few bands: one draw of the chain makes them up to a fifth wider or narrower
than the fit (fitted_sequence rescales each phase's bands to the fitted widths within the
volume), and how the few wide and narrow bands fall still moves a face's scale by up to a
sixth from one seed to the next (layers.layer_bands keeps, of several draws, the one whose
faces read nearest the aim). The scale read here is the spectral centroid (power per
log-frequency band, Welch-averaged Hann windows of the lightness) of each slice family's
cuts, coloured by the phases' lightness, over the same centroid of the exemplar's
segmentation coloured alike: 2 ** (exemplar - cuts), 1 the exemplar's, 2 features twice as
large. It is read on a few evenly spaced slices per family of the antialiased phases the
fill is guided by (layers.Bands.coverage), so it costs a few milliseconds per draw.
"""

from __future__ import annotations

import numpy as np

CUTS = 8  # evenly spaced slices per family, the volume's first and last included
FIT_ROUNDS = 6  # the band widths within a volume: rounds of rescaling (fitted_sequence)
MAX_FIT = 2.0  # ... by at most this factor either way
COVERAGE = 0.5  # voxels: the bands' boundaries antialiased as a Gaussian this wide


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


def held_widths(starts, phases, held: np.ndarray, count: int) -> np.ndarray:
    """(K,) each phase's mean band width along u as the volume holds its bands: `held` the
    volume's u values, sorted; a band counts by the share of its length the volume fills
    (its voxels over its length, relative), so bands cut by the volume's edge count in part
    and the many voxels of a band where the volume is thick count once. NaN: no such band."""
    inside = np.diff(np.searchsorted(held, starts)).astype(np.float64)
    lengths = np.maximum(np.diff(starts), 1e-9)
    mass = np.bincount(phases, inside, count)
    number = np.bincount(phases, inside / lengths, count)
    return np.where(number > 0, mass / np.maximum(number, 1e-300), np.nan)


def fitted_sequence(starts, phases, held: np.ndarray, target: np.ndarray,
                    rounds: int = FIT_ROUNDS):
    """starts of the band sequence with every phase's bands scaled alike, so that the bands the
    volume holds (held: its u values at every voxel, sorted) have the fitted mean widths
    (target: each phase's, layers.fitted_runs). The scaling is about the volume's median u
    (the band there keeps its place), repeated `rounds` times (scaled bands move across the
    volume's thick and thin parts)."""
    centre = float(held[len(held) // 2])
    for _ in range(rounds):
        widths = held_widths(starts, phases, held, len(target))
        scale = np.clip(np.where(np.isnan(widths), 1.0, target / np.where(
            np.isnan(widths), 1.0, widths)), 1 / MAX_FIT, MAX_FIT)
        j = int(np.clip(np.searchsorted(starts, centre, side="right") - 1, 0, len(phases) - 1))
        share = (centre - starts[j]) / max(starts[j + 1] - starts[j], 1e-9)
        lengths = np.diff(starts) * scale[phases]
        starts = np.concatenate([[0.0], np.cumsum(lengths)])
        starts = starts - (starts[j] + share * lengths[j]) + centre
    return starts


def face_reader(u: np.ndarray, lightness, layouts):
    """scales(starts, phases): the scale the volume's faces show (face_scales) with the phases'
    lightness (K,) antialiased as the fill's guide (layers.Bands.coverage), against the
    exemplar's segmentation of each family (layouts[f]: labels); the slices' smooth steps are
    computed once."""
    lightness = np.asarray(lightness, np.float32)
    references = [lightness[lb] for lb in layouts]
    cuts = {}
    for axis in range(3):
        for i in cut_indices(u.shape[axis]):
            lo = max(i - 1, 0)
            slab = np.take(u, np.arange(lo, min(i + 2, u.shape[axis])), axis)
            grad = [np.gradient(slab, axis=a) for a in range(3)]
            width = np.maximum(np.sqrt(sum(g * g for g in grad)), 1e-6) * COVERAGE
            cuts[axis, int(i)] = (np.take(u, i, axis), np.take(width, i - lo, axis))

    def scales(starts, phases):
        def cut_of(axis, i):
            values, width = cuts[axis, int(i)]
            return band_shares(starts, phases, None, values, width, len(lightness)) @ lightness

        return face_scales(cut_of, u.shape, references)

    return scales


def worst_miss(scales, aim: float) -> float:
    """|log| of how far the face farthest from `aim` reads from it (0: no face shows bands)."""
    seen = scales[np.isfinite(scales)]
    return float(np.abs(np.log(seen / aim)).max()) if len(seen) else 0.0


def _step(x: np.ndarray) -> np.ndarray:
    """The Gaussian's cumulative distribution at x (standard deviations), logistic form."""
    return (1.0 / (1.0 + np.exp(-1.702 * np.clip(x, -30.0, 30.0)))).astype(np.float32)


def band_shares(starts, phases, period, u, width, count: int) -> np.ndarray:
    """float32 (..., count): Bands.coverage for values u (read modulo `period` when given)
    whose smooth step is `width` wide."""
    wrap = period is not None
    if wrap:
        u = np.mod(u, period)
    last = len(phases) - 1
    j = np.clip(np.searchsorted(starts, u, side="right") - 1, 0, last)
    below = _step(-(u - starts[j]) / width)
    above = _step(-(starts[j + 1] - u) / width)
    lower = np.where(j > 0, j - 1, last if wrap else 0)
    upper = np.where(j < last, j + 1, 0 if wrap else last)
    out = np.zeros(u.shape + (count,), np.float32)
    for band, share in ((j, np.maximum(1.0 - below - above, 0.0)), (lower, below),
                        (upper, above)):
        phase = phases[band]
        for k in range(count):
            out[..., k] += np.where(phase == k, share, 0.0)
    return out / np.maximum(out.sum(-1, keepdims=True), 1e-6)

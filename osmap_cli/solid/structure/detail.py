"""The residual detail of a structured volume (Jagnow et al. 2004: colour, then residual detail):
the band the averaging fill loses, the exemplar's high-pass (the image less its Gaussian blur
of DETAIL_SIGMA), added per phase up to the exemplar's variance of it. Particles and layers copy
it from every voxel's source pixel (residual_detail); veins take it as 3D noise with the
exemplar's spectrum and colours, the fine band drawn out along the sheets' local planes
(noise_detail, along_sheets).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from osmap_cli.solid.structure.fill import PLANE_AXES
from osmap_cli.solid.structure.noise import RADIAL_TOP, oriented_field, slice_matched_spectrum
from osmap_cli.solid.structure.segment import gaussian_blur

DETAIL_SIGMA = 1.0  # pixels: the residual detail is what a Gaussian this wide removes
SPECTRUM_BINS = 32  # radial bins (0 to RADIAL_TOP cycles per pixel) of noise_detail's spectra
# voxels: noise_detail's grain (the in-sheet Gaussian that draws the fine band out along the
# sheets) is fitted between these two, and kept within GRAIN_RANGE
GRAIN_PAIR = (0.5, 1.0)
GRAIN_RANGE = (0.25, 2.0)
FLOW_SIGMA = 1.5  # pixels: the blur that leaves the veins' flow (the band above the detail)
FLOW_WINDOW = 3.0  # pixels: the flow's structure tensor is averaged over a Gaussian this wide
PROBE_SIDE = 48  # voxels: the grain is fitted on the volume's central cube this wide at most
PROBE_STEP = 4  # the fit reads every this many slices of each family
DIRECTIONS = 64  # grain directions steered between (over the half sphere; any normal lies
#                  within 15 degrees of one)
STEER_RADIUS = 21.0  # degrees: a voxel blends the directions this near its sheets' normal


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


def local_anisotropy(image: np.ndarray, wrap: bool = False) -> float:
    """How strongly an image's detail (the image less its Gaussian blur of DETAIL_SIGMA) runs
    along its own local flow: the mean of cos(2 (angle of the detail's gradient - angle of the
    flow's normal)), weighted by the detail's squared gradient, where the flow's normal is the
    dominant gradient orientation of the image blurred by FLOW_SIGMA, averaged over FLOW_WINDOW
    (structure tensor). 0: the detail ignores the flow; 1: every streak lies along it. Pixels
    within 2 of the edge are left out (the central differences' borders)."""
    img = np.asarray(image, np.float64)
    lum = img.mean(-1)
    high = lum - gaussian_blur(img, DETAIL_SIGMA, wrap).mean(-1)
    fy, fx = np.gradient(gaussian_blur(img, FLOW_SIGMA, wrap).mean(-1))
    tensor = gaussian_blur(np.stack([fy * fy, fx * fx, fy * fx], -1), FLOW_WINDOW, wrap)
    flow = 0.5 * np.arctan2(2 * tensor[..., 2], tensor[..., 0] - tensor[..., 1])
    hy, hx = np.gradient(high)
    inner = (slice(2, -2), slice(2, -2))
    energy = (hy * hy + hx * hx)[inner]
    agree = np.cos(2 * (np.arctan2(hx, hy) - flow))[inner]
    return float((energy * agree).sum() / max(float(energy.sum()), 1e-30))


def _volume_anisotropy(values: np.ndarray) -> float:
    """local_anisotropy averaged over every PROBE_STEP-th slice of every family."""
    return float(np.mean([local_anisotropy(np.take(values, i, axis))
                          for axis in range(3)
                          for i in range(2, values.shape[axis] - 2, PROBE_STEP)]))


def _hemisphere(count: int) -> np.ndarray:
    """(count, 3): unit vectors spread evenly over the half sphere of positive first component
    (a Fibonacci spiral; a grain's normal and its opposite are the same grain)."""
    i = np.arange(count) + 0.5
    first = 1.0 - i / count
    ring = np.sqrt(1.0 - first * first)
    turn = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.stack([first, ring * np.sin(turn), ring * np.cos(turn)], 1)


def along_sheets(values: np.ndarray, normals: np.ndarray, sigma: float,
                 wrap: bool = False) -> np.ndarray:
    """float32 values (Z, Y, X, C) blurred by a Gaussian of `sigma` voxels within the plane of
    every voxel's sheet (normals (Z, Y, X, 3)), not across it: streaks drawn out along the
    sheets, following every fold. Steered: the blur is made (FFT) along each of DIRECTIONS
    normals, and every voxel blends those within STEER_RADIUS of its own, nearer ones more.
    Without wrap the volume is mirrored at its faces first (no wrap-around)."""
    if sigma <= 0:
        return values.astype(np.float32)
    dirs = _hemisphere(DIRECTIONS).astype(np.float32)
    reach = np.float32(np.sin(np.radians(STEER_RADIUS)) ** 2)

    def weight(d):  # made twice rather than held: DIRECTIONS volumes of them would not fit
        return np.maximum(0.0, 1.0 - (1.0 - (normals @ d) ** 2) / reach) ** 2

    total = np.zeros(normals.shape[:3], np.float32)
    for d in dirs:
        total += weight(d)
    total = np.maximum(total, 1e-12)  # every normal is within reach of some direction
    pad = 0 if wrap else int(np.ceil(3 * sigma))
    # mirrored at the faces into a size the FFT factors well
    ends = [(pad, _fast_size(n + 2 * pad) - n - pad) if pad else (0, 0)
            for n in values.shape[:3]]
    padded = np.pad(values.astype(np.float32), ends + [(0, 0)], mode="reflect")
    shape = padded.shape[:3]
    spectrum = np.fft.rfftn(padded, axes=(0, 1, 2))
    k = np.meshgrid(*(np.fft.fftfreq(n).astype(np.float32) for n in shape[:2]),
                    np.fft.rfftfreq(shape[2]).astype(np.float32), indexing="ij")
    k2 = k[0] ** 2 + k[1] ** 2 + k[2] ** 2
    inner = tuple(slice(a, a + n) for (a, _), n in zip(ends, values.shape[:3]))

    def steered(d):
        share = weight(d)
        if not share.any():
            return None
        across = k[0] * d[0] + k[1] * d[1] + k[2] * d[2]
        gauss = np.exp(np.float32(-2.0 * np.pi ** 2 * sigma ** 2) * (k2 - across ** 2))
        blurred = np.fft.irfftn(spectrum * gauss[..., None], s=shape, axes=(0, 1, 2))[inner]
        return (share / total)[..., None] * blurred

    out = np.zeros(values.shape, np.float32)
    from numba import get_num_threads  # the threads the user gave the kernels

    workers = max(1, get_num_threads())
    # NumPy's FFTs release the GIL; the directions are summed in their order whatever the
    # thread count (the same bytes), a batch of `workers` at a time (bounded memory)
    with ThreadPoolExecutor(workers) as pool:
        for start in range(0, len(dirs), workers):
            for part in pool.map(steered, dirs[start:start + workers]):
                if part is not None:
                    out += part
    return out


def _fast_size(n: int) -> int:
    """The least size >= n whose only prime factors are 2, 3 and 5 (a fast FFT)."""
    while True:
        m = n
        for p in (2, 3, 5):
            while m % p == 0:
                m //= p
        if m == 1:
            return n
        n += 1


def noise_detail(voxels: np.ndarray, images, ex_of_axis, labels, ex_labels, strength: float,
                 seed: int, normals=None, wrap: bool = False, grain: float = 0.0) -> np.ndarray:
    """voxels with the exemplar's residual detail (its high-pass: the image less its Gaussian
    blur of DETAIL_SIGMA) given as noise rather than copied: per phase, 3D Gaussian noise whose
    planar cuts show the power spectrum of the phase's high-pass in the exemplar
    (slice_matched_spectrum), coloured by the high-pass's colour covariance, and scaled so that
    the phase's slice high-pass variance reaches `strength` times the exemplar's (as
    residual_detail). Copied detail follows the fill's source pixels, which change with the
    window lattice (every second voxel): on wide uniform regions it prints that lattice as a
    grid; the noise has no lattice and is periodic (it wraps).
    With `normals` (the sheets' local normal at every voxel: sheets.sheet_normals) the fine
    band, the fill's and the noise's alike, is drawn out along the sheets (along_sheets) by the
    grain (voxels; `grain` > 0 sets it, else fitted, fit_grain): the streaks follow every fold
    of the veins, as the exemplar's follow its flow."""
    if strength <= 0:
        return voxels
    highs = _high_passes(images, wrap)
    used = sorted(set(int(e) for e in ex_of_axis))
    detail = _phase_noise(voxels, highs, used, labels, ex_labels, seed)
    if detail is None:
        return voxels
    if normals is not None:
        sigma = grain if grain > 0 else fit_grain(voxels, detail, normals, images, highs, used,
                                                  labels, ex_labels, strength, wrap)
        voxels, detail = _split(along_sheets(np.concatenate([voxels, detail], -1), normals,
                                             sigma, wrap))
    gain = _detail_gain(slice_detail(voxels, wrap), slice_detail(detail, wrap), highs, used,
                        labels, ex_labels, strength)
    return (voxels + gain[..., None] * detail).astype(np.float32)


def _split(both: np.ndarray):
    """The two halves of the channels of `both` (voxels and their detail, filtered at once)."""
    half = both.shape[-1] // 2
    return both[..., :half], both[..., half:]


def _phase_noise(voxels, highs, used, labels, ex_labels, seed: int):
    """float32 (Z, Y, X, C): in every phase, isotropic noise with the spectrum and colours of
    the exemplar's high-pass in that phase (None: no phase has pixels in the exemplar)."""
    shape = voxels.shape[:3]
    detail = np.zeros(voxels.shape, np.float32)
    found = False
    for value in np.unique(labels):
        masks = [(ex_labels[e] == value).astype(np.float64) for e in used]
        pixels = np.concatenate([highs[e][m > 0] for e, m in zip(used, masks)])
        if len(pixels) < 2:
            continue
        radial = np.mean([_radial_power(highs[e], m) for e, m in zip(used, masks)
                          if m.sum() >= 2], 0)
        freqs, power = slice_matched_spectrum(radial)
        cov = np.atleast_2d(np.cov(pixels.T.astype(np.float64)))
        vals, vecs = np.linalg.eigh(cov)
        root = (vecs * np.sqrt(np.maximum(vals, 0.0))) @ vecs.T
        noise = np.stack([oriented_field(shape, freqs, power, seed + 7919 * int(value) + 31 * c)
                          for c in range(voxels.shape[3])], -1)
        inside = labels == value
        detail[inside] = (noise[inside] @ root.T).astype(np.float32)
        found = True
    return detail if found else None


def fit_grain(voxels, detail, normals, images, highs, used, labels, ex_labels, strength: float,
              wrap: bool) -> float:
    """The grain (voxels) whose finished fine band runs along the volume's local flow as
    strongly as the exemplar's runs along its own (local_anisotropy: the same measure on the
    exemplars and on the slices of the volume's central cube, PROBE_SIDE wide, finished there
    as noise_detail finishes the volume). That strength grows steadily with the grain: it is
    measured at the two grains of GRAIN_PAIR and interpolated (within GRAIN_RANGE)."""
    want = float(np.mean([local_anisotropy(images[e], wrap) for e in used]))
    cube = tuple(slice((n - min(n, PROBE_SIDE)) // 2, (n - min(n, PROBE_SIDE)) // 2
                       + min(n, PROBE_SIDE)) for n in voxels.shape[:3])
    fill, noise, normal, label = voxels[cube], detail[cube], normals[cube], labels[cube]
    got = []
    both = np.concatenate([fill, noise], -1)
    for sigma in GRAIN_PAIR:
        smooth, grain = _split(along_sheets(both, normal, sigma))
        gain = _detail_gain(slice_detail(smooth), slice_detail(grain), highs, used, label,
                            ex_labels, strength)
        got.append(_volume_anisotropy(smooth + gain[..., None] * grain))
    (s0, s1), (a0, a1) = GRAIN_PAIR, got
    if a1 <= a0:  # no grain draws this volume's detail out along its sheets
        return GRAIN_RANGE[0]
    return float(np.clip(s0 + (want - a0) * (s1 - s0) / (a1 - a0), *GRAIN_RANGE))

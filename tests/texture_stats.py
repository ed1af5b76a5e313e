"""Objective texture statistics for the tests (numpy only, no code shared with the pipeline).

All distances are on values in [0, 1]; patch distances are RMS per pixel and channel.
"""

import numpy as np


def patches(image: np.ndarray, size: int = 7, stride: int = 1) -> np.ndarray:
    """All size x size patches (flattened) at the given stride."""
    h, w, c = image.shape
    view = np.lib.stride_tricks.sliding_window_view(image, (size, size), axis=(0, 1))
    return view[::stride, ::stride].reshape(-1, c * size * size).astype(np.float64)


def nearest_distances(queries: np.ndarray, references: np.ndarray) -> np.ndarray:
    """RMS distance from each query patch to its nearest reference patch."""
    ref_sq = (references ** 2).sum(1)
    out = np.empty(len(queries))
    for start in range(0, len(queries), 512):
        q = queries[start:start + 512]
        d2 = (q ** 2).sum(1)[:, None] + ref_sq[None] - 2 * q @ references.T
        out[start:start + 512] = np.sqrt(np.maximum(d2.min(1), 0) / q.shape[1])
    return out


def coherence(exemplar: np.ndarray, output: np.ndarray, stride: int = 3) -> float:
    """Mean distance from output patches to their nearest exemplar patch (seams, invented
    content and noise raise it)."""
    return float(nearest_distances(patches(output, stride=stride), patches(exemplar)).mean())


def completeness(exemplar: np.ndarray, output: np.ndarray, stride: int = 3) -> float:
    """Mean distance from exemplar patches to their nearest output patch (missing content)."""
    return float(nearest_distances(patches(exemplar, stride=stride), patches(output)).mean())


def histogram_distance(exemplar: np.ndarray, output: np.ndarray) -> float:
    """Per-channel 1D Wasserstein distance of the value distributions, averaged."""
    q = np.linspace(0, 1, 257)
    return float(np.mean([np.abs(np.quantile(exemplar[..., c], q) - np.quantile(output[..., c], q))
                          .mean() for c in range(exemplar.shape[2])]))


def _radial_spectrum(image: np.ndarray, bins: int = 24):
    gray = image.mean(axis=2)
    gray = gray - gray.mean()
    h, w = gray.shape
    window = np.outer(np.hanning(h), np.hanning(w))
    power = np.abs(np.fft.fftshift(np.fft.fft2(gray * window))) ** 2
    fy, fx = np.meshgrid(np.fft.fftshift(np.fft.fftfreq(h)), np.fft.fftshift(np.fft.fftfreq(w)),
                         indexing="ij")
    radius = np.hypot(fy, fx)
    edges = np.linspace(0.01, 0.5, bins + 1)
    centers = 0.5 * (edges[1:] + edges[:-1])
    spectrum = np.array([power[(radius >= a) & (radius < b)].mean()
                         for a, b in zip(edges[:-1], edges[1:])])
    return centers, spectrum / spectrum.sum()


def feature_scale(exemplar: np.ndarray, output: np.ndarray) -> float:
    """Feature-size ratio output / exemplar from the spectral centroid (1 = same scale)."""
    f, se = _radial_spectrum(exemplar)
    _, so = _radial_spectrum(output)
    return float((f * se).sum() / (f * so).sum())


def _box_mean(a: np.ndarray, radius: int = 2) -> np.ndarray:
    k = 2 * radius + 1
    c = np.pad(np.pad(a, radius, mode="edge").cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    return (c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]) / (k * k)


def _directional_gradients(image: np.ndarray):
    grey = image[..., :3].mean(axis=2)
    down = np.abs(np.diff(grey, axis=0))[:, :-1]
    across = np.abs(np.diff(grey, axis=1))[:-1, :]
    return _box_mean(down), _box_mean(across)


def stripe_fraction(exemplar: np.ndarray, output: np.ndarray, ratio: float = 3.0) -> float:
    """Share of the output's pixels inside stripes: the 5x5-mean gradient along one axis over
    `ratio` times the other's, with contrast above the exemplar's median (1-voxel "barcode"
    patches in volume slices score high; an isotropic texture low)."""
    floor = float(np.median(np.maximum(*_directional_gradients(exemplar))))
    down, across = _directional_gradients(output)
    high, low = np.maximum(down, across), np.minimum(down, across)
    return float(np.mean((high > floor) & (high > ratio * (low + 1e-6))))


def spectrum_distance(exemplar: np.ndarray, output: np.ndarray) -> float:
    """RMS difference (decades) of the normalised radial log power spectra."""
    _, se = _radial_spectrum(exemplar)
    _, so = _radial_spectrum(output)
    return float(np.sqrt(np.mean((np.log10(se + 1e-12) - np.log10(so + 1e-12)) ** 2)))


def dominant_orientation(image: np.ndarray) -> float:
    """Angle (degrees, [0, 180)) of the dominant gradient direction (structure tensor)."""
    gray = image.mean(axis=2)
    gy, gx = np.gradient(gray)
    jxx, jyy, jxy = (gx * gx).sum(), (gy * gy).sum(), (gx * gy).sum()
    return float(np.degrees(0.5 * np.arctan2(2 * jxy, jxx - jyy)) % 180.0)


def axis_energy_share(image: np.ndarray, degrees: float = 7.5) -> float:
    """Share of the gradient energy (Sobel, on the channel mean) whose direction lies within
    `degrees` of the grid axes. Isotropic material scores about 4 x 2 x degrees / 360 (0.17
    for 7.5); rectangular chips, straight cuts between copies and 1-pixel stripes score more."""
    grey = image[..., :3].mean(axis=2).astype(np.float64)
    p = np.pad(grey, 1, mode="edge")
    gx = ((p[:-2, 2:] + 2 * p[1:-1, 2:] + p[2:, 2:]) - (p[:-2, :-2] + 2 * p[1:-1, :-2]
                                                         + p[2:, :-2]))
    gy = ((p[2:, :-2] + 2 * p[2:, 1:-1] + p[2:, 2:]) - (p[:-2, :-2] + 2 * p[:-2, 1:-1]
                                                         + p[:-2, 2:]))
    energy = gx * gx + gy * gy
    angle = np.degrees(np.arctan2(gy, gx)) % 90.0
    near = (angle < degrees) | (angle > 90.0 - degrees)
    return float(energy[near].sum() / max(energy.sum(), 1e-12))


def axis_energy_ratio(exemplar: np.ndarray, images) -> float:
    """Mean axis_energy_share of the images over the exemplar's (1: as axis-aligned as the
    exemplar; boxy or stripy solid-texture slices score well above 1)."""
    return float(np.mean([axis_energy_share(im) for im in images])
                 / max(axis_energy_share(exemplar), 1e-12))


def steps(image, axis):
    """Step between each pixel and the next along axis (wrapping), RMS over channels."""
    return np.sqrt(((image - np.roll(image, -1, axis)) ** 2).sum(-1))


def rim_z(original, output, free, draws=200):
    """Mean step across the border of `free` in output, as a z-score among the mean steps
    along the same contour moved to random places of the original (images in any colour
    space: tests pass RGB, bench/fill_meter.py Lab)."""
    def border_mean(image, mask):
        values = []
        for axis in (0, 1):
            cross = mask != np.roll(mask, -1, axis)
            if axis == 0:
                cross[-1] = False
            else:
                cross[:, -1] = False
            values.append(steps(image, axis)[cross])
        return np.concatenate(values).mean()

    rng = np.random.default_rng(0)
    h, w = free.shape
    ref = [border_mean(np.roll(original, (rng.integers(h), rng.integers(w)), (0, 1)), free)
           for _ in range(draws)]
    return (border_mean(output, free) - np.mean(ref)) / np.std(ref)


def _autocorrelation(gray: np.ndarray) -> np.ndarray:
    """Normalised autocorrelation of a zero-mean gray image, r[dy + h, dx + w] (overlap-normalised,
    no wrap)."""
    x = gray - gray.mean()
    h, w = x.shape
    f = np.fft.rfft2(x, (2 * h, 2 * w))
    num = np.fft.irfft2(np.abs(f) ** 2, (2 * h, 2 * w))
    ones = np.fft.rfft2(np.ones((h, w)), (2 * h, 2 * w))
    count = np.fft.irfft2(np.abs(ones) ** 2, (2 * h, 2 * w))
    return np.fft.fftshift(num / np.maximum(np.rint(count), 1) / max(x.var(), 1e-12))


def _correlation_near(r: np.ndarray, d) -> float:
    """The largest correlation within a pixel of displacement d (dy, dx)."""
    cy, cx = r.shape[0] // 2, r.shape[1] // 2
    y, x = int(round(cy + d[0])), int(round(cx + d[1]))
    window = r[max(y - 1, 0):y + 2, max(x - 1, 0):x + 2]
    return float(window.max()) if window.size else float("nan")


def lattice_vectors(exemplar: np.ndarray):
    """[(dy, dx, r)] the exemplar's two strongest non-collinear autocorrelation peaks outside
    the central lobe (within half its size), strongest first: its lattice, as a person would
    read it off the autocorrelation."""
    gray = exemplar.mean(axis=2)
    r = _autocorrelation(gray)
    h, w = gray.shape
    yy, xx = np.mgrid[-h:h, -w:w]
    radius = np.hypot(yy, xx)
    lobe = next((k for k in range(2, min(h, w) // 2)
                 if r[(radius >= k) & (radius < k + 1)].mean() < 0.1), 2)
    padded = np.pad(r, 1, constant_values=-np.inf)
    around = np.max([padded[1 + a:padded.shape[0] - 1 + a, 1 + b:padded.shape[1] - 1 + b]
                     for a in (-1, 0, 1) for b in (-1, 0, 1)], axis=0)
    peak = (r >= around) & (radius > lobe) & (np.abs(yy) <= h // 2) & (np.abs(xx) <= w // 2)
    peak &= (yy > 0) | ((yy == 0) & (xx > 0))
    found = sorted(((float(r[y, x]), y - h, x - w) for y, x in np.argwhere(peak)), reverse=True)
    first = found[0]
    for value, dy, dx in found[1:]:
        if abs(first[1] * dx - first[2] * dy) > 0.35 * np.hypot(*first[1:]) * np.hypot(dy, dx):
            return [(first[1], first[2], first[0]), (dy, dx, value)]
    return [(first[1], first[2], first[0])]


def regularity(exemplar: np.ndarray, output: np.ndarray):
    """(short, long): how strongly the output correlates with itself at the exemplar's lattice
    vectors, over the exemplar's own peak: at one period (short, the lower of the two vectors)
    and at every multiple that fits in half the output (long, the mean): a lattice that drifts
    or breaks between copies decays in long; 1 = as regular as the exemplar."""
    r = _autocorrelation(output.mean(axis=2))
    half = min(output.shape[:2]) / 2
    short, long_ = [], []
    for dy, dx, own in lattice_vectors(exemplar):
        short.append(_correlation_near(r, (dy, dx)) / own)
        k = 1
        while np.hypot(k * dy, k * dx) <= half:
            long_.append(_correlation_near(r, (k * dy, k * dx)) / own)
            k += 1
    return min(short), float(np.mean(long_))

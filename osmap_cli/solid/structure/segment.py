"""Segmentation of an exemplar into phases: colour clusters (k-means in CIELAB on a lightly
smoothed copy), cleaned of speckle. The same `Segmenter` labels the exemplar and, later, the
slices of a volume (the profile meter), so both are read alike.

>>> seg = Segmenter.fit(image)            # image float32 (H, W, C) in [0, 1]
>>> labels = seg.labels(image)            # int64 (H, W): phase of every pixel
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_kernels.structure import label_components

MAX_SAMPLES = 20000
KMEANS_ITERATIONS = 60
SMOOTH_SIGMA = 0.8  # pixels: removes sensor noise and fibre speckle before clustering
MIN_PHASES, MAX_PHASES = 2, 4
# a further phase must lower the within-cluster variance by at least this share of what is left
SPLIT_GAIN = 0.33
SPECK = 3  # components of at most this many pixels join their surroundings


def lab(image: np.ndarray) -> np.ndarray:
    """float64 (H, W, F): CIELAB of the colour channels (sRGB-encoded values, D65) and alpha
    (x 100) when present; one or two channels: L* (and alpha); more than four: the channels
    x 100."""
    c = image.shape[2]
    if c > 4:
        return image.astype(np.float64) * 100.0
    colour = image[..., :3] if c >= 3 else image[..., :1]
    v = np.clip(colour.astype(np.float64), 0.0, 1.0)
    linear = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
    if c >= 3:
        m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                      [0.0193, 0.1192, 0.9505]])
        xyz = linear @ m.T / np.array([0.95047, 1.0, 1.08883])
    else:
        xyz = np.repeat(linear, 3, axis=2)
    f = np.where(xyz > 216 / 24389, np.cbrt(xyz), (24389 / 27 * xyz + 16) / 116)
    ell = 116 * f[..., 1] - 16
    parts = [ell[..., None]]
    if c >= 3:
        parts += [500 * (f[..., 0] - f[..., 1])[..., None],
                  200 * (f[..., 1] - f[..., 2])[..., None]]
    if c in (2, 4):
        parts.append(image[..., -1:].astype(np.float64) * 100.0)
    return np.concatenate(parts, axis=2)


def gaussian_blur(image: np.ndarray, sigma: float, wrap: bool = False,
                  axes=(0, 1)) -> np.ndarray:
    """image (H, W, ...) blurred by a separable Gaussian along `axes` (reflected edges, or
    wrapped)."""
    if sigma <= 0:
        return image
    radius = max(1, int(np.ceil(3 * sigma)))
    t = np.arange(-radius, radius + 1)
    kernel = np.exp(-0.5 * (t / sigma) ** 2)
    kernel /= kernel.sum()
    out = image.astype(np.float64)
    for axis in axes:
        n = out.shape[axis]
        idx = np.arange(-radius, n + radius)
        idx = idx % n if wrap else np.abs(idx)
        idx = np.where(idx >= n, 2 * (n - 1) - idx, idx) if not wrap else idx
        idx = np.clip(idx, 0, n - 1)
        padded = np.take(out, idx, axis=axis)
        acc = np.zeros_like(out)
        for j, kv in enumerate(kernel):
            acc += kv * np.take(padded, np.arange(j, j + n), axis=axis)
        out = acc
    return out


def smooth_volume(volume: np.ndarray, sigma: float, wrap: bool = False) -> np.ndarray:
    """float32 (Z, Y, X, ...) blurred by a 3D Gaussian."""
    return gaussian_blur(volume, sigma, wrap, axes=(0, 1, 2)).astype(np.float32)


def kmeans(points: np.ndarray, k: int, seed: int = 0) -> tuple[np.ndarray, float]:
    """(centres (k, F), mean squared distance to the nearest centre): k-means++ seeding with a
    fixed generator, then Lloyd iterations to convergence."""
    rng = np.random.default_rng(seed)
    centres = [points[rng.integers(len(points))]]
    d2 = ((points - centres[0]) ** 2).sum(1)
    for _ in range(1, k):
        total = d2.sum()
        pick = rng.choice(len(points), p=d2 / total) if total > 0 else rng.integers(len(points))
        centres.append(points[pick])
        d2 = np.minimum(d2, ((points - points[pick]) ** 2).sum(1))
    centres = np.array(centres)
    assign = None
    for _ in range(KMEANS_ITERATIONS):
        dist = ((points[:, None, :] - centres[None]) ** 2).sum(2)
        new = dist.argmin(1)
        if assign is not None and np.array_equal(new, assign):
            break
        assign = new
        for j in range(k):
            members = points[assign == j]
            if len(members):
                centres[j] = members.mean(0)
    dist = ((points[:, None, :] - centres[None]) ** 2).sum(2)
    return centres, float(dist.min(1).mean())


def clean_labels(labels: np.ndarray, wrap: bool = False, speck: int = SPECK) -> np.ndarray:
    """labels with every component of at most `speck` pixels given the most common label
    around it (repeated until none is left or nothing changes)."""
    out = labels.copy()
    for _ in range(4):
        ids, count = label_components(out, True, wrap)
        sizes = np.bincount(ids.ravel(), minlength=count)
        small = sizes[ids] <= speck
        if not small.any():
            break
        k = int(out.max()) + 1
        votes = np.zeros(out.shape + (k,), np.int64)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dy == 0 and dx == 0:
                    continue
                shifted = np.roll(out, (dy, dx), (0, 1))
                keep = ~np.roll(small, (dy, dx), (0, 1))
                for lab_ in range(k):
                    votes[..., lab_] += (shifted == lab_) & keep
        best = votes.argmax(2)
        has = votes.max(2) > 0
        changed = small & has & (best != out)
        if not changed.any():
            break
        out = np.where(small & has, best, out)
    return out


def _has_intermediate(centres: np.ndarray, slack: float = 0.2) -> bool:
    """Whether one centre lies between two others, near the segment joining them: the blurred
    transition of a smooth boundary (wood's early and late wood), not a material of its own."""
    k = len(centres)
    for j in range(k):
        for i in range(k):
            for m in range(i + 1, k):
                if j in (i, m):
                    continue
                seg = centres[m] - centres[i]
                length2 = float(seg @ seg)
                if length2 == 0:
                    continue
                t = float((centres[j] - centres[i]) @ seg) / length2
                off = centres[j] - (centres[i] + t * seg)
                if 0.1 < t < 0.9 and float(off @ off) < (slack ** 2) * length2:
                    return True
    return False


@dataclass(frozen=True)
class Segmenter:
    """Phase centres in CIELAB (sorted by L*): pixels take the nearest centre after smoothing."""

    centres: np.ndarray
    sigma: float = SMOOTH_SIGMA

    @classmethod
    def fit(cls, image: np.ndarray, phases: int | None = None, wrap: bool = False,
            seed: int = 0) -> Segmenter:
        """Cluster the exemplar's smoothed colours; `phases` None: the smallest count from 2 to
        4 after which one more phase removes less than SPLIT_GAIN of the remaining variance."""
        smooth = gaussian_blur(lab(image), SMOOTH_SIGMA, wrap)
        feats = smooth.reshape(-1, smooth.shape[2])
        rng = np.random.default_rng(seed)
        sample = feats if len(feats) <= MAX_SAMPLES else feats[
            np.sort(rng.choice(len(feats), MAX_SAMPLES, replace=False))]
        counts = [phases] if phases else range(MIN_PHASES, MAX_PHASES + 1)
        fits = [kmeans(sample, k, seed) for k in counts]
        chosen = 0
        if phases is None:
            for i in range(1, len(fits)):
                if fits[i][1] > (1.0 - SPLIT_GAIN) * fits[i - 1][1]:
                    break
                chosen = i
            while chosen > 0 and _has_intermediate(fits[chosen][0]):
                chosen -= 1
        centres = fits[chosen][0]
        return cls(centres[np.argsort(centres[:, 0], kind="stable")])

    def labels(self, image: np.ndarray, wrap: bool = False) -> np.ndarray:
        """int64 (H, W): the nearest phase centre of every smoothed pixel, speckle removed."""
        feats = gaussian_blur(lab(image), self.sigma, wrap)
        dist = ((feats[:, :, None, :] - self.centres[None, None]) ** 2).sum(3)
        return clean_labels(dist.argmin(2).astype(np.int64), wrap)

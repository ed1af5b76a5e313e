"""Image measures the analysis reads: orientation (structure tensor), autocorrelation, the
period of layers along their normal, a 2D lattice test, grey-level morphology with a disc and
the dark network it reveals (cracks, gaps, mortar, cell walls), and distance transforms."""

from __future__ import annotations

import numpy as np

from osmap_cli.solid.structure.segment import gaussian_blur
from osmap_kernels.structure import BIG, squared_distance_rows


def squared_distance(features: np.ndarray, wrap: bool = False, axes=None) -> np.ndarray:
    """float64: the squared Euclidean distance of every cell of an N-D bool array to the
    nearest True cell (exact; separable passes), within the subspaces spanned by `axes` (all
    by default; e.g. the two in-plane axes of a slice family). No feature: BIG."""
    out = np.where(features, 0.0, BIG)
    for axis in range(out.ndim) if axes is None else axes:
        moved = np.moveaxis(out, axis, -1)
        shape = moved.shape
        rows = squared_distance_rows(np.ascontiguousarray(moved.reshape(-1, shape[-1])), wrap)
        out = np.moveaxis(rows.reshape(shape), -1, axis)
    return np.ascontiguousarray(out)


def structure_tensor(lum: np.ndarray, wrap: bool = False, sigma: float = 2.0):
    """(angle of the dominant stripes in degrees, counter-clockwise from the image's x axis
    with rows pointing down; global coherence 0..1; mean local coherence 0..1)."""
    gy, gx = np.gradient(lum)
    j = np.stack([gx * gx, gy * gy, gx * gy], -1)
    js = gaussian_blur(j, sigma, wrap)
    jxx, jyy, jxy = js[..., 0], js[..., 1], js[..., 2]
    tr = jxx + jyy + 1e-12
    local = np.sqrt((jxx - jyy) ** 2 + 4 * jxy ** 2) / tr
    gxx, gyy, gxy = jxx.mean(), jyy.mean(), jxy.mean()
    coherence = float(np.sqrt((gxx - gyy) ** 2 + 4 * gxy ** 2) / (gxx + gyy + 1e-12))
    # the gradient's dominant direction is the stripes' normal; stripes run across it
    normal = 0.5 * np.arctan2(2 * gxy, gxx - gyy)
    stripe = np.degrees(normal) + 90.0
    angle = float(-(((stripe + 90.0) % 180.0) - 90.0))  # rows point down: flip to ccw
    return angle, coherence, float(np.average(local, weights=tr))


def autocorrelation(lum: np.ndarray) -> np.ndarray:
    """The normalised circular autocorrelation of the mean-free image, zero shift at the
    centre (index h // 2, w // 2); 1 there."""
    v = lum - lum.mean()
    f = np.fft.rfft2(v)
    ac = np.fft.irfft2(f * np.conj(f), s=v.shape)
    ac /= max(ac[0, 0], 1e-12)
    return np.fft.fftshift(ac)


def along(ac: np.ndarray, angle_deg: float, length: int) -> np.ndarray:
    """ac sampled (bilinear) along the direction at angle_deg (ccw from x, rows down) from the
    centre, at 0..length-1 pixels."""
    h, w = ac.shape
    t = np.arange(length, dtype=np.float64)
    a = np.radians(angle_deg)
    y = h // 2 - t * np.sin(a)
    x = w // 2 + t * np.cos(a)
    y0 = np.clip(np.floor(y).astype(int), 0, h - 2)
    x0 = np.clip(np.floor(x).astype(int), 0, w - 2)
    fy, fx = y - y0, x - x0
    return ((1 - fy) * (1 - fx) * ac[y0, x0] + (1 - fy) * fx * ac[y0, x0 + 1]
            + fy * (1 - fx) * ac[y0 + 1, x0] + fy * fx * ac[y0 + 1, x0 + 1])


def first_peak(profile: np.ndarray) -> tuple[float, float]:
    """(lag, value) of the first local maximum after the profile first turns up again (the
    period of a repeating pattern); (0, 0) when there is none. Parabolic sub-pixel lag."""
    n = len(profile)
    i = 1
    while i < n - 1 and profile[i + 1] <= profile[i]:
        i += 1
    while i < n - 1 and profile[i + 1] > profile[i]:
        i += 1
    if i >= n - 1 or i < 2:
        return 0.0, 0.0
    a, b, c = profile[i - 1], profile[i], profile[i + 1]
    den = a - 2 * b + c
    shift = 0.5 * (a - c) / den if den < 0 else 0.0
    return float(i + shift), float(b)


def lattice_strength(ac: np.ndarray, min_lag: float = 4.0) -> tuple[float, float]:
    """(strongest, second) autocorrelation peaks beyond min_lag whose directions differ by more
    than 30 degrees (a lattice: bricks, weaves, tiles has two strong ones; layers one)."""
    h, w = ac.shape
    cy, cx = h // 2, w // 2
    yy, xx = np.mgrid[0:h, 0:w]
    r = np.hypot(yy - cy, xx - cx)
    interior = ac[1:-1, 1:-1]
    peak = np.ones_like(interior, bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy or dx:
                peak &= interior >= ac[1 + dy:h - 1 + dy, 1 + dx:w - 1 + dx]
    mask = np.zeros_like(ac, bool)
    mask[1:-1, 1:-1] = peak
    mask &= (r >= min_lag) & (r <= min(h, w) / 3)
    ys, xs = np.nonzero(mask)
    if not len(ys):
        return 0.0, 0.0
    vals = ac[ys, xs]
    order = np.argsort(-vals, kind="stable")
    ang = np.degrees(np.arctan2(-(ys - cy), xs - cx)) % 180.0
    best = order[0]
    for j in order[1:]:
        diff = abs(ang[j] - ang[best]) % 180.0
        if min(diff, 180.0 - diff) > 30.0:
            return float(vals[best]), float(vals[j])
    return float(vals[best]), 0.0


def disc_offsets(radius: int):
    r2 = radius * radius + 0.5
    return [(dy, dx) for dy in range(-radius, radius + 1) for dx in range(-radius, radius + 1)
            if dy * dy + dx * dx <= r2]


def _filter(img: np.ndarray, radius: int, op, wrap: bool) -> np.ndarray:
    h, w = img.shape
    pad = np.pad(img, radius, mode="wrap" if wrap else "reflect")
    out = None
    for dy, dx in disc_offsets(radius):
        s = pad[radius + dy:radius + dy + h, radius + dx:radius + dx + w]
        out = s.copy() if out is None else op(out, s)
    return out


def closing(img: np.ndarray, radius: int, wrap: bool = False) -> np.ndarray:
    return _filter(_filter(img, radius, np.maximum, wrap), radius, np.minimum, wrap)


def black_tophat(lum: np.ndarray, radius: int, wrap: bool = False) -> np.ndarray:
    """closing - image: thin dark structure (narrower than the disc) stands out."""
    return closing(lum, radius, wrap) - lum


def otsu(values: np.ndarray, bins: int = 128) -> float:
    """Otsu's threshold of a set of values."""
    hist, edges = np.histogram(values, bins)
    centres = (edges[1:] + edges[:-1]) / 2
    w0 = np.cumsum(hist)
    w1 = w0[-1] - w0
    s0 = np.cumsum(hist * centres)
    m0 = s0 / np.maximum(w0, 1)
    m1 = (s0[-1] - s0) / np.maximum(w1, 1)
    return float(centres[np.argmax(w0 * w1 * (m0 - m1) ** 2)])

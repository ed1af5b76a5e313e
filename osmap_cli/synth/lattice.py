"""The lattice of a regular texture (bricks, tiles, weaves, knits, printed text), read from the
exemplar's autocorrelation.

A lattice is one or two period vectors (dy, dx) in exemplar pixels, real-valued:
  - two: a 2D lattice (a knit, a weave, tiles): the texture repeats after t1 and after t2;
  - one: stripes (brick courses, planks, lines of text): the texture repeats after t across
    the stripes (t is normal to them) and has no period along them.
`find_lattice` reads it the way Kaspar et al. (2015, "Self tuning texture optimization",
find_grid_base) do: the strongest autocorrelation peak and the strongest one not collinear with
it, reduced to the shortest basis, every basis vector tested for a real period (a peak, not a
point on a ridge), divided down to the primitive period, and fitted to a tenth of a pixel.

>>> lat = Lattice(((12.8, 0.0),))      # courses 12.8 px apart
>>> lat.dual() @ (25.6, 3.0)           # lattice coordinates: two periods down
array([2.])
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Lattice", "autocorrelation", "find_lattice", "parse_lattice"]

# an exemplar has a lattice when its strongest autocorrelation peak reaches this (the
# correlation of the texture with itself one period away; stochastic textures stay under 0.22
# on the development exemplars, regular ones reach 0.29 to 0.56)
MIN_STRENGTH = 0.25
# a peak is a local maximum of at least this (weaker ones are noise)
MIN_PEAK = 0.1
# a basis vector t is a period when r(t) exceeds r(t / 2) by this much; else it lies on a ridge
# of the autocorrelation (stripes: everything along them correlates) and gives no period
MIN_CONTRAST = 0.08
# a divisor t / m of a period is the period itself when r(t / m) reaches this share of r(t)
DIVISOR_SHARE = 0.7
# exemplars are read from a central square this large at most
ANALYSIS_SIZE = 256
# a period shorter than this (pixels) is not a lattice the synthesis can follow
MIN_PERIOD = 4.0


@dataclass(frozen=True)
class Lattice:
    """vectors: one (stripes) or two (a 2D lattice) period vectors (dy, dx) in exemplar pixels;
    strength: the exemplar's autocorrelation at the first (1.0 for vectors given by hand)."""

    vectors: tuple
    strength: float = 1.0

    def basis(self) -> np.ndarray:
        """float64 (2, k): the period vectors as columns."""
        return np.array(self.vectors, np.float64).T

    def dual(self) -> np.ndarray:
        """float64 (k, 2): lattice coordinates of an offset d are dual() @ d (integers on the
        lattice; for stripes the along-stripe part of d is ignored)."""
        return np.linalg.pinv(self.basis())

    def scaled(self, factor: float) -> Lattice:
        """The lattice seen at a pyramid level `factor` times finer (0.5: one level coarser)."""
        return Lattice(tuple((v[0] * factor, v[1] * factor) for v in self.vectors),
                       self.strength)

    def shortest(self) -> float:
        """The shortest period, pixels."""
        return float(min(math.hypot(*v) for v in self.vectors))

    def describe(self) -> str:
        """'DY,DX:DY,DX' as --lattice takes it (rows first), one decimal."""
        return ":".join(f"{v[0]:.1f},{v[1]:.1f}" for v in self.vectors)


def parse_lattice(text: str) -> Lattice:
    """A --lattice value 'DX,DY' or 'DX,DY:DX,DY' (x first, as image sizes are written) as a
    Lattice; ValueError naming the problem otherwise."""
    vectors = []
    for part in text.split(":"):
        try:
            dx, dy = (float(v) for v in part.split(","))
        except ValueError:
            raise ValueError(f"{part!r} is not DX,DY (two numbers)") from None
        if not (math.isfinite(dx) and math.isfinite(dy)):
            raise ValueError(f"{part!r}: the numbers must be finite")
        if math.hypot(dx, dy) < MIN_PERIOD:
            raise ValueError(f"{part!r}: a period must be at least {MIN_PERIOD:g} pixels long")
        vectors.append((dy, dx))
    if len(vectors) > 2:
        raise ValueError("at most two vectors")
    if len(vectors) == 2:
        (a, b), (c, d) = vectors
        area = abs(a * d - b * c)
        if area < 0.2 * math.hypot(a, b) * math.hypot(c, d):
            raise ValueError("the two vectors are (nearly) parallel")
    return Lattice(tuple(vectors))


def autocorrelation(image: np.ndarray, known: np.ndarray | None = None) -> np.ndarray:
    """The normalised autocorrelation r[dy + h, dx + w] of image (h, w[, C]) (each channel's
    mean removed, channels summed, each displacement normalised by its overlap; r[h, w] = 1):
    float64 (2h, 2w). known (bool (h, w), optional): only these pixels count (a hole's are
    left out)."""
    x = np.asarray(image, np.float64)
    if x.ndim == 2:
        x = x[..., None]
    h, w, _ = x.shape
    weight = np.ones((h, w)) if known is None else np.asarray(known, np.float64)
    if weight.sum() < 1:
        return np.zeros((2 * h, 2 * w))
    mean = (x * weight[..., None]).reshape(-1, x.shape[2]).sum(0) / weight.sum()
    x = (x - mean) * weight[..., None]
    variance = float((x * x).sum() / weight.sum())
    power = np.zeros((2 * h, w + 1))
    for c in range(x.shape[2]):
        f = np.fft.rfft2(x[..., c], (2 * h, 2 * w))
        power += (f * np.conj(f)).real
    total = np.fft.irfft2(power, (2 * h, 2 * w))
    ones = np.fft.rfft2(weight, (2 * h, 2 * w))
    overlap = np.fft.irfft2((ones * np.conj(ones)).real, (2 * h, 2 * w))
    # displacements that fewer than an eighth of the pixels see are not read
    enough = np.rint(overlap) >= max(1.0, weight.sum() / 8)
    r = np.where(enough, total / np.maximum(np.rint(overlap), 1.0), 0.0) / max(variance, 1e-12)
    return np.fft.fftshift(r)


class _Correlation:
    """Bilinear reads of an autocorrelation at real displacements (dy, dx)."""

    def __init__(self, r: np.ndarray):
        self.r = r
        self.centre = np.array(r.shape) // 2

    def __call__(self, d) -> np.ndarray:
        d = np.asarray(d, np.float64)
        y = d[..., 0] + self.centre[0]
        x = d[..., 1] + self.centre[1]
        h, w = self.r.shape
        y = np.clip(y, 0, h - 1.001)
        x = np.clip(x, 0, w - 1.001)
        y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
        fy, fx = y - y0, x - x0
        r = self.r
        return ((1 - fy) * ((1 - fx) * r[y0, x0] + fx * r[y0, x0 + 1])
                + fy * ((1 - fx) * r[y0 + 1, x0] + fx * r[y0 + 1, x0 + 1]))


def _peaks(r: np.ndarray, reach) -> list:
    """[(value, (dy, dx))] local maxima of r outside the central lobe, within `reach` (dy, dx),
    in the upper half plane, strongest first."""
    h, w = np.array(r.shape) // 2
    ry, rx = reach
    yy, xx = np.mgrid[-h:h, -w:w]
    radius = np.hypot(yy, xx)
    # the central lobe: out to the first radius where the mean correlation falls under 0.1
    lobe = 2
    for k in range(2, int(min(ry, rx))):
        if r[(radius >= k) & (radius < k + 1)].mean() < 0.1:
            lobe = k
            break
    else:
        return []
    window = (np.abs(yy) <= ry) & (np.abs(xx) <= rx) & (radius > lobe)
    window &= (yy > 0) | ((yy == 0) & (xx > 0))
    padded = np.pad(r, 1, constant_values=-np.inf)
    neighbours = np.max([padded[1 + dy:padded.shape[0] - 1 + dy, 1 + dx:padded.shape[1] - 1 + dx]
                         for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0)
    found = window & (r >= neighbours) & (r >= MIN_PEAK)
    out = [(float(r[y, x]), (float(y - h), float(x - w))) for y, x in np.argwhere(found)]
    return sorted(out, key=lambda p: -p[0])


def _reduce(a, b):
    """The Gauss-reduced basis of the 2D lattice spanned by a and b (shortest vectors)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    for _ in range(32):
        if a @ a > b @ b:
            a, b = b, a
        k = round(float(a @ b) / float(a @ a))
        if k == 0:
            break
        b = b - k * a
    return a, b


def _cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _upper(v):
    """v or -v, whichever points down the rows (or right along row 0)."""
    v = np.asarray(v, np.float64)
    return -v if v[0] < 0 or (v[0] == 0 and v[1] < 0) else v


def _fit(corr: _Correlation, vectors, reach: float):
    """The vectors fitted to the autocorrelation's peaks (weighted least squares over the
    sub-pixel maxima near every lattice point within `reach`; stripes: near every stripe one
    to several periods away, along its length, which also fits the stripes' angle)."""
    vectors = [np.asarray(v, np.float64) for v in vectors]
    offsets = np.linspace(-1.5, 1.5, 31)
    for _ in range(2):
        if len(vectors) == 2:
            coef = _lattice_coefficients(vectors, reach)
            predicted = coef @ np.array(vectors)
            grid = np.stack(np.meshgrid(offsets, offsets, indexing="ij"), -1).reshape(-1, 2)
            values = corr(predicted[:, None, :] + grid[None])  # (m, g)
            best = np.argmax(values, axis=1)
            found = predicted + grid[best]
            weight = np.clip(values[np.arange(len(best)), best], 0.0, None)
            if weight.sum() <= 0:
                return vectors
            sw = np.sqrt(weight)[:, None]
            if np.linalg.matrix_rank(coef * sw) < 2:
                return vectors
            solved, *_ = np.linalg.lstsq(coef * sw, found * sw, rcond=None)
            if max(np.hypot(*(solved[i] - vectors[i])) for i in (0, 1)) > 1.5:
                return vectors  # not the same lattice: keep the peaks' own
            vectors = [solved[0], solved[1]]
        else:
            t = vectors[0]
            period = float(np.hypot(*t))
            normal = t / period
            along = np.array([-normal[1], normal[0]])
            ks = np.arange(1, int(reach / period) + 1, dtype=np.float64)
            us = np.arange(-reach / 2, reach / 2 + 1, 2.0)
            # points k t + u along + o normal: the ridge k's position o at each u
            points = (ks[:, None, None, None] * t + us[None, :, None, None] * along
                      + offsets[None, None, :, None] * normal)
            values = corr(points)  # (K, U, O)
            best = np.argmax(values, axis=2)
            weight = np.clip(np.take_along_axis(values, best[..., None], 2)[..., 0], 0, None)
            if weight.sum() <= 0:
                return vectors
            kk, uu = np.meshgrid(ks, us, indexing="ij")
            where = kk * period + offsets[best]  # distance along the normal
            # where = k * period' + u * slope: the period and the stripes' slope
            design = np.stack([kk.ravel(), uu.ravel()], 1) * np.sqrt(weight.ravel())[:, None]
            (period, slope), *_ = np.linalg.lstsq(design, where.ravel()
                                                  * np.sqrt(weight.ravel()), rcond=None)
            if abs(period - np.hypot(*t)) > 1.5 or abs(slope) > 0.1:
                return vectors
            angle = math.atan(slope)
            normal = normal * math.cos(angle) - along * math.sin(angle)
            vectors = [normal * period * math.cos(angle)]
    return vectors


def _lattice_coefficients(vectors, reach: float) -> np.ndarray:
    """(m, 2) integer pairs (a, b) != 0 with a t1 + b t2 within `reach` of the origin."""
    t1, t2 = vectors
    n = int(reach / min(np.hypot(*t1), np.hypot(*t2))) + 1
    ab = np.array([(a, b) for a in range(-n, n + 1) for b in range(-n, n + 1)
                   if (a, b) != (0, 0)], np.float64)
    points = ab @ np.array([t1, t2])
    return ab[np.hypot(points[:, 0], points[:, 1]) <= reach]


def _lattice_points(vectors, reach: float) -> np.ndarray:
    """(n, 2) displacements the lattice predicts a peak at, within `reach` of the origin:
    a t1 + b t2 (2D), or k t + u along the stripes (u every 4 px)."""
    if len(vectors) == 2:
        return _lattice_coefficients(vectors, reach) @ np.array(vectors)
    t = vectors[0]
    along = np.array([-t[1], t[0]]) / np.hypot(*t)
    ks = np.arange(1, int(reach / np.hypot(*t)) + 1)
    us = np.arange(-reach, reach + 1, 4.0)
    points = (ks[:, None, None] * t + us[None, :, None] * along).reshape(-1, 2)
    return points[np.hypot(points[:, 0], points[:, 1]) <= reach]


def _is_period(value_of, t) -> bool:
    """Whether value_of (the correlation at a displacement) peaks at t: it exceeds its value
    at t / 2 by MIN_CONTRAST."""
    t = np.asarray(t, np.float64)
    return float(value_of(t)) - float(value_of(t / 2)) >= MIN_CONTRAST


def _primitive(t, value_of) -> np.ndarray:
    """The shortest t / m (m = 4, 3, 2, 1) that still correlates as a period of the texture:
    value_of(t / m) at least DIVISOR_SHARE of value_of(t), and a peak."""
    t = np.asarray(t, np.float64)
    for m in (4, 3, 2):
        if np.hypot(*t) / m >= MIN_PERIOD and float(value_of(t / m)) >= \
                DIVISOR_SHARE * float(value_of(t)) and _is_period(value_of, t / m):
            return t / m
    return t


def find_lattice(exemplar: np.ndarray, known: np.ndarray | None = None) -> Lattice | None:
    """The exemplar's lattice (float (h, w[, C])), or None when it has none worth keeping.
    known (bool (h, w), optional): the pixels to read it from (an image with a hole). A
    larger exemplar is read from its central ANALYSIS_SIZE square (periods up to half that
    long; the autocorrelation of a whole photo would cost more than the synthesis)."""
    image = np.asarray(exemplar, np.float64)
    h, w = image.shape[:2]
    y0, x0 = max(0, (h - ANALYSIS_SIZE) // 2), max(0, (w - ANALYSIS_SIZE) // 2)
    image = image[y0:y0 + ANALYSIS_SIZE, x0:x0 + ANALYSIS_SIZE]
    if known is not None:
        known = np.asarray(known, bool)[y0:y0 + ANALYSIS_SIZE, x0:x0 + ANALYSIS_SIZE]
    h, w = image.shape[:2]
    if min(h, w) < 4 * MIN_PERIOD:
        return None
    r = autocorrelation(image, known)
    corr = _Correlation(r)
    reach = min(h, w) / 2
    peaks = [(v, np.array(d)) for v, d in _peaks(r, (h // 2, w // 2))]
    if not peaks or peaks[0][0] < MIN_STRENGTH:
        return None  # no displacement correlates like a period: most stochastic textures
    # periods, not points on a ridge of the autocorrelation (stripes: every point of a stripe
    # one period away correlates, the peaks along it are noise)
    periods = [(v, d) for v, d in peaks if _is_period(corr, d)]
    stripes = _stripes(corr, reach)
    grid = None
    if periods and periods[0][0] >= MIN_STRENGTH:
        grid = _grid(corr, periods, reach, (h, w))
    if grid is not None and stripes is not None and not _beyond_stripes(corr, grid, stripes,
                                                                         (h, w)):
        return stripes
    return grid if grid is not None else stripes


def _beyond_stripes(corr: _Correlation, grid: Lattice, stripes: Lattice, shape) -> bool:
    """Whether the 2D lattice `grid` says more than `stripes` (which it refines): along the
    stripes it repeats within the exemplar's half width, and its points there correlate more
    than the points half its period along the stripes from them. A 2D lattice read from the
    ridges of stripes (planks, lines of text) fails: along a ridge everything correlates."""
    t = np.array(stripes.vectors[0])
    period = float(np.hypot(*t))
    normal = t / period
    along = np.array([-normal[1], normal[0]])
    a, b = (np.array(v) for v in grid.vectors)
    if any(abs(float(v @ normal) / period - round(float(v @ normal) / period)) > 0.2
           for v in (a, b)):
        return True  # not the stripes' lattice: a lattice of its own
    along_period = abs(a[0] * b[1] - a[1] * b[0]) / period
    h, w = shape
    if along_period > min(h, w) / 2:
        return False
    points = _lattice_points([a, b], min(h, w) / 2)
    step = along * along_period / 2
    contrast = corr(points) - 0.5 * (corr(points + step) + corr(points - step))
    return float(np.mean(contrast)) >= MIN_CONTRAST


def _grid(corr: _Correlation, periods, reach: float, shape) -> Lattice | None:
    """The 2D lattice of the strongest period and the strongest one not collinear with it,
    when every vector of its reduced basis (and their sum and difference, where the
    autocorrelation reaches) is a period too; None otherwise."""
    strength, a = periods[0]
    b = next((d for _, d in periods[1:]
              if abs(a[0] * d[1] - a[1] * d[0]) > 0.35 * np.hypot(*a) * np.hypot(*d)), None)
    if b is None:
        return None
    a, b = _reduce(a, b)
    if not _confirmed(corr, (a, b), strength, shape):
        return None
    # the primitive lattice: finer ones (a point between the lattice's points added, itself a
    # period), the finest of them that is confirmed
    confirmed = current = (a, b)
    for _ in range(4):
        a, b = current
        for finer in (a / 2, b / 2, (a + b) / 2, (a - b) / 2, a / 3, b / 3):
            if np.hypot(*finer) >= MIN_PERIOD and _is_period(corr, finer) and \
                    float(corr(finer)) >= DIVISOR_SHARE * min(float(corr(a)), float(corr(b))):
                other = a if abs(_cross(a, finer)) > 1e-6 else b
                current = _reduce(other, finer)
                if _confirmed(corr, current, strength, shape):
                    confirmed = current
                break
        else:
            break
    a, b = confirmed
    a, b = _reduce(*_fit(corr, [a, b], reach))
    if min(np.hypot(*a), np.hypot(*b)) < MIN_PERIOD:
        return None
    vectors = tuple(tuple(round(float(c), 2) for c in _upper(v)) for v in (a, b))
    return Lattice(vectors, round(float(strength), 3))


def _confirmed(corr: _Correlation, basis, strength: float, shape) -> bool:
    """Whether a and b span a 2D lattice of the texture: each is a period (a peak, not a ridge
    point, at least DIVISOR_SHARE of the strength); along each, every lattice point within
    reach peaks against the point half a step back (stripes would pass the first test with
    two points of their ridges, and fail this one along the ridge); and the lattice's further
    points (a + b, a - b and the multiples of a and b, within 3/4 of the exemplar) correlate on
    average at least half as strongly (a lattice repeats; the correlation of strokes or grains
    fades)."""
    a, b = (np.asarray(v, np.float64) for v in basis)
    h, w = shape
    reach = min(h, w) / 2
    points = _lattice_points([a, b], reach)
    for v in (a, b):
        if not _is_period(corr, v) or float(corr(v)) < DIVISOR_SHARE * strength:
            return False
        if float(np.mean(corr(points) - corr(points - v / 2))) < MIN_CONTRAST:
            return False
    further = [a + b, a - b] + [k * v for v in (a, b) for k in range(2, 8)]
    further = [v for v in further if abs(v[0]) <= 0.75 * h and abs(v[1]) <= 0.75 * w]
    return not further or float(np.mean([corr(v) for v in further])) >= 0.5 * strength


def _best_stripes(corr: _Correlation, degrees, us, s, reach: float):
    """(contrast, period, unit normal) of the most periodic stripe profile over the normals at
    `degrees`: the profile across the stripes (the correlation averaged over `us` along each)
    sampled at `s`, contrast its mean at the periods' multiples minus at the half-way points."""
    angles = np.radians(np.asarray(degrees, np.float64))
    normals = np.stack([np.cos(angles), np.sin(angles)], -1)  # (A, 2)
    alongs = np.stack([-normals[:, 1], normals[:, 0]], -1)
    points = (s[None, :, None, None] * normals[:, None, None, :]
              + us[None, None, :, None] * alongs[:, None, None, :])
    profiles = corr(points).mean(axis=2)  # (A, S)
    best = None
    for p in s[int(2 * MIN_PERIOD):len(s) // 2 + 1]:
        ks = np.arange(1, int(reach / p) + 1)
        on = profiles[:, np.rint(2 * ks * p).astype(int)].mean(axis=1)
        off = profiles[:, np.rint(2 * (ks - 0.5) * p).astype(int)].mean(axis=1)
        i = int(np.argmax(on - off))
        if best is None or on[i] - off[i] > best[0] + 1e-9:
            best = (float(on[i] - off[i]), float(p), normals[i])
    return best


def _stripes(corr: _Correlation, reach: float) -> Lattice | None:
    """Stripes: the direction and period whose profile across them (the correlation averaged
    along each stripe) is most periodic, when the stripe one period away correlates at
    MIN_STRENGTH or more somewhere and the profile peaks again at twice the period."""
    us = np.arange(-reach / 2, reach / 2 + 1, 4.0)
    s = np.arange(0.0, reach + 0.25, 0.5)
    best = _best_stripes(corr, np.arange(0.0, 180.0, 3.0), us, s, reach)
    if best is not None:  # the angle to half a degree
        angle = math.degrees(math.atan2(best[2][1], best[2][0])) % 180.0
        finer = _best_stripes(corr, angle + np.arange(-2.5, 2.75, 0.5), us, s, reach)
        best = finer if finer is not None and finer[0] >= best[0] else best
    if best is None or best[0] < MIN_CONTRAST:
        return None
    _, p, normal = best
    t = normal * p
    along = np.array([-normal[1], normal[0]])
    strength = float(corr(t + np.arange(-reach, reach + 1)[:, None] * along).max())
    if strength < MIN_STRENGTH:
        return None

    def ridge_mean(v):  # the correlation along the stripe one displacement v away
        return float(corr(np.asarray(v, np.float64) + us[:, None] * along).mean())

    if ridge_mean(2 * t) < 0.5 * ridge_mean(t):
        return None
    t = _primitive(t, ridge_mean)
    (t,) = _fit(corr, [t], reach)
    if np.hypot(*t) < MIN_PERIOD:
        return None
    return Lattice((tuple(round(float(c), 2) for c in _upper(t)),), round(strength, 3))

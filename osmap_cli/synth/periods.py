"""Period vectors in an autocorrelation: the search behind osmap_cli.synth.lattice.find_lattice.

Peaks, reduced bases, the tests that tell a 2D lattice from stripes and both from a texture's
own short-range correlation, the fits to a tenth of a pixel, and how far the texture's phase
drifts across the exemplar. Vectors are (dy, dx) float64 arrays in exemplar pixels.
"""

from __future__ import annotations

import math

import numpy as np

# a texture has a lattice when the correlation one period away reaches this (stochastic
# textures stay under 0.22 on the development exemplars, regular ones reach 0.26 to 0.56)
MIN_STRENGTH = 0.25
# a peak is a local maximum of at least this (weaker ones are noise)
MIN_PEAK = 0.1
# a basis vector t is a period when r(t) exceeds r(t / 2) by this much; else it lies on a ridge
# of the autocorrelation (stripes: everything along them correlates) and gives no period
MIN_CONTRAST = 0.08
# a divisor t / m of a period is the period itself when r(t / m) reaches this share of r(t)
DIVISOR_SHARE = 0.7
# a period shorter than this (pixels) is not a lattice the synthesis can follow
MIN_PERIOD = 4.0
# the texture's phase is read over a window this many periods wide (its standard deviation)
PHASE_WINDOW = 1.5


class Correlation:
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

    def peaks_at(self, d) -> bool:
        """Whether the autocorrelation has a local maximum within a pixel of d."""
        y = int(round(float(d[0]))) + int(self.centre[0])
        x = int(round(float(d[1]))) + int(self.centre[1])
        h, w = self.r.shape
        if not (2 <= y < h - 2 and 2 <= x < w - 2):
            return False
        near = self.r[y - 1:y + 2, x - 1:x + 2].max()
        return bool(near >= self.r[y - 2:y + 3, x - 2:x + 3].max())


def peaks(r: np.ndarray, reach) -> list:
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


def reduce(a, b):
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


def cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def upper(v):
    """v or -v, whichever points down the rows (or right along row 0)."""
    v = np.asarray(v, np.float64)
    return -v if v[0] < 0 or (v[0] == 0 and v[1] < 0) else v


def fit(corr: Correlation, vectors, reach: float):
    """The vectors fitted to the autocorrelation's peaks (weighted least squares over the
    sub-pixel maxima near every lattice point within `reach`; stripes: near every stripe one
    to several periods away, along its length, which also fits the stripes' angle)."""
    vectors = [np.asarray(v, np.float64) for v in vectors]
    offsets = np.linspace(-1.5, 1.5, 31)
    for _ in range(2):
        if len(vectors) == 2:
            coef = lattice_coefficients(vectors, reach)
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


def lattice_coefficients(vectors, reach: float) -> np.ndarray:
    """(m, 2) integer pairs (a, b) != 0 with a t1 + b t2 within `reach` of the origin."""
    t1, t2 = vectors
    n = int(reach / min(np.hypot(*t1), np.hypot(*t2))) + 1
    ab = np.array([(a, b) for a in range(-n, n + 1) for b in range(-n, n + 1)
                   if (a, b) != (0, 0)], np.float64)
    points = ab @ np.array([t1, t2])
    return ab[np.hypot(points[:, 0], points[:, 1]) <= reach]


def lattice_points(vectors, reach: float) -> np.ndarray:
    """(n, 2) displacements the lattice predicts a peak at, within `reach` of the origin:
    a t1 + b t2 (2D), or k t + u along the stripes (u every 4 px)."""
    if len(vectors) == 2:
        return lattice_coefficients(vectors, reach) @ np.array(vectors)
    t = vectors[0]
    along = np.array([-t[1], t[0]]) / np.hypot(*t)
    ks = np.arange(1, int(reach / np.hypot(*t)) + 1)
    us = np.arange(-reach, reach + 1, 4.0)
    points = (ks[:, None, None] * t + us[None, :, None] * along).reshape(-1, 2)
    return points[np.hypot(points[:, 0], points[:, 1]) <= reach]


def is_period(value_of, t) -> bool:
    """Whether value_of (the correlation at a displacement) peaks at t: it exceeds its value
    at t / 2 by MIN_CONTRAST."""
    t = np.asarray(t, np.float64)
    return float(value_of(t)) - float(value_of(t / 2)) >= MIN_CONTRAST


def primitive(t, value_of) -> np.ndarray:
    """The shortest t / m (m = 4, 3, 2, 1) that still correlates as a period of the texture:
    value_of(t / m) at least DIVISOR_SHARE of value_of(t), and a peak."""
    t = np.asarray(t, np.float64)
    for m in (4, 3, 2):
        if np.hypot(*t) / m >= MIN_PERIOD and float(value_of(t / m)) >= \
                DIVISOR_SHARE * float(value_of(t)) and is_period(value_of, t / m):
            return t / m
    return t


def beyond_stripes(corr: Correlation, grid, stripes, shape) -> bool:
    """Whether the 2D lattice `grid` says more than `stripes` (which it refines): along the
    stripes it repeats within the exemplar's half width, and its points there correlate more
    than the points half its period along the stripes from them. A 2D lattice read from the
    ridges of stripes (planks, lines of text) fails: along a ridge everything correlates."""
    t = np.array(stripes[0])
    period = float(np.hypot(*t))
    normal = t / period
    along = np.array([-normal[1], normal[0]])
    a, b = (np.array(v) for v in grid)
    if any(abs(float(v @ normal) / period - round(float(v @ normal) / period)) > 0.2
           for v in (a, b)):
        return True  # not the stripes' lattice: a lattice of its own
    along_period = abs(a[0] * b[1] - a[1] * b[0]) / period
    h, w = shape
    if along_period > min(h, w) / 2:
        return False
    points = lattice_points([a, b], min(h, w) / 2)
    step = along * along_period / 2
    contrast = corr(points) - 0.5 * (corr(points + step) + corr(points - step))
    return float(np.mean(contrast)) >= MIN_CONTRAST


def grid(corr: Correlation, periods, reach: float, shape):
    """(vectors, strength) of the 2D lattice of the strongest period and the strongest one not
    collinear with it, refined to the finest confirmed lattice and fitted; None when the
    pair is not confirmed (see `confirmed`)."""
    strength, a = periods[0]
    b = next((d for _, d in periods[1:]
              if abs(a[0] * d[1] - a[1] * d[0]) > 0.35 * np.hypot(*a) * np.hypot(*d)), None)
    if b is None:
        return None
    a, b = reduce(a, b)
    if not confirmed(corr, (a, b), strength, shape):
        return None
    a, b = primitive_grid(corr, a, b, strength, shape)
    a, b = reduce(*fit(corr, [a, b], reach))
    if min(np.hypot(*a), np.hypot(*b)) < MIN_PERIOD:
        return None
    vectors = tuple(tuple(round(float(c), 2) for c in upper(v)) for v in (a, b))
    return vectors, round(float(strength), 3)


def primitive_grid(corr: Correlation, a, b, strength: float, shape):
    """The finest confirmed lattice containing the one of a and b: a point a third, a half or
    a quarter of the way between its points added (a period itself, and an autocorrelation
    peak), the shortest such point first, for as long as one gives a confirmed lattice."""
    for _ in range(6):
        finer = []
        for m in (2, 3, 4):
            for i in range(m):
                for j in range(-(m - 1), m):
                    if (i or j > 0) and math.gcd(math.gcd(i, abs(j)), m) == 1:
                        v = (i * a + j * b) / m
                        if np.hypot(*v) >= MIN_PERIOD and is_period(corr, v) and corr.peaks_at(v) \
                                and float(corr(v)) >= DIVISOR_SHARE * min(float(corr(a)),
                                                                          float(corr(b))):
                            finer.append(v)
        for v in sorted(finer, key=lambda v: float(np.hypot(*v))):
            # the lattice of a, b and v: v with a or b, whichever spans the other
            bases = [reduce(x, v) for x in (a, b) if abs(cross(x, v)) > 1e-6]
            basis = next((p for p in bases if _spans(p, a) and _spans(p, b)), None)
            if basis is not None and confirmed(corr, basis, strength, shape):
                a, b = basis
                break
        else:
            return a, b
    return a, b


def _spans(basis, v) -> bool:
    """Whether v is an integer combination of the two basis vectors."""
    coef = np.linalg.solve(np.array(basis).T, v)
    return bool(np.all(np.abs(coef - np.rint(coef)) < 1e-6))


def confirmed(corr: Correlation, basis, strength: float, shape) -> bool:
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
    points = lattice_points([a, b], reach)
    for v in (a, b):
        if not is_period(corr, v) or float(corr(v)) < DIVISOR_SHARE * strength:
            return False
        if len(points) and float(np.mean(corr(points) - corr(points - v / 2))) < MIN_CONTRAST:
            return False
    further = [a + b, a - b] + [k * v for v in (a, b) for k in range(2, 8)]
    further = [v for v in further if abs(v[0]) <= 0.75 * h and abs(v[1]) <= 0.75 * w]
    return not further or float(np.mean([corr(v) for v in further])) >= 0.5 * strength


def best_stripes(corr: Correlation, degrees, us, s, reach: float):
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


def stripes(corr: Correlation, reach: float):
    """((t,), strength) of stripes: the direction and period whose profile across them (the
    correlation averaged along each stripe) is most periodic, when the stripe one period away
    correlates at MIN_STRENGTH or more somewhere and the profile peaks again at twice the
    period; None otherwise."""
    us = np.arange(-reach / 2, reach / 2 + 1, 4.0)
    s = np.arange(0.0, reach + 0.25, 0.5)
    best = best_stripes(corr, np.arange(0.0, 180.0, 3.0), us, s, reach)
    if best is not None:  # the angle to half a degree
        angle = math.degrees(math.atan2(best[2][1], best[2][0])) % 180.0
        finer = best_stripes(corr, angle + np.arange(-2.5, 2.75, 0.5), us, s, reach)
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
    t = primitive(t, ridge_mean)
    (t,) = fit(corr, [t], reach)
    if np.hypot(*t) < MIN_PERIOD:
        return None
    return (tuple(round(float(c), 2) for c in upper(t)),), round(strength, 3)


def drift(image: np.ndarray, vectors, known: np.ndarray | None = None) -> float:
    """How far the texture's phase strays from the lattice across the image, in periods: per
    period vector the local phase (the luminance demodulated at the lattice's frequency over a
    PHASE_WINDOW-period Gaussian window), its gradient fitted with that of a quadratic phase
    (a smooth deformation: perspective, curvature), and the range that phase takes. Rigid
    copies keep a lattice that drifts by a fraction of a period; one that drifts by whole
    periods (bricks seen in perspective, tree rings) has no single lattice to keep."""
    gray = np.asarray(image, np.float64)
    gray = gray.mean(axis=2) if gray.ndim == 3 else gray
    weight = np.ones(gray.shape) if known is None else np.asarray(known, np.float64)
    gray = (gray - (gray * weight).sum() / max(weight.sum(), 1.0)) * weight
    h, w = gray.shape
    rows, cols = np.indices(gray.shape, dtype=np.float64)
    Y, X = (rows - (h - 1) / 2) / h, (cols - (w - 1) / 2) / w
    dual = np.linalg.pinv(np.array(vectors, np.float64).T)
    worst = 0.0
    for n in dual:
        sigma = PHASE_WINDOW / float(np.hypot(*n))
        wave = np.exp(-2j * np.pi * (n[0] * rows + n[1] * cols))
        z = _gaussian(gray * wave.real, sigma) + 1j * _gaussian(gray * wave.imag, sigma)
        gy, gx = np.gradient(z)
        power = np.abs(z) ** 2
        margin = min(int(sigma), h // 4, w // 4)
        inner = (slice(margin, h - margin), slice(margin, w - margin))
        # d(phase)/dy and d(phase)/dx (radians per pixel), weighted by the local amplitude
        fy = (np.imag(np.conj(z) * gy) / np.maximum(power, 1e-12))[inner].ravel()
        fx = (np.imag(np.conj(z) * gx) / np.maximum(power, 1e-12))[inner].ravel()
        y, x = Y[inner].ravel(), X[inner].ravel()
        root = np.sqrt(power[inner].ravel())[:, None]
        if root.sum() <= 0:
            continue
        # phase = a Y + b X + c Y^2 + d X Y + e X^2, its gradient in pixels
        zero, one = np.zeros_like(y), np.ones_like(y)
        by_y = np.stack([one, zero, 2 * y, x, zero], 1) / h
        by_x = np.stack([zero, one, zero, y, 2 * x], 1) / w
        coef, *_ = np.linalg.lstsq(np.concatenate([by_y * root, by_x * root]),
                                   np.concatenate([fy, fx]) * np.concatenate([root, root])[:, 0],
                                   rcond=None)
        phase = (coef[0] * Y + coef[1] * X + coef[2] * Y ** 2 + coef[3] * X * Y
                 + coef[4] * X ** 2)
        worst = max(worst, float(np.ptp(phase)) / (2 * np.pi))
    return worst


def _gaussian(image: np.ndarray, sigma: float) -> np.ndarray:
    """image blurred by a Gaussian of `sigma` pixels (edges mirrored), separably."""
    radius = max(1, min(int(3 * sigma), min(image.shape) - 1))
    taps = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    taps /= taps.sum()
    padded = np.pad(image, radius, mode="reflect")
    out = np.apply_along_axis(np.convolve, 0, padded, taps, "valid")
    return np.apply_along_axis(np.convolve, 1, out, taps, "valid")

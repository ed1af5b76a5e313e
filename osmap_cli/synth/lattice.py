"""The lattice of a regular texture (bricks, tiles, weaves, knits, printed text), read from the
exemplar's autocorrelation.

A lattice is one or two period vectors (dy, dx) in exemplar pixels, real-valued:
  - two: a 2D lattice (a knit, a weave, tiles): the texture repeats after t1 and after t2;
  - one: stripes (brick courses, planks, lines of text): the texture repeats after t across
    the stripes (t is normal to them) and has no period along them.
`find_lattice` reads it the way Kaspar et al. (2015, "Self tuning texture optimization",
find_grid_base) do: the strongest autocorrelation peak and the strongest one not collinear with
it, reduced to the shortest basis, every basis vector tested for a real period (a peak, not a
point on a ridge), divided down to the primitive period, and fitted to the peaks' sub-pixel
positions (osmap_cli.synth.periods); a lattice that drifts by whole periods across the
exemplar (perspective, curved rings) is refused.

>>> lat = Lattice(((12.8, 0.0),))      # courses 12.8 px apart
>>> lat.dual() @ (25.6, 3.0)           # lattice coordinates: two periods down
array([2.])
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from osmap_cli.synth import periods

__all__ = ["Lattice", "autocorrelation", "find_lattice", "parse_lattice"]

# exemplars are read from a central square this large at most
ANALYSIS_SIZE = 256
# a period shorter than this (pixels) is not a lattice the synthesis can follow
MIN_PERIOD = periods.MIN_PERIOD
# a lattice whose phase drifts by more than this many periods across the exemplar is none
# rigid copies can keep (measured: perspective bricks 2.6-2.8, tree rings 4.0; the regular
# development exemplars 0.06-0.6)
MAX_DRIFT = 1.0


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
    parts = text.split(":")
    if len(parts) > 2:
        raise ValueError("at most two vectors")
    vectors = []
    for part in parts:
        name = f"{part!r}: " if len(parts) > 1 else ""
        try:
            dx, dy = (float(v) for v in part.split(","))
        except ValueError:
            raise ValueError(f"{name}not two numbers DX,DY") from None
        if not (math.isfinite(dx) and math.isfinite(dy)):
            raise ValueError(f"{name}the numbers must be finite")
        if math.hypot(dx, dy) < MIN_PERIOD:
            raise ValueError(f"{name}a period must be at least {MIN_PERIOD:g} pixels long")
        vectors.append((dy, dx))
    if len(vectors) == 2:
        (a, b), (c, d) = vectors
        if abs(a * d - b * c) < 0.2 * math.hypot(a, b) * math.hypot(c, d):
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
    corr = periods.Correlation(r)
    reach = min(h, w) / 2
    peaks = [(v, np.array(d)) for v, d in periods.peaks(r, (h // 2, w // 2))]
    if not peaks or peaks[0][0] < periods.MIN_STRENGTH:
        return None  # no displacement correlates like a period: most stochastic textures
    # periods, not points on a ridge of the autocorrelation (stripes: every point of a stripe
    # one period away correlates, the peaks along it are noise)
    candidates = [(v, d) for v, d in peaks if periods.is_period(corr, d)]
    stripes = periods.stripes(corr, reach)
    grid = None
    if candidates and candidates[0][0] >= periods.MIN_STRENGTH:
        grid = periods.grid(corr, candidates, reach, (h, w))
    if grid is not None and stripes is not None \
            and not periods.beyond_stripes(corr, grid[0], stripes[0], (h, w)):
        grid = None
    found = grid if grid is not None else stripes
    if found is None or periods.drift(image, found[0], known) > MAX_DRIFT:
        return None
    return Lattice(*found)

"""Profile statistics of the particles of a labelled image: what a cut through the material
shows. The exemplar's statistics steer the 3D structure (stereology by simulation) and the same
function measures a volume's slices (the profile meter), so both are read alike.

>>> stats = profile_stats(labels, phases=(1, 2))
>>> stats.fraction, stats.diameter_mean, stats.solidity, stats.elongation
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_kernels.structure import hull_areas, label_components

MIN_PROFILE = 4  # pixels: smaller profiles are specks, not counted in the size statistics
QUANTILES = (0.25, 0.5, 0.75, 0.9)


@dataclass(frozen=True)
class ProfileStats:
    """Area fraction of the particle phases; the profiles' equivalent diameters (2 sqrt(A / pi),
    pixels: mean, area-weighted mean, quantiles); count per 10^4 pixels; mean solidity (area over
    convex-hull area) and elongation (major over minor axis of the second moments)."""

    fraction: float
    count: int
    density: float
    diameters: np.ndarray
    solidity: float
    elongation: float

    @property
    def diameter_mean(self) -> float:
        return float(self.diameters.mean()) if len(self.diameters) else 0.0

    @property
    def diameter_weighted(self) -> float:
        """Area-weighted mean diameter: what the eye reads as the size of the stones."""
        d = self.diameters
        return float((d ** 3).sum() / (d ** 2).sum()) if len(d) else 0.0

    def quantiles(self) -> np.ndarray:
        if not len(self.diameters):
            return np.zeros(len(QUANTILES))
        return np.quantile(self.diameters, QUANTILES)

    def scaled(self, factor: float) -> ProfileStats:
        """The same profiles measured on an image `factor` times larger (px lengths x factor)."""
        return ProfileStats(self.fraction, self.count, self.density / factor ** 2,
                            self.diameters * factor, self.solidity, self.elongation)

    def figures(self) -> dict:
        """The compared figures, by name."""
        q = self.quantiles()
        return {"fraction": self.fraction, "diameter": self.diameter_weighted,
                "d50": float(q[1]), "d90": float(q[3]), "solidity": self.solidity,
                "elongation": self.elongation}


def profile_ids(labels: np.ndarray, phases, wrap: bool = False,
                split: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """(ids int64 (H, W), count): 4-connected components of the pixels in `phases` (each
    phase apart), -1 elsewhere. `split`: bool (H, W) of pixels that separate profiles (the
    watershed lines of touching stones); they belong to no profile."""
    mask = np.isin(labels, np.asarray(phases))
    if split is not None:
        mask &= ~split
    return label_components(np.where(mask, labels, -1).astype(np.int64), False, wrap)


def profile_stats(labels: np.ndarray, phases, wrap: bool = False,
                  split: np.ndarray | None = None) -> ProfileStats:
    """Statistics of the profiles of `phases` in `labels` (int64 (H, W)). Profiles touching the
    border of a non-wrapping image count in the fraction, not in sizes or shapes (their size is
    unknown)."""
    h, w = labels.shape
    inside = np.isin(labels, np.asarray(phases))
    ids, count = profile_ids(labels, phases, wrap, split)
    if count == 0:
        return ProfileStats(float(inside.mean()), 0, 0.0, np.zeros(0), 1.0, 1.0)
    flat = ids.ravel()
    keep = flat >= 0
    area = np.bincount(flat[keep], minlength=count).astype(np.float64)
    ok = area >= MIN_PROFILE
    if not wrap:
        edge = np.unique(np.concatenate([ids[0], ids[-1], ids[:, 0], ids[:, -1]]))
        ok[edge[edge >= 0]] = False
    # second moments per profile (wrapped profiles: coordinates unwrapped around a seed pixel)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    if wrap:
        first_y = np.zeros(count)
        first_x = np.zeros(count)
        order = np.flatnonzero(keep)
        rev = order[::-1]
        first_y[flat[rev]] = yy.ravel()[rev]
        first_x[flat[rev]] = xx.ravel()[rev]
        dy = yy.ravel() - np.where(keep, first_y[np.maximum(flat, 0)], 0)
        dx = xx.ravel() - np.where(keep, first_x[np.maximum(flat, 0)], 0)
        yy = (np.where(dy > h / 2, dy - h, np.where(dy < -h / 2, dy + h, dy))).reshape(h, w)
        xx = (np.where(dx > w / 2, dx - w, np.where(dx < -w / 2, dx + w, dx))).reshape(h, w)
    ys, xs = yy.ravel()[keep], xx.ravel()[keep]
    lab = flat[keep]
    my = np.bincount(lab, ys, count) / area
    mx = np.bincount(lab, xs, count) / area
    cyy = np.bincount(lab, ys * ys, count) / area - my ** 2 + 1 / 12
    cxx = np.bincount(lab, xs * xs, count) / area - mx ** 2 + 1 / 12
    cxy = np.bincount(lab, ys * xs, count) / area - my * mx
    tr = cyy + cxx
    det = np.maximum(cyy * cxx - cxy ** 2, 1e-12)
    disc = np.sqrt(np.maximum(tr * tr / 4 - det, 0.0))
    elong = np.sqrt((tr / 2 + disc) / np.maximum(tr / 2 - disc, 1e-9))
    hull = hull_areas(ids, count) if not wrap else None
    if hull is None:
        # wrapped profiles: hulls of the unwrapped coordinates are not pixel-aligned; a profile
        # crossing the wrap keeps the solidity of those that do not
        crossing = np.zeros(count, bool)
        for line, other in ((ids[0], ids[-1]), (ids[:, 0], ids[:, -1])):
            both = (line >= 0) & (line == other)
            crossing[line[both]] = True
        hull = hull_areas(np.where(crossing[np.maximum(ids, 0)] & (ids >= 0), -1, ids), count)
        ok_hull = ok & ~crossing
    else:
        ok_hull = ok
    solidity = area / np.maximum(hull, 1e-9)
    diam = 2.0 * np.sqrt(area[ok] / np.pi)
    return ProfileStats(
        fraction=float(inside.mean()), count=int(ok.sum()),
        density=float(ok.sum() * 1e4 / (h * w)), diameters=np.sort(diam),
        solidity=float(np.average(solidity[ok_hull], weights=area[ok_hull]))
        if ok_hull.any() else 1.0,
        elongation=float(np.average(elong[ok], weights=area[ok])) if ok.any() else 1.0)


def relative_errors(got: ProfileStats, want: ProfileStats) -> dict:
    """|got / want - 1| for every compared figure."""
    a, b = got.figures(), want.figures()
    return {k: abs(a[k] / b[k] - 1.0) if b[k] else float("inf") for k in b}

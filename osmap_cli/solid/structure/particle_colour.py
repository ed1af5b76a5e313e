"""One exemplar particle's colours per 3D particle: every particle's voxels take the colour
distribution of its source profile (exact histogram specification per channel, by each voxel's
rank within its particle), so a cell filled from two exemplar cells of different colours reads
as one cell of its source's colour, while the fill's texture inside it (which voxel is lighter)
stays.

Moving only a particle's mean (fill.match_regions) leaves such a two-coloured cell two-coloured:
its halves keep their difference. The rank mapping squeezes any spread the particle has onto its
source's, which for a uniformly coloured exemplar cell is narrow.

>>> spreads = colour_spreads(image, ids, count)     # with the sources (particles.sources_from)
>>> voxels = match_particles(voxels, built.regions, built.region_sources, spreads,
...                          built.coverage[..., 1], lo, hi)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

QUANTILES = 33  # points of each source profile's colour distribution
# a particle this small (voxels), or a source profile this small (pixels of the enlarged
# exemplar), moves only partly: its distribution is mostly its rim's, or barely known
MIN_VOXELS = 64.0
MIN_PIXELS = 16.0


@dataclass(frozen=True)
class ColourSpreads:
    """Every exemplar profile's mean colour (P, C), principal colour axes (P, C, C, columns),
    colour quantiles along those axes (P, QUANTILES, C) and size in pixels (P,)."""

    means: np.ndarray
    axes: np.ndarray
    quantiles: np.ndarray
    pixels: np.ndarray

    def take(self, which) -> ColourSpreads:
        """The profiles `which` (indices or a mask)."""
        return ColourSpreads(*(getattr(self, f)[which] for f in _FIELDS))

    @staticmethod
    def pooled(spreads: list[ColourSpreads]) -> ColourSpreads:
        """The profiles of several exemplars, in turn."""
        return ColourSpreads(*(np.concatenate([getattr(s, f) for s in spreads])
                               for f in _FIELDS))


_FIELDS = ("means", "axes", "quantiles", "pixels")


def colour_spreads(image: np.ndarray, ids: np.ndarray, count: int) -> ColourSpreads:
    """The spreads of the `count` profiles `ids` (int (H, W), -1 outside) of `image`."""
    flat = ids.ravel()
    keep = flat >= 0
    order = np.argsort(flat[keep], kind="stable")
    lab = flat[keep][order]
    vals = image.reshape(-1, image.shape[2])[keep][order].astype(np.float64)
    starts = np.searchsorted(lab, np.arange(count + 1))
    q = np.linspace(0.0, 1.0, QUANTILES)
    means, axes, tables, sizes = [], [], [], []
    for p in range(count):
        pix = vals[starts[p]:starts[p + 1]]
        centre = pix.mean(0)
        cov = np.atleast_2d(np.cov((pix - centre).T)) if len(pix) > 1 else np.eye(len(centre))
        vecs = np.linalg.eigh(cov)[1]
        means.append(centre)
        axes.append(vecs)
        tables.append(np.quantile((pix - centre) @ vecs, q, axis=0))
        sizes.append(len(pix))
    channels = image.shape[2]
    return ColourSpreads(np.array(means).reshape(-1, channels),
                         np.array(axes).reshape(-1, channels, channels),
                         np.array(tables).reshape(-1, QUANTILES, channels),
                         np.array(sizes, np.float64))


def match_particles(voxels: np.ndarray, regions: np.ndarray, sources: np.ndarray,
                    spreads: ColourSpreads, share: np.ndarray, lo, hi) -> np.ndarray:
    """voxels (Z, Y, X, C) with every particle's colours specified to its source profile's
    distribution along the source's principal colour axes (a cell's shading, along its main
    axis, keeps its range; a second hue, across it, shrinks to the source's narrow spread).
    regions int (Z, Y, X): the particle of every voxel (-1: matrix); sources int (R,): each
    particle's source profile (an index into `spreads`); share (Z, Y, X): the particle's share
    of each voxel (antialiased rims move in proportion). Small particles and small sources move
    partly (MIN_VOXELS, MIN_PIXELS). The result stays within lo .. hi per channel: a
    distribution specified along rotated axes can reach colours outside the exemplar's (below
    black)."""
    flat = regions.ravel()
    keep = np.flatnonzero(flat >= 0)
    if not len(keep) or not len(sources):
        return voxels
    means, axes, tables = spreads.means, spreads.axes, spreads.quantiles
    lab = flat[keep]
    count = np.bincount(lab, minlength=len(sources)).astype(np.float64)
    weight = (np.minimum(1.0, count / MIN_VOXELS)
              * np.minimum(1.0, spreads.pixels[sources] / MIN_PIXELS))[lab]
    weight *= share.ravel()[keep]
    vals = voxels.reshape(-1, voxels.shape[-1])
    src = sources[lab]
    rotated = np.einsum("nc,ncd->nd", vals[keep].astype(np.float64) - means[src], axes[src])
    mapped = np.empty_like(rotated)
    starts = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    last = QUANTILES - 1
    for c in range(rotated.shape[1]):
        order = np.lexsort((rotated[:, c], lab))
        grouped = lab[order]
        at = (np.arange(len(order)) - starts[grouped] + 0.5) / count[grouped] * last
        low = np.minimum(at.astype(np.int64), last - 1)
        t = at - low
        s = sources[grouped]
        mapped[order, c] = tables[s, low, c] * (1.0 - t) + tables[s, low + 1, c] * t
    back = np.einsum("nd,ncd->nc", mapped, axes[src]) + means[src]
    out = vals.astype(np.float64).copy()
    out[keep] += weight[:, None] * (back - out[keep])
    return np.clip(out, lo, hi).reshape(voxels.shape).astype(np.float32)

"""One exemplar particle's colours per 3D particle: every particle's voxels take the colour
distribution of its source profile (exact histogram specification per channel, by each voxel's
rank within its particle), so a cell filled from two exemplar cells of different colours reads
as one cell of its source's colour, while the fill's texture inside it (which voxel is lighter)
stays.

Moving only a particle's mean (fill.match_regions) leaves such a two-coloured cell two-coloured:
its halves keep their difference. The rank mapping squeezes any spread the particle has onto its
source's, which for a uniformly coloured exemplar cell is narrow.

>>> voxels = match_particles(voxels, images, readers, built.regions, built.region_colours,
...                          built.coverage[..., 1])
"""

from __future__ import annotations

import numpy as np

from osmap_cli.solid.structure.analysis import enlarge
from osmap_cli.solid.structure.profiles import profile_ids

QUANTILES = 33  # points of each source profile's colour distribution
# a particle this small (voxels), or a source profile this small (pixels of the enlarged
# exemplar), moves only partly: its distribution is mostly its rim's, or barely known
MIN_VOXELS = 64.0
MIN_PIXELS = 16.0


def source_distributions(images, readers, wrap: bool = False):
    """(means (P, C), axes (P, C, C), quantiles (P, QUANTILES, C), pixels (P,)): every exemplar
    profile's mean colour, principal colour axes (columns), colour quantiles along those axes and
    size, read as the particle sources are (each reader's working mask of the enlarged
    exemplar), profiles of all exemplars in turn."""
    means, axes, tables, sizes = [], [], [], []
    q = np.linspace(0.0, 1.0, QUANTILES)
    for image, reader in zip(images, readers):
        big = enlarge(np.ascontiguousarray(image, np.float32), reader.factor)
        mask = reader.working_mask(big, wrap)
        ids, count = profile_ids(mask.astype(np.int64), (1,), wrap)
        flat = ids.ravel()
        keep = flat >= 0
        order = np.argsort(flat[keep], kind="stable")
        lab = flat[keep][order]
        vals = big.reshape(-1, big.shape[2])[keep][order].astype(np.float64)
        starts = np.searchsorted(lab, np.arange(count + 1))
        for p in range(count):
            pix = vals[starts[p]:starts[p + 1]]
            centre = pix.mean(0)
            cov = np.atleast_2d(np.cov((pix - centre).T)) if len(pix) > 1 else np.eye(len(centre))
            vecs = np.linalg.eigh(cov)[1]
            means.append(centre)
            axes.append(vecs)
            tables.append(np.quantile((pix - centre) @ vecs, q, axis=0))
            sizes.append(len(pix))
    return np.array(means), np.array(axes), np.array(tables), np.array(sizes, np.float64)


def match_particles(voxels: np.ndarray, images, readers, regions: np.ndarray,
                    targets: np.ndarray, share: np.ndarray, wrap: bool = False) -> np.ndarray:
    """voxels (Z, Y, X, C) with every particle's colours specified to its source profile's
    distribution along the source's principal colour axes (a cell's shading, along its main
    axis, keeps its range; a second hue, across it, shrinks to the source's narrow spread).
    regions int (Z, Y, X): the particle of every voxel (-1: matrix); targets (R, C): each
    particle's source profile's mean colour (the source is the exemplar profile of that mean);
    share (Z, Y, X): the particle's share of each voxel (antialiased rims move in proportion).
    Small particles and small sources move partly (MIN_VOXELS, MIN_PIXELS). The result stays
    within the exemplars' range per channel: a distribution specified along rotated axes can
    reach colours outside it (below black), which an image file would clip."""
    flat = regions.ravel()
    keep = np.flatnonzero(flat >= 0)
    if not len(keep) or not len(targets):
        return voxels
    means, axes, tables, sizes = source_distributions(images, readers, wrap)
    if not len(means):
        return voxels
    source = np.argmin(((targets[:, None, :] - means[None]) ** 2).sum(2), 1)
    lab = flat[keep]
    count = np.bincount(lab, minlength=len(targets)).astype(np.float64)
    weight = (np.minimum(1.0, count / MIN_VOXELS)
              * np.minimum(1.0, sizes[source] / MIN_PIXELS))[lab]
    weight *= share.ravel()[keep]
    vals = voxels.reshape(-1, voxels.shape[-1])
    src = source[lab]
    rotated = np.einsum("nc,ncd->nd", vals[keep].astype(np.float64) - means[src], axes[src])
    mapped = np.empty_like(rotated)
    starts = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    last = QUANTILES - 1
    for c in range(rotated.shape[1]):
        order = np.lexsort((rotated[:, c], lab))
        grouped = lab[order]
        at = (np.arange(len(order)) - starts[grouped] + 0.5) / count[grouped] * last
        lo = np.minimum(at.astype(np.int64), last - 1)
        t = at - lo
        s = source[grouped]
        mapped[order, c] = tables[s, lo, c] * (1.0 - t) + tables[s, lo + 1, c] * t
    back = np.einsum("nd,ncd->nc", mapped, axes[src]) + means[src]
    out = vals.astype(np.float64).copy()
    out[keep] += weight[:, None] * (back - out[keep])
    pixels = np.concatenate([im.reshape(-1, im.shape[-1]) for im in images])
    out = np.clip(out, pixels.min(0), pixels.max(0))
    return out.reshape(voxels.shape).astype(np.float32)

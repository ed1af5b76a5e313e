"""Constraints on a position field: pixels pinned to known exemplar positions, and exemplar
positions that no candidate may take.

Inpainting pins every pixel outside the mask to its own position and forbids the positions
whose matching window touches the hole; a tileable photo pins its centre. The refinement
(osmap_cli.synth.refine.refine) applies a :class:`LevelConstraint` per pyramid level: a
forbidden position costs infinity (through the occupancy factor of the candidate cost), and
pinned pixels are reset after every pass.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.texture.pyramid import half_size

__all__ = ["LevelConstraint", "dilate", "identity_positions", "mask_pyramid", "push_pull"]


@dataclass(frozen=True)
class LevelConstraint:
    """One pyramid level: pinned bool (H, W), known float32 (H, W, 2) positions of the pinned
    pixels, forbidden bool (h, w) exemplar positions."""

    pinned: np.ndarray
    known: np.ndarray
    forbidden: np.ndarray
    usage_scale: float = 1.0  # occupancy times this (an atlas: the share that is exemplar)
    # whether the pinned pixels count in the occupancy (their use of the exemplar); a tileable
    # photo's centre uses every centre position once, which is no reason to avoid them
    count_pinned: bool = True

    def pin(self, pos: np.ndarray) -> np.ndarray:
        """pos with the pinned pixels at their known positions (pos is modified)."""
        pos[self.pinned] = self.known[self.pinned]
        return pos

    def penalise(self, occ: np.ndarray, lam: float):
        """(occupancy, lam) for the candidate cost cost * (1 + lam * occ): infinite on the
        forbidden positions, unchanged elsewhere (lam 0: occ 0 elsewhere, lam 1)."""
        if not self.forbidden.any():
            return occ, lam
        if self.usage_scale != 1.0:
            occ = occ * np.float32(self.usage_scale)
        if lam == 0.0:
            occ, lam = np.zeros_like(occ), 1.0
        return np.where(self.forbidden, np.float32(np.inf), occ).astype(np.float32), lam

    def counted(self, pos: np.ndarray, source_pixels: int):
        """(positions, samples) for the occupancy: pos and its pixel count, or, when
        count_pinned is False, (1, n, 2) of the free pixels only, with at least one sample per
        source pixel (a position used once is then uniform use, not over-use)."""
        if self.count_pinned:
            return pos, pos.shape[0] * pos.shape[1]
        free = np.ascontiguousarray(pos[~self.pinned][None])
        return free, max(free.shape[1], source_pixels)

    def unlinked(self, pos: np.ndarray) -> np.ndarray:
        """pos with every pinned pixel moved far away and apart, for measuring the copy regions
        of the synthesized pixels only (the kept region is not a copy that grows too large)."""
        out = pos.copy()
        ys, xs = np.nonzero(self.pinned)
        out[ys, xs, 0] = -1e6 * (ys + 1.0)
        out[ys, xs, 1] = -1e6 * (xs + 1.0)
        return out


def identity_positions(shape) -> np.ndarray:
    """float32 (H, W, 2): every pixel's own (row, col)."""
    rows, cols = np.indices(shape, dtype=np.float32)
    return np.stack([rows, cols], -1)


def mask_pyramid(mask: np.ndarray, levels: int) -> list[np.ndarray]:
    """[finest, ..., coarsest] bool masks, each level's pixel set where any of its (up to 2x2)
    finer pixels is (the shapes of osmap_cli.texture.pyramid.half_size)."""
    out = [np.asarray(mask, bool)]
    for _ in range(levels - 1):
        fine = out[-1]
        h, w = half_size(fine.shape)
        padded = np.zeros((2 * h, 2 * w), bool)
        padded[:fine.shape[0], :fine.shape[1]] = fine
        out.append(padded.reshape(h, 2, w, 2).any(axis=(1, 3)))
    return out


def dilate(mask: np.ndarray, radius: int, wrap: bool = False) -> np.ndarray:
    """mask grown by `radius` pixels (a square: Chebyshev distance)."""
    out = mask.copy()
    if radius <= 0:
        return out
    h, w = mask.shape
    for axis, size in ((0, h), (1, w)):
        src = out.copy()
        for d in range(1, radius + 1):
            if wrap:
                out |= np.roll(src, d, axis) | np.roll(src, -d, axis)
            elif d < size:
                if axis == 0:
                    out[d:] |= src[:-d]
                    out[:-d] |= src[d:]
                else:
                    out[:, d:] |= src[:, :-d]
                    out[:, :-d] |= src[:, d:]
    return out


def push_pull(image: np.ndarray, known: np.ndarray) -> np.ndarray:
    """image (H, W, C) with the pixels where `known` is False replaced by a smooth fill from
    the known ones (push-pull: averaged down a 2x2 pyramid, interpolated back up)."""
    if known.all():
        return image
    stack = []
    values = np.where(known[..., None], image, 0.0).astype(np.float64)
    weights = known.astype(np.float64)
    while True:
        stack.append((values, weights))
        h, w = weights.shape
        if h == 1 and w == 1:
            break
        h2, w2 = half_size((h, w))
        v = np.zeros((2 * h2, 2 * w2, values.shape[2]))
        v[:h, :w] = values
        wt = np.zeros((2 * h2, 2 * w2))
        wt[:h, :w] = weights
        values = v.reshape(h2, 2, w2, 2, -1).sum(axis=(1, 3))
        weights = wt.reshape(h2, 2, w2, 2).sum(axis=(1, 3))
    filled = None
    for values, weights in reversed(stack):
        mean = values / np.maximum(weights, 1e-12)[..., None]
        if filled is None:
            filled = mean
            continue
        h, w = weights.shape
        up = np.repeat(np.repeat(filled, 2, 0), 2, 1)[:h, :w]
        share = np.minimum(weights, 1.0)[..., None]
        filled = share * mean + (1.0 - share) * up
    return np.where(known[..., None], image, filled.astype(np.float32))

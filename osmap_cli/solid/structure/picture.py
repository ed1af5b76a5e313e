"""The picture `osmap solid --analyse` writes: the exemplar beside its segmentation (each phase,
or each particle profile, in its mean colour; profile outlines dark), enlarged so small
exemplars stay readable."""

from __future__ import annotations

import numpy as np

from osmap_cli.solid.structure.analysis import Analysis
from osmap_cli.solid.structure.profiles import profile_ids

GAP = 4
MIN_SIDE = 256


def _rgb(image: np.ndarray) -> np.ndarray:
    c = image.shape[2]
    if c >= 3:
        return image[..., :3]
    return np.repeat(image[..., :1], 3, axis=2)


def segmentation_picture(image: np.ndarray, found: Analysis) -> np.ndarray:
    """float32 (H', W', 3): the exemplar | its segmentation."""
    rgb = _rgb(np.clip(image, 0.0, 1.0)).astype(np.float32)
    labels = found.labels
    if found.kind == "particles":
        mask = labels.astype(bool)
        ids, count = profile_ids(mask.astype(np.int64), (1,))
        flat = ids.ravel()
        keep = flat >= 0
        area = np.maximum(np.bincount(flat[keep], minlength=count), 1)
        means = np.stack([np.bincount(flat[keep], rgb.reshape(-1, 3)[keep, c], count) / area
                          for c in range(3)], 1)
        matrix = rgb[~mask].mean(0) if (~mask).any() else np.zeros(3)
        seg = np.where(mask[..., None], means[np.maximum(ids, 0)], matrix)
        edge = mask & ~(np.roll(mask, 1, 0) & np.roll(mask, -1, 0) & np.roll(mask, 1, 1)
                        & np.roll(mask, -1, 1))
        seg[edge] *= 0.35
    else:
        colours = _rgb(found.colours[None])[0]
        seg = colours[labels]
    scale = max(1, int(np.ceil(MIN_SIDE / max(min(rgb.shape[:2]), 1))))
    both = [np.repeat(np.repeat(a, scale, 0), scale, 1) for a in (rgb, seg.astype(np.float32))]
    h, w = both[0].shape[:2]
    out = np.ones((h, 2 * w + GAP, 3), np.float32)
    out[:, :w] = both[0]
    out[:, w + GAP:] = both[1]
    return out

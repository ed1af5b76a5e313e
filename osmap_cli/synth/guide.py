"""Guided synthesis: the output follows a target guide where the exemplar follows its own guide.

A guide is a float32 (h, w) map, one value per pixel (a painted mask, a gradient, a height map).
The exemplar's guide (``--guide``) has the exemplar's size; without one the exemplar's own
luminance, blurred and stretched to 0..1, is its guide, and the target guide is stretched to
0..1 as well (a photo of any contrast then spans the exemplar's range). The target guide
(``--target-guide``) is resized to the output size, whatever its size. Both are reduced like
the exemplar pyramid (osmap_cli.texture.pyramid), and the refinement adds, per candidate
position, ``guide_weight * (G_ex[candidate] - G_target[pixel])^2`` in units of a whole
window's feature variance (osmap_cli.synth.refine).
"""

from __future__ import annotations

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.texture.pyramid import build_pyramid, resize

__all__ = ["auto_guide", "guide_levels", "load_guide", "luminance", "stretch"]

# blur of the automatic guide (exemplar luminance): OpenImageIO's Gaussian filter of this width
# (pixels), a standard deviation of about 2 px: the regions, not the grain
AUTO_WIDTH = 9.0


def luminance(pixels: np.ndarray) -> np.ndarray:
    """float32 (h, w): Rec. 709 luminance of RGB(A) pixels; a gray (+ alpha) image's gray."""
    pixels = np.asarray(pixels, np.float32)
    if pixels.ndim == 2:
        return pixels
    if pixels.shape[2] >= 3:
        rgb = pixels[..., :3].astype(np.float64)
        return (rgb @ np.array([0.2126, 0.7152, 0.0722])).astype(np.float32)
    return pixels[..., 0].copy()


def _blur(image: np.ndarray) -> np.ndarray:
    """OpenImageIO's Gaussian (filter width AUTO_WIDTH), edges mirrored."""
    import OpenImageIO as oiio

    pad = int(AUTO_WIDTH) // 2 + 1
    padded = np.pad(np.asarray(image, np.float32), pad,
                    mode="symmetric" if min(image.shape) > pad else "edge")
    kernel = oiio.ImageBufAlgo.make_kernel("gaussian", AUTO_WIDTH, AUTO_WIDTH)
    blurred = oiio.ImageBufAlgo.convolve(oiio.ImageBuf(np.ascontiguousarray(padded[..., None])),
                                         kernel)
    out = blurred.get_pixels(oiio.FLOAT).reshape(padded.shape)
    return out[pad:-pad, pad:-pad]


def stretch(guide: np.ndarray) -> np.ndarray:
    """float32 guide stretched to 0..1 (a flat guide: all 0)."""
    guide = np.asarray(guide, np.float64)
    lo, hi = float(guide.min()), float(guide.max())
    if hi - lo < 1e-6:
        return np.zeros(guide.shape, np.float32)
    return ((guide - lo) / (hi - lo)).astype(np.float32)


def auto_guide(exemplar: np.ndarray) -> np.ndarray:
    """The exemplar's own guide: its luminance, blurred (AUTO_WIDTH), stretched to 0..1."""
    return stretch(_blur(luminance(exemplar)))


def guide_levels(guide: np.ndarray, shape, levels: int, values=None) -> list[np.ndarray]:
    """[finest, ..., coarsest] float32 (h, w) guides: `guide` resized to `shape`, then halved
    like the exemplar pyramid. With `values` (a painted exemplar guide's values: a map of
    materials) and a `guide` painted in them alone, every level's pixel takes the value nearest
    it: halving would otherwise blur the border between two materials into values between
    theirs, which cost either material little there, and a copy of one would spill across the
    border at the coarse levels, where the layout forms, by as many output pixels as the blur
    spans at the finest. A guide with other values (a gradient between materials) is kept as
    it is."""
    image = np.asarray(guide, np.float32)[..., None]
    table = None if values is None else np.asarray(values, np.float32)
    painted = table is not None and bool(np.isin(image, table).all())
    if image.shape[:2] != tuple(shape):
        image = resize(image, int(shape[0]), int(shape[1]))
    out = [np.ascontiguousarray(level[..., 0]) for level in build_pyramid(image, levels)]
    if not painted:
        return out
    return [np.ascontiguousarray(table[np.abs(level[..., None] - table).argmin(axis=-1)])
            for level in out]


def load_guide(path: str, flag: str) -> np.ndarray:
    """A guide file as float32 (h, w): gray (+ alpha) as stored, RGB(A) as its luminance
    (alpha ignored). OsmapError naming the file for anything else."""
    from osmap_cli.fields import read_map

    pixels = read_map(path, flag).pixels
    channels = pixels.shape[2]
    if channels not in (1, 2, 3, 4):
        raise OsmapError(f"{path}: {channels} channels; {flag} needs a gray or RGB(A) image")
    return luminance(pixels)

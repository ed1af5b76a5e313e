"""Control fields: per-output-pixel orientation and scale, turned into a Jacobian field.

``--orientation-field FILE`` gives the direction of the texture per output pixel, added to
``--orientation``; ``--scale-field FILE`` gives the feature size per pixel, multiplied with
``--scale``. Encodings (docs/fields.md):

* orientation, gray image (1 channel, gray + alpha, or R = G = B): integer files (8/16-bit)
  0..1 = 0..360 degrees counter-clockwise; float files (EXR, float TIFF) degrees as stored.
* orientation, colour image: the vector (R, G), x to the right and y *up*; integer files are
  decoded as 2 v - 1 (0.5 = zero, like a flow map), float files as stored. Angle = atan2(G, R).
* scale, gray image (colour: the mean of the colour channels): integer files 0..1 =
  2^(2 v - 1) = 0.5..2 (mid gray = 1); float files the scale factor as stored (> 0).

A field of any size is resized to the output size (OpenImageIO), as the three smooth channels
(cos, sin, log2 scale), so angles interpolate the short way round; each pyramid level resizes
the same channels again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from osmap_cli.errors import OsmapError

__all__ = ["ControlFields", "jacobians", "load_fields"]


@dataclass(frozen=True)
class ControlFields:
    """float32 (H, W) maps at some resolution: angle cos/sin (degrees added to the base
    orientation) and log2 of the scale factor (added to log2 of the base scale)."""

    cos: np.ndarray
    sin: np.ndarray
    log2_scale: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        return self.cos.shape

    def resized(self, shape) -> ControlFields:
        """The same fields at another resolution."""
        if tuple(shape) == self.shape:
            return self
        from osmap_cli.texture.pyramid import resize

        stack = np.stack([self.cos, self.sin, self.log2_scale], -1)
        out = resize(stack, int(shape[0]), int(shape[1]))
        return ControlFields(out[..., 0].copy(), out[..., 1].copy(), out[..., 2].copy())

    def jacobian_field(self, shape, orientation: float, scale: float,
                       anisotropy: float) -> np.ndarray:
        """float32 (H, W, 2, 2) output-to-exemplar Jacobian (row/col order) at `shape`."""
        f = self.resized(shape)
        base = math.radians(orientation)
        cb, sb = math.cos(base), math.sin(base)
        norm = np.hypot(f.cos, f.sin)
        norm = np.where(norm > 1e-6, norm, 1.0)
        c0, s0 = f.cos / norm, f.sin / norm
        c = c0 * cb - s0 * sb
        s = s0 * cb + c0 * sb
        s_factor = scale * np.exp2(f.log2_scale)
        return jacobians(c, s, s_factor, anisotropy)

    def representative(self, orientation: float, scale: float) -> tuple[float, float]:
        """(orientation, scale) summarising the field: the mean direction when the directions
        agree (resultant length > 0.5), else the base orientation; the geometric mean scale."""
        mc, ms = float(self.cos.mean()), float(self.sin.mean())
        angle = orientation
        if math.hypot(mc, ms) > 0.5:
            angle = orientation + math.degrees(math.atan2(ms, mc))
        return angle, scale * float(np.exp2(self.log2_scale.mean()))


def jacobians(c, s, scale, anisotropy: float) -> np.ndarray:
    """Vectorised SynthOptions.jacobian: J for rotation (cos c, sin s), scale and anisotropy.

    J = swap (scale R diag(a, 1))^-1 swap = (1 / scale) [[c, s], [-s / a, c / a]].
    """
    c = np.asarray(c, np.float64)
    s = np.asarray(s, np.float64)
    inv = 1.0 / np.asarray(scale, np.float64)
    out = np.empty(c.shape + (2, 2), np.float64)
    out[..., 0, 0] = c * inv
    out[..., 0, 1] = s * inv
    out[..., 1, 0] = -s * inv / anisotropy
    out[..., 1, 1] = c * inv / anisotropy
    return out.astype(np.float32)


def _is_gray(image) -> bool:
    names = tuple(image.channel_names)
    if image.pixels.shape[2] == 1 or names in (("Y", "A"), ("Y",)):
        return True
    colour = _colour_channels(image)
    if len(colour) < 2:
        return True
    first = image.pixels[..., colour[0]]
    return all(np.array_equal(first, image.pixels[..., k]) for k in colour[1:])


def _colour_channels(image) -> list[int]:
    return [k for k, n in enumerate(image.channel_names)
            if k != image.alpha_channel and n != "A"] or [0]


def read_map(path: str, what: str):
    """The image of a per-pixel map (a field, a guide); OsmapError naming the file for
    NaN or infinite values."""
    from osmap_cli.imageio import read_image

    image = read_image(path)
    if not np.all(np.isfinite(image.pixels)):
        raise OsmapError(f"{path}: {what} has NaN or infinite values")
    return image


def orientation_from_image(path: str) -> tuple[np.ndarray, np.ndarray]:
    """(cos, sin) float32 (h, w) of the orientation field stored in `path`."""
    image = read_map(path, "orientation field")
    floating = image.bit_depth == 32
    px = image.pixels
    if _is_gray(image):
        value = px[..., _colour_channels(image)[0]].astype(np.float64)
        radians = np.radians(value) if floating else value * (2.0 * math.pi)
        return np.cos(radians).astype(np.float32), np.sin(radians).astype(np.float32)
    r, g = (px[..., k].astype(np.float64) for k in _colour_channels(image)[:2])
    if not floating:
        r, g = 2.0 * r - 1.0, 2.0 * g - 1.0
    length = np.hypot(r, g)
    zero = length < 1e-6
    c = np.where(zero, 1.0, r / np.where(zero, 1.0, length))
    s = np.where(zero, 0.0, g / np.where(zero, 1.0, length))
    return c.astype(np.float32), s.astype(np.float32)


def scale_from_image(path: str) -> np.ndarray:
    """log2 of the scale factor, float32 (h, w), of the scale field stored in `path`."""
    image = read_map(path, "scale field")
    value = image.pixels[..., _colour_channels(image)].astype(np.float64).mean(axis=2)
    if image.bit_depth == 32:
        if np.any(value <= 0):
            raise OsmapError(f"{path}: scale field has values <= 0 (a float field stores the "
                             "scale factor itself, e.g. 0.5 to 2)")
        return np.log2(value).astype(np.float32)
    return (2.0 * value - 1.0).astype(np.float32)


def load_fields(orientation_path: str | None, scale_path: str | None, out_shape,
                base_scale: float) -> ControlFields | None:
    """The control fields at the output resolution, or None when neither is given.

    Raises OsmapError for an unreadable field or one that pushes the scale out of range.
    """
    if orientation_path is None and scale_path is None:
        return None
    shape = tuple(int(v) for v in out_shape)
    if orientation_path is not None:
        cos, sin = orientation_from_image(orientation_path)
    else:
        cos, sin = np.ones(shape, np.float32), np.zeros(shape, np.float32)
    log2_scale = (scale_from_image(scale_path) if scale_path is not None
                  else np.zeros(cos.shape, np.float32))
    if scale_path is not None:
        lo = base_scale * float(np.exp2(log2_scale.min()))
        hi = base_scale * float(np.exp2(log2_scale.max()))
        if lo < 0.25 - 1e-6 or hi > 8.0 + 1e-6:
            raise OsmapError(f"{scale_path}: scale field times --scale gives {lo:.3g} to "
                             f"{hi:.3g}; allowed 0.25 to 8")
    fields = ControlFields(*_same_shape(cos, sin, log2_scale, shape))
    return fields.resized(shape)


def _same_shape(cos, sin, log2_scale, shape):
    """Bring the orientation and scale maps (which may differ in size) to one size."""
    if cos.shape == log2_scale.shape:
        return cos, sin, log2_scale
    from osmap_cli.texture.pyramid import resize

    cs = resize(np.stack([cos, sin], -1), *shape)
    ls = resize(log2_scale[..., None], *shape)
    return cs[..., 0].copy(), cs[..., 1].copy(), ls[..., 0].copy()

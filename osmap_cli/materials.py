"""Material sets: extra maps aligned with the exemplar, rendered with the same position map.

``--with [NAME=]MAP`` names a map (normal, roughness, height, ...) that is pixel-aligned with
the exemplar. It is rendered through the position map of the synthesized texture, so all
outputs stay aligned, and written next to the main output as ``<output stem>_<NAME><ext>``.
NAME defaults to the map's file stem.

Normal maps (NAME containing "normal", case-insensitive) stay valid: they are decoded (integer
files: n = 2 v - 1; float files: as stored when any value is negative, else 2 v - 1), rotated
with the texture (OpenGL convention: +x right, +y up, the rotation and stretch part of the
Jacobian; ``--scale`` does not flatten them: features keep their slopes), renormalised to unit
length after bilinear rendering, and encoded back the same way.

The rendering itself is the caller's (the command that drew the texture passes its renderer):
this module knows the maps, not how a command renders.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numpy as np

from osmap_cli.errors import OsmapError

__all__ = ["WithMap", "parse_with", "render_map", "with_output_path"]

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")


@dataclass(frozen=True)
class WithMap:
    """One --with map: output suffix, path (may hold {stem}/{dir} fields), normal-map flag."""

    name: str
    path: str

    @property
    def normal(self) -> bool:
        return "normal" in self.name.lower()


def parse_with(spec: str) -> WithMap:
    """``NAME=PATH`` or ``PATH``; raises ValueError with a message for a bad NAME."""
    name, sep, path = spec.partition("=")
    if not sep or os.sep in name or "/" in name:
        name, path = "", spec
    if not path:
        raise ValueError(f"{spec!r}: give a map path, NAME=PATH or PATH")
    if not name:
        if "{" in path:
            raise ValueError(f"{spec!r}: a map path with {{fields}} needs an explicit NAME= "
                             "(e.g. normal={stem}_normal.png)")
        name = os.path.splitext(os.path.basename(path))[0]
    if not _NAME.fullmatch(name):
        raise ValueError(f"{spec!r}: NAME must be letters, digits, '_', '-' or '.'")
    return WithMap(name, path)


def with_output_path(output: str, name: str) -> str:
    """Where the map NAME of `output` goes: same folder and extension, stem + "_" + NAME."""
    stem, ext = os.path.splitext(output)
    return f"{stem}_{name}{ext}"


def expand_path(template: str, exemplar: str) -> str:
    """A --with path with {stem} (exemplar name without extension), {name} (with extension)
    and {dir} (the exemplar's folder) filled in."""
    if "{" not in template:
        return template
    folder = os.path.dirname(exemplar) or "."
    base = os.path.basename(exemplar)
    try:
        return template.format(stem=os.path.splitext(base)[0], name=base, dir=folder)
    except (KeyError, IndexError, ValueError) as exc:
        raise OsmapError(f"{template}: bad --with path template ({exc}); fields: {{stem}}, "
                         "{name}, {dir}") from None


def load_aligned(path: str, exemplar_shape, exemplar_path: str):
    """Read a map that must have the exemplar's size; OsmapError otherwise."""
    from osmap_cli.imageio import read_image

    image = read_image(path)
    h, w = image.pixels.shape[:2]
    if (h, w) != tuple(exemplar_shape[:2]):
        raise OsmapError(f"{path}: map is {w}x{h} but the exemplar {exemplar_path} is "
                         f"{exemplar_shape[1]}x{exemplar_shape[0]}; --with maps must be "
                         "aligned with the exemplar (same size)")
    return image


def _colour(image) -> list[int]:
    return [k for k, n in enumerate(image.channel_names)
            if k != image.alpha_channel and n != "A"]


def render_map(image, draw, jacobian: np.ndarray, normal: bool, path: str = "") -> np.ndarray:
    """float32 (H, W, C): `image` rendered by draw(pixels) -> (H, W, C), the renderer the
    texture itself was drawn with (its positions and seam blending), so the map stays aligned
    with it; normal maps are decoded first and turned by `jacobian` ((2, 2) or (H, W, 2, 2),
    output-to-exemplar in row/col order) after.
    """
    if not normal:
        return draw(image.pixels)
    colour = _colour(image)
    if len(colour) < 3:
        raise OsmapError(f"{path or image.path}: a normal map needs 3 colour channels "
                         f"(x, y, z), got {len(colour)}")
    xyz = colour[:3]
    pixels = image.pixels.copy()
    encoded = image.bit_depth != 32 or float(pixels[..., xyz].min()) >= 0.0
    vectors = pixels[..., xyz].astype(np.float64)
    if encoded:
        vectors = 2.0 * vectors - 1.0
    pixels[..., xyz] = vectors.astype(np.float32)
    out = draw(pixels)
    n = out[..., xyz].astype(np.float64)
    n = rotate_normals(n, jacobian)
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    flat = np.zeros_like(n)
    flat[..., 2] = 1.0
    n = np.where(length > 1e-8, n / np.where(length > 1e-8, length, 1.0), flat)
    if encoded:
        n = (n + 1.0) * 0.5
    out[..., xyz] = n.astype(np.float32)
    return out


def rotate_normals(n: np.ndarray, jacobian: np.ndarray) -> np.ndarray:
    """Tangent-space normals (..., 3), x right / y up, turned with the texture.

    The slope (nx, ny) / nz is a gradient, which maps by J^T (J in x / y-up coordinates); the
    uniform scale of J is divided out, so magnified features keep their slopes.
    """
    jac = np.asarray(jacobian, np.float64)
    det = np.abs(jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0])
    unit = 1.0 / np.sqrt(np.maximum(det, 1e-12))
    j00, j01 = jac[..., 0, 0] * unit, jac[..., 0, 1] * unit
    j10, j11 = jac[..., 1, 0] * unit, jac[..., 1, 1] * unit
    nx, ny = n[..., 0], n[..., 1]
    out = n.copy()
    # J in (x, y-up) coordinates, transposed: [[J11, -J01], [-J10, J00]] (J is row/col, y down)
    out[..., 0] = j11 * nx - j01 * ny
    out[..., 1] = -j10 * nx + j00 * ny
    return out

"""A picture of the carved object: three orthographic views side by side (front left, back right,
from above; y is up, as in glTF), two-sided Lambert shading under a light from the upper left of
each view, the colour read from the baked texture (bilinear, so a seam in the map would show)
or the vertex colours. Deterministic: a software z-buffer (osmap_kernels.carve), rendered at
twice the size and averaged down."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["VIEWS", "render_preview"]

# (azimuth about y, elevation) in degrees of each view's camera
VIEWS = ((-35.0, 20.0), (145.0, 20.0), (55.0, 65.0))
BACKGROUND = 0.16
AMBIENT = 0.3
GAP = 8
SUPERSAMPLE = 2


def _camera(azimuth: float, elevation: float) -> np.ndarray:
    """(3, 3) rows: screen right, screen up, towards the camera (world coordinates, y up)."""
    a, e = math.radians(azimuth), math.radians(elevation)
    back = np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])
    right = np.cross([0.0, 1.0, 0.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    return np.stack([right, up, back])


def render_preview(result, size: int = 384) -> np.ndarray:
    """float32 (size, 3 size + 2 GAP, 3) RGB in [0, 1]: RESULT (a CarveResult) in VIEWS."""
    from osmap_kernels import carve as kernels

    mesh = result.mesh
    faces = mesh.faces
    normals = result.normals[faces]
    if result.texture is not None:
        from osmap_cli.carving.bake import texel_corners

        texture = result.texture
        uv = texel_corners(mesh, texture.shape[1], texture.shape[0])
        colours = np.zeros((0, 3, 1), np.float32)
    else:
        texture = np.zeros((1, 1, 1), np.float32)
        uv = np.zeros((len(faces), 3, 2))
        colours = result.vertex_colors[faces]
    centre = (mesh.vertices.min(axis=0) + mesh.vertices.max(axis=0)) / 2.0
    cameras = [_camera(*view) for view in VIEWS]
    projected = [(mesh.vertices - centre) @ cam.T for cam in cameras]
    reach = max(float(np.abs(p[:, :2]).max()) for p in projected) or 1.0
    side = size * SUPERSAMPLE
    scale = 0.46 * side / reach
    panels = []
    for cam, p in zip(cameras, projected):
        corners = np.stack([side / 2 + scale * p[:, 0], side / 2 - scale * p[:, 1]], axis=-1)
        tri, _ = kernels.rasterise(corners[faces], side, side, depth=-p[faces][..., 2])
        light = 0.45 * cam[0] + 0.6 * cam[1] + 0.66 * cam[2]
        light /= np.linalg.norm(light)
        image = kernels.shade(tri, corners[faces], normals, uv, texture, colours, light,
                              AMBIENT, BACKGROUND)
        panels.append(image.reshape(size, SUPERSAMPLE, size, SUPERSAMPLE, 3).mean(axis=(1, 3)))
    canvas = np.full((size, 3 * size + 2 * GAP, 3), BACKGROUND, np.float32)
    for k, panel in enumerate(panels):
        left = k * (size + GAP)
        canvas[:, left:left + size] = panel
    return canvas

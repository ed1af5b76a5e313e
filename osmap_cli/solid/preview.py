"""Preview of a volume: the cube's three visible faces in isometric view (top: z = 0, left:
y = Y-1, right: x = X-1) next to the three orthogonal centre slices, each labelled. Labels are
drawn with OpenImageIO's render_text (its bundled font)."""

from __future__ import annotations

import math

import numpy as np

BACKGROUND = 0.16
LABEL_HEIGHT = 22
SHADE = (1.0, 0.86, 0.72)  # top, left, right face brightness


def display_rgb(volume: np.ndarray) -> np.ndarray:
    """(Z, Y, X, 3) in [0, 1]: grey channels repeated, alpha and extra channels dropped."""
    rgb = volume[..., :3] if volume.shape[3] >= 3 else np.repeat(volume[..., :1], 3, axis=3)
    return np.clip(np.nan_to_num(rgb), 0.0, 1.0).astype(np.float32)


def isometric_cube(rgb: np.ndarray, side: int) -> np.ndarray:
    """(side, side, 3) image of the cube seen from above the (+x, +y) corner."""
    Z, Y, X, _ = rgb.shape
    c = math.cos(math.radians(30))
    width = (X + Y) * c
    height = (X + Y) * 0.5 + Z
    s = 0.94 * side / max(width, height)
    sy, sx = np.mgrid[0:side, 0:side].astype(np.float64)
    # screen -> world: sx = (x - y) c s + ox, sy = ((x + y) / 2 + z) s + oy
    ox = side / 2 - (X - Y) * c * s / 2
    oy = (side - height * s) / 2
    u = (sx - ox) / (s * c)
    v = (sy - oy) / s
    out = np.full((side, side, 3), BACKGROUND, np.float32)
    # top face (z = 0): x - y = u, (x + y) / 2 = v
    x, y = v + u / 2, v - u / 2
    hit = (x >= 0) & (x < X) & (y >= 0) & (y < Y)
    out[hit] = SHADE[0] * rgb[0, y[hit].astype(int), x[hit].astype(int)]
    # left face (y = Y): x = u + Y, z = v - (x + Y) / 2
    x = u + Y
    z = v - (x + Y) / 2
    hit = (x >= 0) & (x < X) & (z >= 0) & (z < Z)
    out[hit] = SHADE[1] * rgb[z[hit].astype(int), Y - 1, x[hit].astype(int)]
    # right face (x = X): y = X - u, z = v - (X + y) / 2
    y = X - u
    z = v - (X + y) / 2
    hit = (y >= 0) & (y < Y) & (z >= 0) & (z < Z)
    out[hit] = SHADE[2] * rgb[z[hit].astype(int), y[hit].astype(int), X - 1]
    return out


def _fit(image: np.ndarray, side: int) -> np.ndarray:
    """Nearest-neighbour scale of a slice into a side x side panel (aspect kept)."""
    h, w = image.shape[:2]
    s = side / max(h, w)
    H, W = max(1, int(h * s)), max(1, int(w * s))
    ys = np.minimum((np.arange(H) / s).astype(int), h - 1)
    xs = np.minimum((np.arange(W) / s).astype(int), w - 1)
    panel = np.full((side, side, 3), BACKGROUND, np.float32)
    oy, ox = (side - H) // 2, (side - W) // 2
    panel[oy:oy + H, ox:ox + W] = image[ys][:, xs]
    return panel


def _label(canvas: np.ndarray, text: str, x: int, y: int) -> None:
    """Draw text with its baseline at (x, y); skipped if OpenImageIO has no font."""
    import OpenImageIO as oiio

    h, w, c = canvas.shape
    buf = oiio.ImageBuf(oiio.ImageSpec(w, h, c, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(), canvas)
    if oiio.ImageBufAlgo.render_text(buf, x, y, text, 15, "DroidSans", (0.92, 0.92, 0.92)):
        canvas[:] = np.asarray(buf.get_pixels(oiio.FLOAT)).reshape(h, w, c)


def render_preview(volume: np.ndarray, panel: int = 256) -> np.ndarray:
    """(panel + label, 4 * panel, 3) float32 RGB: cube, then centre slices z, y, x."""
    rgb = display_rgb(np.asarray(volume, np.float32))
    Z, Y, X, _ = rgb.shape
    gap = 8
    canvas = np.full((panel + LABEL_HEIGHT + gap, 4 * panel + 5 * gap, 3), BACKGROUND,
                     np.float32)
    panels = [
        (isometric_cube(rgb, panel), f"volume {X}x{Y}x{Z} (x, y, z)"),
        (_fit(rgb[Z // 2], panel), f"z = {Z // 2}: rows y, cols x"),
        (_fit(rgb[:, Y // 2], panel), f"y = {Y // 2}: rows z, cols x"),
        (_fit(rgb[:, :, X // 2], panel), f"x = {X // 2}: rows z, cols y"),
    ]
    for i, (image, _) in enumerate(panels):
        left = gap + i * (panel + gap)
        canvas[LABEL_HEIGHT:LABEL_HEIGHT + panel, left:left + panel] = image
    for i, (_, text) in enumerate(panels):
        _label(canvas, text, gap + i * (panel + gap) + 4, LABEL_HEIGHT - 6)
    return canvas

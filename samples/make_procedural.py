"""Make the procedural colour sample exemplars: cells.png, cells_rgba.png, weave.png and the
wood pair wood_side.png / wood_end.png.

Needs only numpy and OpenImageIO; deterministic (fixed seeds, numpy's PCG64 generator). Run it
from the repository root:

    python samples/make_procedural.py

* ``cells.png``      128x128 RGB  -- pebble-like Voronoi cells with dark borders, a random colour
                                     per cell, soft shading and per-pixel noise.
* ``cells_rgba.png`` 64x64 RGBA   -- the same kind of cells; alpha is 0 on the borders and 1
                                     inside the cells (for testing RGBA handling).
* ``weave.png``      128x128 RGB  -- a 2/2 twill weave of blue and tan threads: a regular pattern
                                     with a clear diagonal orientation, shaded threads, fibre
                                     streaks and slight noise.

* ``wood_side.png`` 128x128 RGB -- side grain: a slice along a log (growth rings cut lengthwise:
                                     wavy light/dark grain lines along x, fine fibre streaks).
* ``wood_end.png``  128x128 RGB  -- end grain of the same log: concentric rings (the log's axis
                                     off the image, so arcs), same colours.
* ``wood_top.png``  128x128 RGB  -- flat-sawn face of the same log (rings cut tangentially).
  All three are slices of one procedural 3D wood function, so they are consistent: a block
  with its grain along x is `osmap solid --x wood_end.png --y wood_side.png --z wood_top.png`.

Cells and weave tile seamlessly (distances are measured on a torus and the weave repeat divides
128); the wood pair does not tile.
The images are made by the osmap project and released under CC0.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import OpenImageIO as oiio

HERE = os.path.dirname(os.path.abspath(__file__))


def smoothstep(edge0: float, edge1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def hsv_to_rgb(h: np.ndarray, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectorised HSV -> RGB, all inputs in [0, 1]; returns (..., 3)."""
    i = np.floor(h * 6.0).astype(int) % 6
    f = h * 6.0 - np.floor(h * 6.0)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    table = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)]
    rgb = np.zeros(h.shape + (3,))
    for k, (r, g, b) in enumerate(table):
        rgb[i == k] = np.stack([r, g, b], axis=-1)[i == k]
    return rgb


def voronoi_cells(size: int, grid: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Tileable pebble cells: returns (rgb (size, size, 3), inside-mask (size, size)) in [0, 1]."""
    rng = np.random.default_rng(seed)
    step = size / grid
    gy, gx = np.mgrid[0:grid, 0:grid]
    points = np.stack(
        [
            (gx.ravel() + 0.1 + 0.8 * rng.random(grid * grid)) * step,
            (gy.ravel() + 0.1 + 0.8 * rng.random(grid * grid)) * step,
        ],
        axis=-1,
    )  # (N, 2) as (x, y), jittered grid -> evenly sized cells
    n = len(points)
    colours = hsv_to_rgb(rng.random(n), 0.35 + 0.35 * rng.random(n), 0.6 + 0.3 * rng.random(n))

    y, x = np.mgrid[0:size, 0:size].astype(np.float64) + 0.5
    dx = x[..., None] - points[:, 0]
    dy = y[..., None] - points[:, 1]
    dx = (dx + size / 2) % size - size / 2  # torus: nearest periodic copy
    dy = (dy + size / 2) % size - size / 2
    dist = np.hypot(dx, dy)  # (size, size, N)
    order = np.argsort(dist, axis=-1)
    nearest, second = order[..., 0], order[..., 1]
    d1 = np.take_along_axis(dist, nearest[..., None], -1)[..., 0]
    d2 = np.take_along_axis(dist, second[..., None], -1)[..., 0]

    inside = smoothstep(0.8, 2.6, d2 - d1)  # 0 on the borders, 1 inside
    radius = 0.6 * step
    sx = np.take_along_axis(dx, nearest[..., None], -1)[..., 0] / radius
    sy = np.take_along_axis(dy, nearest[..., None], -1)[..., 0] / radius
    dome = np.clip(1.0 - (d1 / radius) ** 2, 0.0, 1.0)
    shade = 0.7 + 0.25 * dome - 0.12 * (sx + sy)  # rounded, lit from the top left
    body = colours[nearest] * shade[..., None]
    border = np.array([0.09, 0.075, 0.06])
    rgb = border + (body - border) * inside[..., None]
    rgb += rng.normal(0.0, 0.025, rgb.shape)  # per-pixel colour noise
    rgb += rng.normal(0.0, 0.02, rgb.shape[:2])[..., None]  # per-pixel luminance grain
    return np.clip(rgb, 0.0, 1.0), inside


def weave(size: int = 128, pitch: int = 8, seed: int = 3) -> np.ndarray:
    """A 2/2 twill of horizontal blue threads over/under vertical tan threads, (size, size, 3)."""
    rng = np.random.default_rng(seed)
    assert size % (4 * pitch) == 0, "the twill repeats every 4 threads"
    blue = np.array([0.18, 0.32, 0.62])
    tan = np.array([0.86, 0.72, 0.46])
    gap = np.array([0.07, 0.06, 0.05])
    half = 0.40  # thread half-width, as a fraction of the pitch

    y, x = np.mgrid[0:size, 0:size]
    ix, iy = x // pitch, y // pitch
    fx = (x % pitch + 0.5) / pitch - 0.5  # across a vertical thread, in [-0.5, 0.5]
    fy = (y % pitch + 0.5) / pitch - 0.5  # across a horizontal thread
    phase = (ix + iy) % 4
    horizontal_on_top = phase < 2
    # position along the two-cell float of the thread on top, in [0, 1]
    t_h = ((phase % 2) * pitch + x % pitch + 0.5) / (2 * pitch)
    t_v = ((phase % 2) * pitch + y % pitch + 0.5) / (2 * pitch)

    def thread(colour, across, along, streaks):
        profile = np.cos(np.pi * np.clip(across / (2 * half), -0.5, 0.5))  # round thread
        lift = 0.7 + 0.3 * np.sin(np.pi * along)  # darker where it dives under
        light = (0.5 + 0.5 * profile) * lift * (1.0 + streaks)
        return colour * light[..., None]

    # per-thread colour jitter and fibre streaks running along each thread
    row_tint = 1.0 + 0.06 * rng.standard_normal((size // pitch, 1, 1))
    col_tint = 1.0 + 0.06 * rng.standard_normal((1, size // pitch, 1))
    h_streaks = 0.10 * rng.standard_normal((size, 1)) + 0.03 * rng.standard_normal((size, size))
    v_streaks = 0.10 * rng.standard_normal((1, size)) + 0.03 * rng.standard_normal((size, size))
    h_col = blue * row_tint[iy, 0]
    v_col = tan * col_tint[0, ix]

    top_h = thread(h_col, fy, t_h, h_streaks)
    top_v = thread(v_col, fx, t_v, v_streaks)
    in_h = np.abs(fy) < half
    in_v = np.abs(fx) < half
    shadow = 0.45  # a thread seen beside the one on top is in its shadow
    rgb = np.broadcast_to(gap, (size, size, 3)).copy()
    rgb = np.where((in_v & horizontal_on_top)[..., None], shadow * v_col, rgb)
    rgb = np.where((in_h & ~horizontal_on_top)[..., None], shadow * h_col, rgb)
    rgb = np.where((in_h & horizontal_on_top)[..., None], top_h, rgb)
    rgb = np.where((in_v & ~horizontal_on_top)[..., None], top_v, rgb)
    rgb += rng.normal(0.0, 0.015, rgb.shape)
    return np.clip(rgb, 0.0, 1.0)


def _wood(x: np.ndarray, y: np.ndarray, z: np.ndarray, seed: int = 5) -> np.ndarray:
    """RGB of a log whose axis runs along x through (y, z) = (64, -40), at the given points
    (pixels): growth rings 7 px apart, wobbling slowly along the log and around it, darker
    latewood at the end of each ring, fibre streaks along x."""
    rng = np.random.default_rng(seed)
    dy, dz = y - 64.0, z + 40.0
    radius = np.hypot(dy, dz)
    angle = np.arctan2(dz, dy)
    wobble = np.zeros_like(radius)
    for _ in range(6):  # slow, smooth perturbation of the ring radius
        fx, fa = rng.uniform(0.005, 0.03), rng.integers(1, 5)
        wobble += rng.uniform(0.6, 1.4) * np.sin(fx * 2 * np.pi * x + fa * angle
                                                 + rng.uniform(0, 2 * np.pi))
    phase = (radius + 0.7 * wobble) / 7.0
    t = phase - np.floor(phase)
    late = smoothstep(0.55, 0.8, t) * (1.0 - smoothstep(0.92, 1.0, t))
    fibre = np.zeros_like(radius)
    for _ in range(8):  # streaks: fast across the grain, slow along it
        fr, fl = rng.uniform(0.15, 0.5), rng.uniform(0.002, 0.02)
        fibre += np.sin(fr * 2 * np.pi * radius + fl * 2 * np.pi * x + rng.uniform(0, 6.3))
    fibre /= 8.0
    early = np.array([0.80, 0.62, 0.40])
    dark = np.array([0.47, 0.29, 0.15])
    rgb = early + late[..., None] * (dark - early)
    rgb = rgb * (1.0 + 0.06 * fibre[..., None]) + rng.normal(0.0, 0.012, rgb.shape)
    return np.clip(rgb, 0.0, 1.0)


def wood_set(size: int = 128) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(side, end, top): three cuts of one block of the log, consistent with each other.
    side: quarter-sawn, rows z, cols x in the plane y = 64 through the axis (grain lines along
    the columns); end: rows z, cols y at x = 64 (arcs of the rings around the axis above the
    image); top: flat-sawn, rows y, cols x at z = 64 (the rings cut tangentially: lines along x
    whose spacing widens towards the middle)."""
    rows, cols = np.mgrid[0:size, 0:size].astype(np.float64)
    side = _wood(x=cols, y=np.full_like(rows, 64.0), z=rows)
    end = _wood(x=np.full_like(rows, 64.0), y=cols, z=rows)
    top = _wood(x=cols, y=rows, z=np.full_like(rows, 64.0))
    return side, end, top


def write_png(path: str, pixels: np.ndarray) -> None:
    """Write float pixels in [0, 1] as an 8-bit PNG (rounded), checking every OIIO call."""
    quantised = np.rint(np.clip(pixels, 0.0, 1.0) * 255.0).astype(np.uint8)
    height, width, channels = quantised.shape
    spec = oiio.ImageSpec(width, height, channels, "uint8")
    spec.attribute("oiio:UnassociatedAlpha", 1)  # straight alpha: store the values as given
    out = oiio.ImageOutput.create(path)
    if out is None:
        raise RuntimeError(f"{path}: {oiio.geterror()}")
    if not out.open(path, spec):
        raise RuntimeError(f"{path}: {out.geterror()}")
    ok = out.write_image(quantised)
    out.close()
    error = out.geterror()
    if not ok or error:
        raise RuntimeError(f"{path}: {error}")
    print(f"wrote {os.path.relpath(path)} ({width}x{height}, {channels} channels)")


def main() -> int:
    cells, _ = voronoi_cells(128, grid=6, seed=1)
    write_png(os.path.join(HERE, "cells.png"), cells)

    small, inside = voronoi_cells(64, grid=4, seed=2)
    alpha = np.where(inside < 0.5, 0.0, inside)  # fully transparent borders
    write_png(os.path.join(HERE, "cells_rgba.png"), np.dstack([small, alpha]))

    write_png(os.path.join(HERE, "weave.png"), weave())

    side, end, top = wood_set()
    write_png(os.path.join(HERE, "wood_side.png"), side)
    write_png(os.path.join(HERE, "wood_end.png"), end)
    write_png(os.path.join(HERE, "wood_top.png"), top)
    return 0


if __name__ == "__main__":
    sys.exit(main())

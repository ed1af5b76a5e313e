"""Carve kernels: triangles rasterised into a 2D raster (a UV layout, or a view of the object),
and a volume sampled at 3D points.

Conventions. A raster is H x W pixels (texels); pixel (r, c) has its centre at (x, y) =
(c + 0.5, r + 0.5). Triangle corners are given in these pixel units as float64 (T, 3, 2) =
(x, y). A pixel is covered by a triangle when its centre lies inside it or on its edge
(barycentrics >= -EDGE). Triangles whose raster area is below AREA_MIN cover nothing.

A volume is float32 (Z, Y, X, C); a 3D point q = (x, y, z) in voxel units has voxel (k, j, i)'s
centre at (i + 0.5, j + 0.5, k + 0.5). Sampling is trilinear, or tricubic (Catmull-Rom, which
interpolates: at voxel centres both return the voxel exactly). Outside the volume the index is
clamped to the border voxel, or wraps around when the volume tiles.

Determinism: every kernel here writes only its own rows (osmap_kernels.bands) from inputs it
does not write, and visits triangles in index order, so the output is the same bytes whatever
the thread count. Ties go to the lower triangle index: in a UV layout the first triangle that
covers a texel keeps it; in a view the nearest triangle wins, and of two at the same depth the
lower index.
"""

import numpy as np
from numba import njit

from osmap_kernels.bands import run_bands
from osmap_kernels.common import sample

EDGE = 1e-9  # barycentric tolerance: a centre on a shared edge belongs to both triangles
AREA_MIN = 1e-12  # twice the raster area below which a triangle covers nothing
# the order a padding texel looks at its neighbours: the four sides first, then the corners
NEIGHBOURS = np.array([(0, -1), (0, 1), (-1, 0), (1, 0), (-1, -1), (-1, 1), (1, -1), (1, 1)],
                      np.int64)


# ---------------------------------------------------------------------------------------------
# rasterisation


@njit(cache=True, inline="always")
def _barycentric(corners, t, px, py):
    """(b0, b1, b2, twice the signed area) of point (px, py) in triangle t."""
    x0, y0 = corners[t, 0, 0], corners[t, 0, 1]
    x1, y1 = corners[t, 1, 0], corners[t, 1, 1]
    x2, y2 = corners[t, 2, 0], corners[t, 2, 1]
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if abs(area) < AREA_MIN:
        return -1.0, -1.0, -1.0, area
    b1 = ((px - x0) * (y2 - y0) - (x2 - x0) * (py - y0)) / area
    b2 = ((x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)) / area
    return 1.0 - b1 - b2, b1, b2, area


@njit(cache=True, nogil=True)
def _raster_rows(corners, depth, use_depth, tri, zbuf, overlaps, y0, y1):
    """Rows y0 <= r < y1 of rasterise (see there)."""
    W = tri.shape[1]
    for r in range(y0, y1):
        for c in range(W):
            tri[r, c] = -1
    for t in range(corners.shape[0]):
        ymin = min(corners[t, 0, 1], corners[t, 1, 1], corners[t, 2, 1])
        ymax = max(corners[t, 0, 1], corners[t, 1, 1], corners[t, 2, 1])
        r0 = max(int(np.ceil(ymin - 0.5)), y0)
        r1 = min(int(np.floor(ymax - 0.5)), y1 - 1)
        if r0 > r1:
            continue
        xmin = min(corners[t, 0, 0], corners[t, 1, 0], corners[t, 2, 0])
        xmax = max(corners[t, 0, 0], corners[t, 1, 0], corners[t, 2, 0])
        c0 = max(int(np.ceil(xmin - 0.5)), 0)
        c1 = min(int(np.floor(xmax - 0.5)), W - 1)
        for r in range(r0, r1 + 1):
            py = r + 0.5
            for c in range(c0, c1 + 1):
                px = c + 0.5
                b0, b1, b2, area = _barycentric(corners, t, px, py)
                if b0 < -EDGE or b1 < -EDGE or b2 < -EDGE:
                    continue
                old = tri[r, c]
                if use_depth:
                    z = b0 * depth[t, 0] + b1 * depth[t, 1] + b2 * depth[t, 2]
                    if old < 0 or z < zbuf[r, c]:
                        tri[r, c] = t
                        zbuf[r, c] = z
                elif old < 0:
                    tri[r, c] = t
                elif b0 > EDGE and b1 > EDGE and b2 > EDGE:
                    a0, a1, a2, _ = _barycentric(corners, old, px, py)
                    if a0 > EDGE and a1 > EDGE and a2 > EDGE:
                        overlaps[r] += 1


def rasterise(corners, height, width, depth=None):
    """(tri int32 (H, W), overlaps int64): the triangle covering each pixel (-1: none) and how
    many pixels lie strictly inside two or more triangles.

    corners: float64 (T, 3, 2) in pixel units. Without DEPTH the first triangle (lowest index)
    that covers a pixel keeps it (a UV layout). With DEPTH, float64 (T, 3) per corner, the pixel
    takes the triangle of least interpolated depth (a view; overlaps are then not counted)."""
    corners = np.ascontiguousarray(corners, np.float64)
    tri = np.empty((height, width), np.int32)
    overlaps = np.zeros(height, np.int64)
    use_depth = depth is not None
    if use_depth:
        zbuf = np.empty((height, width), np.float64)
        depth = np.ascontiguousarray(depth, np.float64)
    else:
        zbuf = np.empty((1, 1), np.float64)
        depth = np.zeros((1, 3), np.float64)
    run_bands(_raster_rows, height, corners, depth, use_depth, tri, zbuf, overlaps)
    return tri, int(overlaps.sum())


@njit(cache=True, nogil=True)
def _dilate_rows(src, dst, y0, y1):
    H, W = src.shape
    for r in range(y0, y1):
        for c in range(W):
            value = src[r, c]
            if value < 0:
                for k in range(NEIGHBOURS.shape[0]):
                    rr = r + NEIGHBOURS[k, 0]
                    cc = c + NEIGHBOURS[k, 1]
                    if 0 <= rr < H and 0 <= cc < W and src[rr, cc] >= 0:
                        value = src[rr, cc]
                        break
            dst[r, c] = value


def dilate(tri, steps):
    """tri grown by STEPS pixels: an empty pixel next to a filled one (sides first, then
    corners, in NEIGHBOURS order) takes that neighbour's triangle, one ring per step."""
    current = np.ascontiguousarray(tri, np.int32)
    spare = np.empty_like(current)
    for _ in range(steps):
        run_bands(_dilate_rows, current.shape[0], current, spare)
        current, spare = spare, current
    return current


# ---------------------------------------------------------------------------------------------
# volume sampling


@njit(cache=True, inline="always")
def _clamp_index(i, n, wrap):
    if wrap:
        return i % n
    return min(max(i, 0), n - 1)


@njit(cache=True, inline="always")
def _cubic_weights(t, w):
    """Catmull-Rom weights of the four taps at -1, 0, 1, 2 for fraction t."""
    t2 = t * t
    t3 = t2 * t
    w[0] = 0.5 * (-t3 + 2.0 * t2 - t)
    w[1] = 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0)
    w[2] = 0.5 * (-3.0 * t3 + 4.0 * t2 + t)
    w[3] = 0.5 * (t3 - t2)


@njit(cache=True, inline="always")
def _sample_volume(volume, qx, qy, qz, wrap, cubic, acc, wx, wy, wz, out):
    """volume at (qx, qy, qz) (voxel units, centres at +0.5) into out (C,)."""
    Z, Y, X, C = volume.shape
    gx, gy, gz = qx - 0.5, qy - 0.5, qz - 0.5
    ix, iy, iz = int(np.floor(gx)), int(np.floor(gy)), int(np.floor(gz))
    fx, fy, fz = gx - ix, gy - iy, gz - iz
    for ch in range(C):
        acc[ch] = 0.0
    if cubic:
        _cubic_weights(fx, wx)
        _cubic_weights(fy, wy)
        _cubic_weights(fz, wz)
        for a in range(4):
            k = _clamp_index(iz - 1 + a, Z, wrap)
            for b in range(4):
                j = _clamp_index(iy - 1 + b, Y, wrap)
                wzy = wz[a] * wy[b]
                for d in range(4):
                    i = _clamp_index(ix - 1 + d, X, wrap)
                    weight = wzy * wx[d]
                    for ch in range(C):
                        acc[ch] += weight * volume[k, j, i, ch]
    else:
        for a in range(2):
            k = _clamp_index(iz + a, Z, wrap)
            waz = fz if a else 1.0 - fz
            for b in range(2):
                j = _clamp_index(iy + b, Y, wrap)
                wzy = waz * (fy if b else 1.0 - fy)
                for d in range(2):
                    i = _clamp_index(ix + d, X, wrap)
                    weight = wzy * (fx if d else 1.0 - fx)
                    if weight == 0.0:
                        continue
                    for ch in range(C):
                        acc[ch] += weight * volume[k, j, i, ch]
    for ch in range(C):
        out[ch] = acc[ch]


@njit(cache=True, inline="always")
def _closest_on_segment(px, py, ax, ay, bx, by):
    """(s, squared distance): the point a + s (b - a), 0 <= s <= 1, nearest to p."""
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy
    s = 0.0
    if length2 > 0.0:
        s = min(max(((px - ax) * dx + (py - ay) * dy) / length2, 0.0), 1.0)
    ex, ey = ax + s * dx - px, ay + s * dy - py
    return s, ex * ex + ey * ey


@njit(cache=True, inline="always")
def _clamped_barycentric(corners, t, px, py):
    """Barycentrics of the point of triangle t nearest to (px, py) (itself when inside)."""
    b0, b1, b2, area = _barycentric(corners, t, px, py)
    if abs(area) >= AREA_MIN and b0 >= 0.0 and b1 >= 0.0 and b2 >= 0.0:
        return b0, b1, b2
    s01, d01 = _closest_on_segment(px, py, corners[t, 0, 0], corners[t, 0, 1],
                                   corners[t, 1, 0], corners[t, 1, 1])
    s12, d12 = _closest_on_segment(px, py, corners[t, 1, 0], corners[t, 1, 1],
                                   corners[t, 2, 0], corners[t, 2, 1])
    s20, d20 = _closest_on_segment(px, py, corners[t, 2, 0], corners[t, 2, 1],
                                   corners[t, 0, 0], corners[t, 0, 1])
    if d01 <= d12 and d01 <= d20:
        return 1.0 - s01, s01, 0.0
    if d12 <= d20:
        return 0.0, 1.0 - s12, s12
    return s20, 0.0, 1.0 - s20


@njit(cache=True, nogil=True)
def _bake_rows(tri, corners, points, transform, volume, wrap, cubic, out, y0, y1):
    W = tri.shape[1]
    C = volume.shape[3]
    acc = np.empty(C)
    wx, wy, wz = np.empty(4), np.empty(4), np.empty(4)
    value = np.empty(C)
    for r in range(y0, y1):
        for c in range(W):
            t = tri[r, c]
            if t < 0:
                continue
            b0, b1, b2 = _clamped_barycentric(corners, t, c + 0.5, r + 0.5)
            px = b0 * points[t, 0, 0] + b1 * points[t, 1, 0] + b2 * points[t, 2, 0]
            py = b0 * points[t, 0, 1] + b1 * points[t, 1, 1] + b2 * points[t, 2, 1]
            pz = b0 * points[t, 0, 2] + b1 * points[t, 1, 2] + b2 * points[t, 2, 2]
            mx = transform[0, 0] * px + transform[0, 1] * py + transform[0, 2] * pz \
                + transform[0, 3]
            my = transform[1, 0] * px + transform[1, 1] * py + transform[1, 2] * pz \
                + transform[1, 3]
            mz = transform[2, 0] * px + transform[2, 1] * py + transform[2, 2] * pz \
                + transform[2, 3]
            _sample_volume(volume, mx, my, mz, wrap, cubic, acc, wx, wy, wz, value)
            for ch in range(C):
                out[r, c, ch] = value[ch]


def bake(tri, corners, points, transform, volume, wrap, cubic):
    """float32 (H, W, C): every pixel with a triangle (tri >= 0) takes the volume at the 3D
    point it maps to: the barycentrics of its centre in that triangle's CORNERS (clamped to the
    triangle for a pixel outside it, i.e. a padding pixel), applied to the triangle's POINTS
    (float64 (T, 3, 3), object units), carried into the volume by TRANSFORM (float64 (3, 4):
    q = A p + b, voxel units). Pixels without a triangle are left zero."""
    height, width = tri.shape
    out = np.zeros((height, width, volume.shape[3]), np.float32)
    run_bands(_bake_rows, height, tri, np.ascontiguousarray(corners, np.float64),
              np.ascontiguousarray(points, np.float64), np.ascontiguousarray(transform,
                                                                             np.float64),
              volume, bool(wrap), bool(cubic), out)
    return out


@njit(cache=True, nogil=True)
def _sample_rows(q, volume, wrap, cubic, out, y0, y1):
    C = volume.shape[3]
    acc = np.empty(C)
    wx, wy, wz = np.empty(4), np.empty(4), np.empty(4)
    value = np.empty(C)
    for n in range(y0, y1):
        _sample_volume(volume, q[n, 0], q[n, 1], q[n, 2], wrap, cubic, acc, wx, wy, wz, value)
        for ch in range(C):
            out[n, ch] = value[ch]


def sample_points(q, volume, wrap, cubic):
    """float32 (N, C): the volume at the points q (float64 (N, 3), voxel units)."""
    q = np.ascontiguousarray(q, np.float64)
    out = np.zeros((q.shape[0], volume.shape[3]), np.float32)
    run_bands(_sample_rows, q.shape[0], q, volume, bool(wrap), bool(cubic), out)
    return out


# ---------------------------------------------------------------------------------------------
# preview shading


@njit(cache=True, nogil=True)
def _shade_rows(tri, corners, normals, uv, texture, colours, light, ambient, background, out,
                y0, y1):
    W = tri.shape[1]
    C = texture.shape[2] if colours.shape[0] == 0 else colours.shape[2]
    texel = np.empty(texture.shape[2])
    albedo = np.empty(3)
    for r in range(y0, y1):
        for c in range(W):
            t = tri[r, c]
            if t < 0:
                for ch in range(3):
                    out[r, c, ch] = background
                continue
            b0, b1, b2 = _clamped_barycentric(corners, t, c + 0.5, r + 0.5)
            nx = b0 * normals[t, 0, 0] + b1 * normals[t, 1, 0] + b2 * normals[t, 2, 0]
            ny = b0 * normals[t, 0, 1] + b1 * normals[t, 1, 1] + b2 * normals[t, 2, 1]
            nz = b0 * normals[t, 0, 2] + b1 * normals[t, 1, 2] + b2 * normals[t, 2, 2]
            length = np.sqrt(nx * nx + ny * ny + nz * nz)
            lambert = 0.0
            if length > 0.0:
                lambert = abs(nx * light[0] + ny * light[1] + nz * light[2]) / length
            if colours.shape[0] == 0:
                u = b0 * uv[t, 0, 0] + b1 * uv[t, 1, 0] + b2 * uv[t, 2, 0]
                v = b0 * uv[t, 0, 1] + b1 * uv[t, 1, 1] + b2 * uv[t, 2, 1]
                sample(texture, v - 0.5, u - 0.5, texel)
                for ch in range(3):
                    albedo[ch] = texel[min(ch, C - 1)]
            else:
                for ch in range(3):
                    k = min(ch, C - 1)
                    albedo[ch] = (b0 * colours[t, 0, k] + b1 * colours[t, 1, k]
                                  + b2 * colours[t, 2, k])
            shade = ambient + (1.0 - ambient) * lambert
            for ch in range(3):
                out[r, c, ch] = min(max(albedo[ch], 0.0), 1.0) * shade


def shade(tri, corners, normals, uv, texture, colours, light, ambient, background):
    """float32 (H, W, 3): each pixel of a view (tri from rasterise with depth) lit by a
    directional LIGHT (unit (3,)), two-sided Lambert over AMBIENT, its colour the TEXTURE
    (float32 (h, w, C), sampled bilinearly at the interpolated UV in texel units, float64
    (T, 3, 2)) or, when COLOURS (float32 (T, 3, C)) is not empty, the interpolated vertex
    colours. One or two channels are shown grey."""
    height, width = tri.shape
    out = np.empty((height, width, 3), np.float32)
    run_bands(_shade_rows, height, tri, np.ascontiguousarray(corners, np.float64),
              np.ascontiguousarray(normals, np.float64), np.ascontiguousarray(uv, np.float64),
              np.ascontiguousarray(texture, np.float32), np.ascontiguousarray(colours,
                                                                              np.float32),
              np.ascontiguousarray(light, np.float64), float(ambient), float(background), out)
    return out

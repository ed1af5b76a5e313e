"""Render kernels: output colours from a position field, blending the copies across seams."""

import numpy as np
from numba import njit

from osmap_kernels.bands import run_bands
from osmap_kernels.common import neighbour, sample


def vote_image(image, pos, jac, radius, wrap):
    """Render with seam blending: every pixel p is the Gaussian-weighted mean of the colours its
    neighbours q (|q - p|_inf <= radius) assign to it, image at pos[q] + J[q] (p - q) (Kwatra et al.
    2005's voting). Inside a verbatim copy all votes agree, so copies stay exact; across a seam
    the two sides blend over about `radius` pixels. radius 0 samples pos itself (bilinear).
    Where all votes agree the pixel is the copied value itself, bit for bit. Row bands run on
    osmap_kernels.bands' threads."""
    out = np.empty((pos.shape[0], pos.shape[1], image.shape[2]), np.float32)
    run_bands(_vote_rows, pos.shape[0], image, pos, jac, radius, wrap, out)
    return out


@njit(cache=True, inline="always")
def _one_copy(pos, jac, y, x, radius, wrap):
    """Whether every neighbour q of (y, x) within radius votes for the pixel's own position
    (pos[q] - J[q] (q - p) == pos[p], in _vote_rows' arithmetic): p lies inside one copy."""
    py, px = np.float64(pos[y, x, 0]), np.float64(pos[y, x, 1])
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            inside, sy, sx = _vote(pos, jac, y, x, dy, dx, wrap)
            if inside and (sy != py or sx != px):
                return False
    return True


@njit(cache=True, inline="always")
def _vote(pos, jac, y, x, dy, dx, wrap):
    """(inside, sy, sx): where neighbour (y + dy, x + dx) puts pixel (y, x) in the exemplar, its
    position carried back by its Jacobian; inside False off a non-wrapping edge."""
    qy, qx, inside = neighbour(y, x, dy, dx, pos.shape[0], pos.shape[1], wrap)
    if not inside:
        return False, 0.0, 0.0
    J = jac[qy, qx]
    return (True, pos[qy, qx, 0] - (J[0, 0] * dy + J[0, 1] * dx),
            pos[qy, qx, 1] - (J[1, 0] * dy + J[1, 1] * dx))


@njit(cache=True, inline="always")
def _finite(values):
    for c in range(values.shape[0]):
        if not np.isfinite(values[c]):
            return False
    return True


@njit(cache=True, nogil=True)
def _vote_rows(image, pos, jac, radius, wrap, out, y0, y1):
    """vote_image's rows y0 <= y < y1, written into out."""
    W = pos.shape[1]
    C = image.shape[2]
    sigma = max(0.6 * radius, 0.5)
    side = 2 * radius + 1
    weights = np.empty((side, side))
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            weights[dy + radius, dx + radius] = np.exp(-(dy * dy + dx * dx) / (2.0 * sigma * sigma))
    buf = np.empty(C, np.float32)
    acc = np.empty(C)
    centre = np.empty(C, np.float32)
    for y in range(y0, y1):
        for x in range(W):
            sample(image, pos[y, x, 0], pos[y, x, 1], centre)
            if _one_copy(pos, jac, y, x, radius, wrap) and _finite(centre):
                # every vote samples where the pixel does: they all agree (see below)
                for c in range(C):
                    out[y, x, c] = centre[c]
                continue
            acc[:] = 0.0
            total = 0.0
            agree = True
            for dy in range(-radius, radius + 1):
                for dx in range(-radius, radius + 1):
                    inside, sy, sx = _vote(pos, jac, y, x, dy, dx, wrap)
                    if not inside:
                        continue
                    weight = weights[dy + radius, dx + radius]
                    sample(image, sy, sx, buf)
                    for c in range(C):
                        acc[c] += weight * buf[c]
                        agree = agree and buf[c] == centre[c]
                    total += weight
            for c in range(C):
                out[y, x, c] = centre[c] if agree else acc[c] / total

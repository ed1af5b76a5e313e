"""Helpers shared by the kernel modules (coherence, regions, render, solid, structure): hashed
random numbers, bilinear feature sampling, the neighbours of a pixel in a 2D field, and the root
of a union-find forest. Pure `@njit`
functions, inlined into their callers."""

import numpy as np
from numba import njit

# (dy, dx) of the 8 neighbours, in scan order
EIGHT_NEIGHBOURS = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)],
                            np.int64)


@njit(cache=True, inline="always")
def hash_uniform(seed, salt, index, j):
    """A uniform float in [0, 1) from four integers (splitmix64 finaliser)."""
    z = np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15)
    z ^= np.uint64(salt) * np.uint64(0xBF58476D1CE4E5B9)
    z ^= np.uint64(index) * np.uint64(0x94D049BB133111EB)
    z += np.uint64(j) * np.uint64(0x2545F4914F6CDD1D)
    z ^= z >> np.uint64(30)
    z *= np.uint64(0xBF58476D1CE4E5B9)
    z ^= z >> np.uint64(27)
    z *= np.uint64(0x94D049BB133111EB)
    z ^= z >> np.uint64(31)
    return (z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, inline="always")
def sample(feat, y, x, out):
    """Bilinear sample of feat (h, w, F) at (y, x) into out (F,); exact fetch at integers."""
    h, w, nf = feat.shape
    y0 = int(np.floor(y))
    x0 = int(np.floor(x))
    fy = y - y0
    fx = x - x0
    y0 = min(max(y0, 0), h - 1)
    x0 = min(max(x0, 0), w - 1)
    if fy == 0.0 and fx == 0.0:
        for f in range(nf):
            out[f] = feat[y0, x0, f]
        return
    y1 = min(y0 + 1, h - 1)
    x1 = min(x0 + 1, w - 1)
    w00 = (1 - fy) * (1 - fx)
    w01 = (1 - fy) * fx
    w10 = fy * (1 - fx)
    w11 = fy * fx
    for f in range(nf):
        out[f] = (w00 * feat[y0, x0, f] + w01 * feat[y0, x1, f]
                  + w10 * feat[y1, x0, f] + w11 * feat[y1, x1, f])


@njit(cache=True, inline="always")
def neighbour(y, x, dy, dx, H, W, wrap):
    """(qy, qx, inside): pixel (y + dy, x + dx) of an H x W field, wrapped when toroidal."""
    qy = y + dy
    qx = x + dx
    if wrap:
        return qy % H, qx % W, True
    return qy, qx, 0 <= qy < H and 0 <= qx < W


@njit(cache=True, inline="always")
def find_root(parent, i):
    """The root of i in the union-find forest `parent` (int64[N]), halving the path on the way."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i
